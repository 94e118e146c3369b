"""The README's generated blocks: numbers and verdicts quoted from the committed report, never typed.

README.md holds blocks ``<!-- NAME:start ... -->`` … ``<!-- NAME:end -->``. Each is rendered from a
generated file under ``paper_figures/`` by a function here:

- ``headline``: the protocol's headline numbers (Tables I–IV, ours beside the paper's, paired
  differences with their 95 % intervals), from ``reproduction.json``;
- ``claims``: the verdicts of the claims table, from ``claims.json``;
- ``findings``: a few generated findings (verdict counts, the paper's numbers that cannot all be
  true, the sensing radius's effect), from ``claims.json`` and ``reproduction.json``.

``tests/test_readme_blocks.py`` fails when a block differs from its rendering;
``python scripts/update_readme.py`` rewrites the blocks in place (the workflow never edits README).
"""

from __future__ import annotations

import json
import re
from pathlib import Path
from typing import Callable

from madpinn.evaluation.claims import readme_lines as claims_lines


def _pct(x) -> str:
    return "–" if x is None else f"{100 * x:.1f}"


def _paper_pct(x) -> str:
    return "–" if x is None else f"{100 * x:g}"


def _diff(d: dict | None, scale: float, digits: int) -> str:
    """A paired difference with its 95 % interval, e.g. ``+3.2 [+2.1, +4.4]``; – where there is none."""
    if not d:
        return "–"
    return f"{scale * d['diff']:+.{digits}f} [{scale * d['lo']:+.{digits}f}, {scale * d['hi']:+.{digits}f}]"


def _cost(x) -> str:
    return "–" if x is None else f"{x:.3f}"


def _paper_cost(x) -> str:
    return "–" if x is None else f"{x:g}"


def _per_n(row: dict, cell: Callable[[dict], str]) -> str:
    return " / ".join(cell(row[n]) for n in sorted(row, key=int))


def _seeds(row: dict) -> str:
    seeds = sorted({c.get("n_seeds") for c in row.values() if c.get("n_seeds")})
    return "/".join(map(str, seeds)) or "–"


def _row(what: str, row: dict, prefix: str = "") -> str:
    label = prefix + next(iter(row.values()))["label"]
    vs = lambda key, scale, digits: _per_n(row, lambda c: _diff((c.get("vs_ours") or {}).get(key), scale, digits))
    return " | ".join([
        "", f"{what} ({_seeds(row)})", label, " / ".join(sorted(row, key=int)),
        _per_n(row, lambda c: f"{_pct(c.get('safety'))} ({_paper_pct(c.get('paper_safety'))})"),
        vs("safety", 100, 1),
        _per_n(row, lambda c: f"{_cost(c.get('cost_time_avg'))} ({_paper_cost(c.get('paper_cost'))})"),
        vs("cost_time_avg", 1, 3), ""]).strip()


# (report table, run, which paper table, label prefix) of each headline row, in README order.
HEADLINE = (
    ("table_safety_scaling", "madpinn", "Table I", ""),
    ("table_safety_scaling", "safemarl", "Table I", ""),
    ("table_safety_scaling", "madpinn-lookahead", "Table I", ""),
    ("table_ours_scaling", "madpinn", "Table II", ""),
    ("table_ours_scaling", "madpinn-carrot05vmaxh", "Table II", ""),
    ("table_neighbour_ablation", "madpinn-value", "Table III", ""),
    ("table_neighbour_ablation", "madpinn-nearest", "Table III", ""),
    ("table_neighbour_ablation", "madpinn-random", "Table III", ""),
    ("table_update_ablation", "madpinn-k1", "Table IV", "k = "),
    ("table_update_ablation", "madpinn-kinf", "Table IV", "k = "),
)


def headline_lines(report: dict) -> list[str]:
    """The README's headline numbers from ``reproduction.json`` (a run the report lacks is left out)."""
    rows = [_row(what, report[table][run], prefix) for table, run, what, prefix in HEADLINE if run in report.get(table, {})]
    prov = report.get("provenance", {})
    cells = prov.get("cells", {})   # the report holds no commit (identical inputs, identical bytes): git log has it
    return [f"Run: config hash `{prov.get('config_hash')}`, backend {prov.get('backend')}, {cells.get('count')} cells "
            f"({cells.get('time_h')} core-hours of cell time).", "",
            "| Table (seeds) | Run | Agents | Safety %, ours (paper) | Run − Ours, safety pts [95 %] "
            "| Cost ÷T, ours (paper) | Run − Ours, cost ÷T [95 %] |", "|---|---|---|---|---|---|---|", *rows]


def _pts(d: dict) -> str:
    return f"{100 * d['diff']:+.1f}"


