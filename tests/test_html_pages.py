"""The Snakemake report's pages (issue 49 item 4): our Markdown as HTML (madpinn/evaluation/html.py),
every table fitting the report's pane or scrolling inside its own box (Table I was cut after its
3-agent columns), and the landing page (workflow/report/workflow.rst): the claims first, the rule
graph hidden until asked for."""

import html
import re

from conftest import REPO
from madpinn.evaluation.html import STYLE, markdown_page

GROUPED = """| Method | 3 agents · Safety | 3 agents · Cost ÷T | 8 agents · Safety | 8 agents · Cost ÷T |
|---|---:|---:|---:|---:|
| Ours (paper's deployment) | 98.4% ± 1.4% | 0.30 ± 0.01 | 98.2% ± 0.7% | 0.44 ± 0.01 |
| Oracle | – | 0.18 ± 0.01 | – | 0.17 ± 0.01 |
"""


def _tables(page: str) -> list[str]:
    return re.findall(r"<table>.*?</table>", page, flags=re.S)


def test_a_grouped_table_is_one_table_per_group_with_the_row_names_repeated():
    page = markdown_page(GROUPED, "t")
    tables = _tables(page)
    assert re.findall(r"<h3>(.*?)</h3>", page) == ["3 agents", "8 agents"] and len(tables) == 2
    for t in tables:
        assert re.findall(r"<th>(.*?)</th>", t) == ["Method", "Safety", "Cost ÷T"]
        assert "Ours (paper&#x27;s deployment)" in t or "Ours (paper's deployment)" in t
    assert '<td class="num">98.2% ± 0.7%</td>' in tables[1]


def test_every_table_sits_in_a_box_that_scrolls_sideways_and_long_text_wraps():
    page = markdown_page("| Claim | Verdict | Figure |\n|---|---|---:|\n| a long sentence of a claim | holds | 96.7% ± 0.9% [95.6, 97.8] |\n", "c")
    assert page.count('<div class="wide"><table>') == len(_tables(page)) == 1
    assert ".wide{overflow-x:auto" in STYLE
    assert re.search(r"td\.num\{[^}]*white-space:nowrap", STYLE) and "td.text{" in STYLE
    assert not re.search(r"(^|[},])(th,)?td\{[^}]*nowrap", STYLE)         # text cells are free to wrap
    assert '<td class="text">a long sentence of a claim</td>' in page
    assert '<td class="num">96.7%<br><span class="sd">± 0.9% [95.6, 97.8]</span></td>' in page


def test_committed_table_pages_are_the_pages_of_their_markdown_and_none_is_wider_than_a_group():
    """Each committed HTML page is what the writers make of the committed Markdown; Table I's
    columns come as one table per agent count (the method and that count's columns)."""
    for page in sorted((REPO / "paper_figures").glob("*.html")):
        md = page.with_suffix(".md").read_text()
        title = html.unescape(re.search(r"<title>(.*?)</title>", page.read_text()).group(1))
        assert page.read_text() == markdown_page(md, title), page.name
    table_i = REPO / "paper_figures" / "table_safety_scaling"
    header = [c.strip() for c in table_i.with_suffix(".md").read_text().splitlines()[0].strip("|").split("|")][1:]
    groups = [c.split(" · ")[0] for c in header]
    expected = [1 + groups.count(g) for g in dict.fromkeys(groups)]
    assert len(expected) == 4 and all(w >= 6 for w in expected)            # 3 / 8 / 12 / 16 agents
    assert [len(re.findall(r"<th>", t)) for t in _tables(table_i.with_suffix(".html").read_text())] == expected


def test_landing_page_starts_at_the_claims_and_hides_the_rule_graph():
    """Rendered as Snakemake renders the report's description (Jinja, then docutils), with the link
    target Snakemake appends for each report item."""
    from docutils.core import publish_parts
    from jinja2 import Template

    from madpinn.config import load_config

    class Snakemake:
        config = load_config([REPO / "config.yaml"])

    text = (REPO / "workflow" / "report" / "workflow.rst").read_text()
    text += "\n\n.. _claims.html: javascript:app.showResultInfo('paper_figures%2Fclaims.html')\n"
    page = publish_parts(Template(text).render(snakemake=Snakemake), writer="html")["html_body"]
    assert page.index('href="javascript:app.showResultInfo(') < page.index("Sections, in reading order")
    assert "#rulegraph{display:none}" in page and ":checked) #rulegraph{display:block}" in page
    assert '<input type="checkbox" id="madpinn-show-rulegraph">' in page
