"""Issue 48 item 4: the docs' layout and their links. Every relative Markdown link in README.md,
docs/**/*.md and paper_figures/README.md names a file (and, with ``#anchor``, a heading) that
exists; every ``docs/…`` path that code, configs or docs mention exists; docs/ holds only the
index, ``reference/`` and dated ``findings/YYYY-MM-DD-topic.md`` (generated tables live under
paper_figures/ or results/, where their command writes them)."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from conftest import REPO

DOCS = REPO / "docs"
LINK = re.compile(r"!?\[(?:[^\[\]]|\[[^\]]*\])*\]\(\s*<?([^)\s>]+)>?(?:\s+\"[^\"]*\")?\s*\)")
FENCE = re.compile(r"^(```|~~~).*?^\1[^\n]*$", re.S | re.M)
CODE_SPAN = re.compile(r"(`+)(?!`).*?(?<!`)\1(?!`)", re.S)
EXTERNAL = re.compile(r"^(?:[a-z][a-z0-9+.-]*:|//)", re.I)
DOCS_PATH = re.compile(r"(?<![\w/.-])docs/[A-Za-z0-9_./-]*[A-Za-z0-9_/]")
DOCS_JOINED = re.compile(r"[\"']docs[\"']((?:\s*/\s*[\"'][^\"'\n]+[\"'])+)")   # a path joined from quoted parts in code
# Where a `docs/…` path may be mentioned: hand-written text and code (generated outputs under
# paper_figures/ and output_cache/ are refreshed from their generators, which are scanned).
MENTION_ROOTS = ("README.md", "Snakefile", "config.yaml", "docs", "madpinn", "workflow", "tests", "benchmarks",
                 "scripts", "training", "profiles", "paper_figures/README.md", ".ci")
MENTION_SUFFIXES = {".md", ".py", ".smk", ".yaml", ".yml", ".rst", ".sh", ".toml", ".txt", ""}


def markdown_files() -> list[Path]:
    """The hand-written Markdown pages whose links are checked."""
    return [REPO / "README.md", REPO / "paper_figures" / "README.md", *sorted(DOCS.rglob("*.md"))]


def _without_code(text: str) -> str:
    """``text`` without fenced blocks and inline code spans (a link there is not a link)."""
    text = FENCE.sub(lambda m: "\n" * m.group(0).count("\n"), text)
    return CODE_SPAN.sub(lambda m: "\n" * m.group(0).count("\n"), text)


def heading_anchors(page: Path) -> set[str]:
    """GitHub's anchors of the headings of ``page`` (lower case, punctuation dropped, spaces → -)."""
    anchors = set()
    for line in FENCE.sub("", page.read_text(encoding="utf-8")).splitlines():
        if m := re.match(r"#{1,6}\s+(.*?)\s*#*\s*$", line):
            slug = re.sub(r"[^\w\- ]", "", m.group(1).replace("`", "").lower()).replace(" ", "-")
            anchors.add(slug)
    return anchors


def broken_links(page: Path, root: Path = REPO) -> list[str]:
    """The relative links of Markdown ``page`` whose file (or heading anchor) does not exist, as
    ``"page:line: target"`` (page relative to ``root``)."""
    text = _without_code(page.read_text(encoding="utf-8"))
    broken = []
    for m in LINK.finditer(text):
        target = m.group(1)
        if EXTERNAL.match(target):
            continue
        path_part, _, anchor = target.partition("#")
        dest = page if not path_part else (page.parent / path_part).resolve()
        line = text.count("\n", 0, m.start()) + 1
        where = f"{page.relative_to(root)}:{line}: {target}"
        if not dest.exists():
            broken.append(where)
        elif anchor and dest.suffix == ".md" and anchor.lower() not in heading_anchors(dest):
            broken.append(where + " (no such heading)")
    return broken