def findings_lines(claims: dict, report: dict) -> list[str]:
    """Short generated findings (README's ``findings`` block)."""
    counts = ", ".join(f"{w} {k}" for w, k in claims["counts"].items() if k)
    bad = [r for r in claims["consistency"] if not r["holds"]]
    always = sorted({f"{r['paper_table']} row \"{r['label']}\" at N = {r['n']} ({r['check']})" for r in bad if not r["reading"]})
    readings = sorted({r["reading"] for r in bad if r["reading"]})
    lines = [f"- Claims: {counts} (`paper_figures/claims.md`).",
             f"- The paper's own numbers: {len(bad)} of {len(claims['consistency'])} consistency checks cannot hold"
             + (f"; under every reading: {'; '.join(always)}" if always else "")
             + (f"; the others only if its scenarios are read as {' or '.join(readings)}" if readings else "") + "."]
    wide = {t: [c["vs_ours"]["safety"] for c in report.get(t, {}).get("madpinn-wide", {}).values()
                if (c.get("vs_ours") or {}).get("safety")] for t in ("table_safety_scaling", "table_ours_scaling")}
    if all(wide.values()):
        small, large = (sorted(wide[t], key=lambda d: d["diff"]) for t in ("table_safety_scaling", "table_ours_scaling"))
        label = next(iter(report["table_safety_scaling"]["madpinn-wide"].values()))["label"]
        lines.append(f"- `madpinn-wide` ({label}) − `madpinn`, same scenarios: safety {_pts(small[0])} to "
                     f"{_pts(small[-1])} points in Table I, {_pts(large[0])} to {_pts(large[-1])} in Table II.")
    return lines


def seed_band_sentence(recipe: dict) -> str:
    """The deployed V̂'s training-seed band in the recipe page's reported cells (issue 60 item 3;
    ``vhat_recipe.json``'s ``adopted_band``), e.g. ``The deployed V̂'s 3 training seeds (validation
    seed 100): 60.9–68.4 / … % at 64 / … agents.``; empty when the page has none."""
    band = recipe.get("adopted_band")
    cells = [c for c in (band or {}).get("cells", []) if c["role"] == "reported"]
    if not cells:
        return ""
    seeds = ", ".join(map(str, recipe["seeds"]))
    return (f" The deployed V̂'s {max(c['models'] for c in cells)} training seeds (validation seed {seeds}): "
            + " / ".join(f"{c['lo']:.1f}–{c['hi']:.1f}" for c in cells) + " % safety at "
            + " / ".join(str(c["n_agents"]) for c in cells) + " agents.")


def table_ii_lines(verdict: dict, recipe: dict | None = None) -> list[str]:
    """Table II over the readings the paper leaves open (README's ``table_ii`` block): the published
    readings page's verdict (issue 60: the final readings on protocol seed 0, or a validation page) in
    its own sentence, where its readings were chosen, the baselines' reading and, from the recipe page
    (``recipe``), the deployed V̂'s training-seed band."""
    from madpinn.evaluation.table_ii_page import verdict_sentence

    ch = verdict.get("chosen_on")
    if ch:   # the final readings: kept from a validation page by the rule fixed before they ran
        where = (f"The final readings on protocol seed 0, kept from {len(ch['readings'])} readings of what the paper leaves "
                 f"open for the large arena, tried on validation seeds (there: {ch['verdict']}; closest "
                 f"{ch['closest']}, {dict(ch['readings']).get(ch['closest'], '–')} checks)")
    else:
        where = f"Over {verdict['readings_judged']} readings of what the paper leaves open for the large arena (validation seeds)"
    return [f"- {where}: {verdict_sentence(verdict)}",
            f"- The baselines in the large arena (not in the paper): {verdict['baselines']['reading']}."
            + (seed_band_sentence(recipe) if recipe else "")]


# block name -> (files under paper_figures/, renderer of their parsed JSON, in that order)
BLOCKS: dict[str, tuple[tuple[str, ...], Callable[..., list[str]]]] = {
    "headline": (("reproduction.json",), headline_lines),
    "claims": (("claims.json",), claims_lines),
    "findings": (("claims.json", "reproduction.json"), findings_lines),
    "table_ii": (("table_ii_final/table_ii_readings/verdict.json", "vhat_recipe/vhat_recipe.json"), table_ii_lines),   # issue 60: seed 0's final readings, the seed band
}


def _pattern(name: str) -> re.Pattern:
    return re.compile(rf"(<!-- {name}:start[^>]*-->\n)(.*?)(\n?<!-- {name}:end -->)", re.S)


def rendered(name: str, figures_dir: str | Path) -> list[str]:
    sources, render = BLOCKS[name]
    return render(*(json.loads((Path(figures_dir) / source).read_text()) for source in sources))


def block(text: str, name: str) -> list[str] | None:
    """The lines of block ``name`` in ``text`` (None: no such block)."""
    m = _pattern(name).search(text)
    return None if m is None else m.group(2).splitlines()


def render_readme(text: str, figures_dir: str | Path) -> str:
    """``text`` with every block replaced by its rendering from ``figures_dir``; a missing block is an error."""
    for name in BLOCKS:
        pattern = _pattern(name)
        if not pattern.search(text):
            raise ValueError(f"README lacks the block <!-- {name}:start --> … <!-- {name}:end -->")
        body = "\n".join(rendered(name, figures_dir))
        text = pattern.sub(lambda m: m.group(1) + body + "\n" + m.group(3).lstrip("\n"), text, count=1)
    return text
