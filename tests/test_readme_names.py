"""README's commands and names stay true to the code (issue 63 item 4): every snakemake target,
profile, config file, ``python -m madpinn`` command, script, run name and registration hook that
README.md or the cookbook it points to names exists. Static reads only: seconds."""

from __future__ import annotations

import re
import shlex

import pytest
import yaml

from conftest import REPO

PAGES = [REPO / "README.md", REPO / "docs" / "reference" / "cookbook.md"]
RULES = REPO / "workflow" / "rules"


def _targets() -> set[str]:
    """Rule names of the workflow, and the tables ``register_table`` defines (per study where the
    name is an f-string over the configured studies)."""
    text = "\n".join(p.read_text() for p in [REPO / "Snakefile", *sorted(RULES.glob("*.smk"))])
    names = set(re.findall(r"^\s*rule (\w+)\s*:", text, re.M)) | set(re.findall(r'register_table\("(\w+)"', text))
    studies = yaml.safe_load((REPO / "config.yaml").read_text())["studies"]
    if 'register_table(f"table_{_study}"' in text:
        names |= {f"table_{s}" for s in studies}
    return names


def _commands(page) -> list[list[str]]:
    """Every shell command of ``page``: lines of its ``bash`` blocks and inline code spans that run
    snakemake, ``python -m madpinn`` or a script."""
    text = page.read_text()
    lines = [ln for block in re.findall(r"```bash\n(.*?)```", text, re.S) for ln in block.splitlines()]
    lines += re.findall(r"`([^`]*(?:snakemake|python -m madpinn|python scripts/)[^`]*)`", text)
    out = []
    for line in lines:
        line = line.split("#", 1)[0].strip()
        if line:
            out.append(shlex.split(line.replace("…", "")))
    return out


def _snakemake_args(words: list[str]) -> tuple[list[str], list[str], list[str]]:
    """(targets, profiles, config files) of one snakemake command line: ``--configfile`` takes
    every following word up to the next flag, ``--profile`` / ``--report`` / ``-j`` / ``-d`` one."""
    i = next(k for k, w in enumerate(words) if w.endswith("snakemake")) + 1
    targets, profiles, configs, mode = [], [], [], None
    for w in words[i:]:
        if w.startswith("-"):
            mode = w if w in ("--profile", "--configfile", "--report", "-d", "--cores") else None
        elif mode == "--configfile":
            configs.append(w)
        elif mode is not None:
            (profiles if mode == "--profile" else []).append(w)
            mode = None
        else:
            targets.append(w)
    return targets, profiles, configs


@pytest.mark.parametrize("page", PAGES, ids=lambda p: p.name)
def test_every_command_names_what_exists(page):
    from madpinn.commands import handler_entry

    targets, checked = _targets(), 0
    for words in _commands(page):
        if any(w.endswith("snakemake") for w in words):
            tgts, profiles, configs = _snakemake_args(words)
            assert set(tgts) <= targets, (page.name, words, set(tgts) - targets)
            for p in profiles:
                assert (REPO / p / "config.yaml").is_file(), (page.name, p)
            for c in configs:
                assert (REPO / c).is_file(), (page.name, c)
            checked += 1
        elif words[:3] == ["python", "-m", "madpinn"] and len(words) > 3 and not words[3].startswith(("-", "<")):
            handler_entry(words[3])   # raises for an unknown command
            checked += 1
        elif len(words) > 1 and words[0].endswith("python") and words[1].startswith(("scripts/", "benchmarks/")):
            assert (REPO / words[1]).is_file(), (page.name, words[1])
            checked += 1
    assert checked >= 3, (page.name, checked)


def test_every_run_name_in_the_methods_table_is_a_configured_run():
    """The cookbook's methods table names runs (``madpinn``, ``safemarl-layered``, …): each is a
    method or a method's variant in config.yaml."""
    from madpinn.config import load_config, method_config

    cfg = load_config([REPO / "config.yaml"])
    text = (REPO / "docs" / "reference" / "cookbook.md").read_text()
    table = text[text.index("## Methods"):text.index("## Extend")]
    runs = [r for row in re.findall(r"^\| (`[^|]*`) \|", table, re.M) for r in re.findall(r"`([a-z0-9-]+)`", row)]
    assert len(runs) >= 6, runs
    for run in runs:
        method_config(cfg, run)   # raises for an unknown run


def test_the_hooks_the_docs_name_exist():
    """``@register_policy``, ``register_table`` / ``register_targets`` and ``make_backend``: the
    cookbook's extension points are the code's (README once advertised a ``@register_backend``
    that no longer existed)."""
    text = (REPO / "docs" / "reference" / "cookbook.md").read_text()
    package = "\n".join(p.read_text() for p in (REPO / "madpinn").rglob("*.py"))
    smk = "\n".join(p.read_text() for p in RULES.glob("*.smk"))
    for hook in re.findall(r"`@?(register_\w+|make_backend)`", text):
        assert f"def {hook}(" in package + smk, hook


README_MAX_LINES = 120
"""README stays a front page (issue 63 item 4): what it is, the two commands, the generated headline and
verdicts, where to go next; narrative goes to docs/findings/, reference material to docs/reference/"""


def test_readme_stays_a_front_page():
    lines = (REPO / "README.md").read_text().splitlines()
    assert len(lines) <= README_MAX_LINES, f"README.md has {len(lines)} lines (at most {README_MAX_LINES}): move narrative to docs/"