def _mention_files() -> list[Path]:
    files = []
    for root in MENTION_ROOTS:
        path = REPO / root
        if path.is_file():
            files.append(path)
        elif path.is_dir():
            files += [p for p in sorted(path.rglob("*")) if p.is_file() and p.suffix in MENTION_SUFFIXES
                      and "__pycache__" not in p.parts and p.stat().st_size < 1_000_000]
    return files


def missing_docs_paths(files: list[Path]) -> list[str]:
    """Every ``docs/…`` path mentioned in ``files`` (code, configs, docs) that does not exist in the
    repository, as ``"file:line: path"``; glob patterns and this module's own examples are skipped."""
    missing = []
    for f in files:
        try:
            text = f.read_text(encoding="utf-8")
        except UnicodeDecodeError:
            continue
        for m in DOCS_PATH.finditer(text):
            path = m.group(0).rstrip(".")
            if "*" in text[m.end():m.end() + 1] or "YYYY" in path or not path.strip("/").count("/"):
                continue
            if not (REPO / path).exists():
                missing.append(f"{f.relative_to(REPO)}:{text.count(chr(10), 0, m.start()) + 1}: {path}")
        for m in DOCS_JOINED.finditer(text):
            path = "/".join(["docs", *re.findall(r"[\"']([^\"'\n]+)[\"']", m.group(1))])
            if "{" not in path and not (REPO / path).exists():
                missing.append(f"{f.relative_to(REPO)}:{text.count(chr(10), 0, m.start()) + 1}: {path}")
    return missing


def test_the_link_checker_finds_a_broken_link_and_passes_a_good_one(tmp_path):
    """The checker itself: a missing file, a missing heading and a path only in code are told apart."""
    (tmp_path / "there.md").write_text("# A heading, with `code`\n", encoding="utf-8")
    page = tmp_path / "page.md"
    page.write_text("[ok](there.md) [ok](there.md#a-heading-with-code) [web](https://example.org/x.md)\n"
                    "[gone](missing.md) [bad anchor](there.md#nope)\n"
                    "`[in code](missing_too.md)`\n```\n[fenced](missing_three.md)\n```\n", encoding="utf-8")
    assert broken_links(page, tmp_path) == ["page.md:2: missing.md", "page.md:2: there.md#nope (no such heading)"]


@pytest.mark.parametrize("page", markdown_files(), ids=lambda p: str(p.relative_to(REPO)))
def test_relative_markdown_links_resolve(page):
    assert broken_links(page) == []


def test_every_mentioned_docs_path_exists():
    """A `docs/…` path in a comment, docstring, caption, config or page names a file that exists
    (a moved page leaves no dangling mention)."""
    assert missing_docs_paths(_mention_files()) == []


def test_docs_layout():
    """docs/ = README.md (the index) + reference/ (what the code does now) + findings/ (dated
    experiments, ``YYYY-MM-DD-topic.md``) + screenshots/ (PNGs of the UI and report,
    scripts/screenshots.py); no generated tables."""
    top = sorted(p.name for p in DOCS.iterdir())
    assert top == ["README.md", "findings", "reference", "screenshots"], top
    assert all(p.suffix == ".png" for p in (DOCS / "screenshots").iterdir())
    assert all(p.suffix == ".md" for p in (DOCS / "reference").rglob("*") if p.is_file())
    bad = [p.name for p in (DOCS / "findings").iterdir() if not re.fullmatch(r"\d{4}-\d{2}-\d{2}-[a-z0-9-]+\.md", p.name)]
    assert bad == []


def test_the_index_lists_every_page():
    """docs/README.md links every reference page and every finding."""
    index = DOCS / "README.md"
    linked = {(index.parent / m.group(1).partition("#")[0]).resolve() for m in LINK.finditer(_without_code(index.read_text(encoding="utf-8")))}
    pages = sorted((DOCS / "reference").glob("*.md")) + sorted((DOCS / "findings").glob("*.md"))
    assert [str(p.relative_to(DOCS)) for p in pages if p.resolve() not in linked] == []
