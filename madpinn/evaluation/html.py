"""HTML pages of the generated Markdown (tables, the reproduction report) for the Snakemake report,
which shows HTML inline but offers Markdown and CSV only as downloads.

Covers the Markdown subset our writers emit: ``#`` headings, paragraphs, ``-`` lists, pipe tables,
inline ``code`` and ``**bold**``. Everything else is escaped text.

Tables fit the report's pane (about 1 100 px beside its menu): a table whose headers are
``group · column`` (e.g. ``8 agents · Safety``) is shown as one table per group, one below the
other, the row names repeated; in other tables a number's ``± std …`` goes on a second line; text
cells wrap. Whatever is still wider scrolls sideways inside its own box, its first column (the row
names) staying in view.
"""

from __future__ import annotations

import html
import re

GROUP_SEP = " · "     # header "group · column": the column belongs to a group (e.g. an agent count)
NUMBER = re.compile(r"^[-+−–]?\d|^[–—-]$|^n/a$")   # a cell that is a number (or a dash or n/a for none)

STYLE = (
    "body{font-family:system-ui,sans-serif;font-size:14px;margin:1em;color:#222}"
    ".wide{overflow-x:auto;max-width:100%;margin:0.3em 0 1.2em}"
    "table{border-collapse:collapse}th,td{border:1px solid #ccc;padding:3px 7px;vertical-align:top}"
    "th{background:#f2f2f2;text-align:center}td.num{text-align:right;white-space:nowrap}"
    "td.text{text-align:left;min-width:6em;max-width:30em}"
    "td:first-child,th:first-child{text-align:left;position:sticky;left:0;background:#fff;z-index:1;max-width:18em}"
    "th:first-child{background:#f2f2f2}.sd{color:#666;font-size:0.9em}"
    "tr:nth-child(even) td{background:#fafafa}code{background:#f4f4f4;padding:0 3px}h1{font-size:1.4em}"
    "h2{font-size:1.2em;margin-top:1.4em}h3{font-size:1.05em;margin:1em 0 0.2em}"
)


def _inline(text: str) -> str:
    out = html.escape(text, quote=False)
    out = re.sub(r"`([^`]+)`", r"<code>\1</code>", out)
    return re.sub(r"\*\*([^*]+)\*\*", r"<strong>\1</strong>", out)


def _cells(line: str) -> list[str]:
    return [c.strip() for c in line.strip().strip("|").split("|")]


def _cell(text: str, sd_below: bool) -> str:
    """A body cell: numbers right-aligned, unbroken (``sd_below``: a ``± std …`` on a second line);
    text wraps."""
    if NUMBER.match(text):
        mean, sep, sd = text.partition(" ± ")
        if sep and sd_below:
            return f'<td class="num">{_inline(mean)}<br><span class="sd">± {_inline(sd)}</span></td>'
        return f'<td class="num">{_inline(text)}</td>'
    return f'<td class="text">{_inline(text)}</td>'


def _groups(head: list[str]) -> list[tuple[str, list[int]]] | None:
    """``[(group, [column index, ...]), ...]`` when every header but the first is ``group · column``
    and there are at least two groups, else None."""
    if len(head) < 3 or not all(GROUP_SEP in h for h in head[1:]):
        return None
    out: dict[str, list[int]] = {}
    for i, h in enumerate(head[1:], 1):
        out.setdefault(h.split(GROUP_SEP, 1)[0], []).append(i)
    return list(out.items()) if len(out) >= 2 else None


def _html_table(head: list[str], rows: list[list[str]], sd_below: bool) -> str:
    thead = "<tr>" + "".join(f"<th>{_inline(c)}</th>" for c in head) + "</tr>"
    body = "".join("<tr>" + "".join(_cell(c, sd_below) for c in r) + "</tr>" for r in rows)
    return f'<div class="wide"><table><thead>{thead}</thead><tbody>{body}</tbody></table></div>'


def table_html(head: list[str], rows: list[list[str]]) -> str:
    """HTML of one pipe table (header cells ``head``, body ``rows``), laid out to fit (module doc)."""
    groups = _groups(head)
    if groups is None:
        return _html_table(head, rows, sd_below=True)
    return "".join(f"<h3>{_inline(g)}</h3>" + _html_table(
        [head[0], *(head[i].split(GROUP_SEP, 1)[1] for i in cols)], [[r[0], *(r[i] for i in cols)] for r in rows],
        sd_below=False) for g, cols in groups)


def markdown_page(md: str, title: str) -> str:
    """A standalone HTML page of the Markdown text ``md``."""
    body: list[str] = []
    lines = md.splitlines()
    i = 0
    while i < len(lines):
        line = lines[i]
        if not line.strip():
            i += 1
        elif line.startswith("#"):
            level = min(len(line) - len(line.lstrip("#")), 6)
            body.append(f"<h{level}>{_inline(line[level:].strip())}</h{level}>")
            i += 1
        elif line.lstrip().startswith("|"):
            rows = []
            while i < len(lines) and lines[i].lstrip().startswith("|"):
                rows.append(_cells(lines[i]))
                i += 1
            head, rest = rows[0], [r for r in rows[1:] if not all(re.fullmatch(r":?-+:?", c) for c in r)]
            body.append(table_html(head, rest))
        elif line.startswith("- "):
            items = []
            while i < len(lines) and lines[i].startswith("- "):
                items.append(f"<li>{_inline(lines[i][2:])}</li>")
                i += 1
            body.append("<ul>" + "".join(items) + "</ul>")
        else:
            para = []
            while i < len(lines) and lines[i].strip() and not lines[i].startswith(("#", "- ", "|")):
                para.append(lines[i].strip())
                i += 1
            body.append(f"<p>{_inline(' '.join(para))}</p>")
    return (f"<!DOCTYPE html>\n<html><head><meta charset=\"utf-8\"><title>{html.escape(title)}</title>"
            f"<style>{STYLE}</style></head><body>\n" + "\n".join(body) + "\n</body></html>\n")


def write_table_files(table, markdown: str, out_dir, name: str) -> list:
    """Write a table's three files into ``out_dir`` (created): ``<name>.csv`` (the numbers of the
    DataFrame ``table``), ``<name>.md`` (the display text ``markdown``) and ``<name>.html`` (that
    text as a standalone page, titled ``name``); returns their paths in that order."""
    from pathlib import Path

    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    csv, md, page = (out_dir / f"{name}.{ext}" for ext in ("csv", "md", "html"))
    table.to_csv(csv, index=False)
    md.write_text(markdown)
    page.write_text(markdown_page(markdown, name))
    return [csv, md, page]
