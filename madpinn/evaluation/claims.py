"""The paper's claims, each tested on the reproduction report (issues 47, 61).

Each :class:`Claim` quotes a sentence of the paper, says in plain words the rule that tests it, and
turns the report's cells into checks (:mod:`madpinn.evaluation.claim_rules`,
:mod:`madpinn.evaluation.claim_ablations`), never a typed result. Verdicts follow the scale of
:mod:`madpinn.evaluation.claim_checks`, one per reading (run or convention) compared.

:func:`build_claims` takes the report (``reproduction.json``); :func:`write_claims` writes
``claims.json``, ``claims.md`` and ``claims.html`` with the per-cell value tables
(:mod:`madpinn.evaluation.claim_values`) and the paper's consistency
(:mod:`madpinn.evaluation.paper_consistency`) in their own sections.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Mapping

from madpinn.evaluation import claim_ablations as ab
from madpinn.evaluation import claim_rules as cr
from madpinn.evaluation.claim_checks import (  # noqa: F401  (the verdict scale, imported from here by tests)
    DOES_NOT, HOLDS, PARTLY, SCALE, UNMEASURED, UNSTATED, Check, by_reading, claim_verdict, headline, scale_of, verdict,
)

VHAT_PROVENANCE = ("the shipped V̂'s recipe (fine-tune, conflict sampling) was chosen on protocol seeds 0 and 1 "
                   "(docs/findings/2026-11-21-vhat-training-results.md) and is being re-made on validation seeds (≥ 100) "
                   "by the rule written first (docs/findings/2026-11-29-vhat-recipe-preregistered.md; issue 61)")
"""where the V̂ recipe was chosen, until the recipe page's choice is given (:func:`recipe_provenance`)"""


@dataclass(frozen=True)
class Claim:
    """A claim of the paper: its words, where they are, the rule in plain words, and its checks."""

    id: str
    text: str
    source: str
    rule: str
    checks: Callable[[Mapping], list[Check]] = field(repr=False)


CLAIMS = (
    Claim("best_tradeoff", "Ours attains the lowest cumulative cost while maintaining near-perfect safety rates "
          "across all settings", "Results 1, tex 425; Fig. 2 caption, tex 287-293",
          "per agent count: no baseline significantly cheaper than Ours (Δcost interval below 0), and Ours' safety "
          "interval reaching the paper's lowest Ours safety of Table I (\"near-perfect\"); the paper does not claim "
          "Ours is the safest", cr.best_tradeoff),
    Claim("fig2_ordering", "Cost–safety figure: Ours consistently appears in the bottom-right region, "
          "superior to all baselines", "Fig. 2 caption, tex 287-293",
          "per baseline and agent count: the baseline does not dominate Ours (significantly better on one axis and "
          "not significantly worse on the other)", cr.fig2_ordering),
    Claim("fig2_scalability", "Ours' degradation with increasing agent count is minimal: better scalability than the baselines",
          "Fig. 2 caption, tex 287-293",
          "per baseline: Ours' safety fall from the fewest to the most agents significantly smaller than the "
          "baseline's (conservative interval of each fall from the two cells' intervals)", cr.fig2_scalability),
    Claim("safemarl_costlier", "SafeMARL maintains high safety but incurs substantially higher costs due to conservative behaviour",
          "Results 1, tex 425",
          "per SafeMARL run and agent count: not significantly less safe than Ours, and significantly costlier",
          cr.safemarl_costlier),
    Claim("mppi_poor", "MPPI performs poorly on both metrics (safety enforced only through soft penalties)",
          "Results 1, tex 425", "per MPPI run and agent count: significantly less safe than Ours; significantly costlier",
          cr.mppi_poor),
    Claim("defmarl_mppi_degrade", "DEF-MARL and MPPI deteriorate rapidly with increasing density", "Results 1, tex 425; Table I",
          "per run: essential, safety at the most agents significantly below the fewest; safe scenarios too; and each "
          "fall significantly larger than Ours' (the paper's comparison)", cr.degrade),
    Claim("safe_scenarios_high", "The proposed method consistently achieves a high percentage of safe scenarios across "
          "all agent counts", "Results 1, tex 425; Table I",
          "per agent count: Ours' safe-scenario interval reaches the paper's Table I value", cr.safe_scenarios_high),
    Claim("table2_scales", "Table II: Ours maintains high safety rates and safe-scenario percentages even with 256 agents, "
          "co-optimising safety and performance", "Table II, tex 410-424; Results 2, tex 427",
          "per MAD-PINN run and agent count: our safety and safe-scenario intervals reach the paper's (safety at the "
          "most agents: essential); cost ÷T not above the paper's (interval's lower end ≤ paper)", ab.table2_scales),
    Claim("table2_cost_proportional", "Table II: cumulative costs increase with the larger environment, approximately "
          "in proportion to its size, preserving the level of performance of Table I", "Results 2, tex 427",
          "per agent count: Ours' cost ÷T over its Table I cost ÷T at the most agents not significantly above the "
          "arena side ratio; a reading of ours (the paper states no tolerance, and plots Table I's cost only)",
          ab.cost_proportional),
    Claim("neighbour_safety_order", "Table III: value-based neighbours are safer than nearest, nearest safer than random",
          "Table III, tex 429-443; Results 3, tex 445",
          "nearest − value Δsafety interval below 0; random's interval below nearest's", ab.neighbour_safety),
    Claim("neighbour_cost_least", "Table III: value-based neighbour selection achieves the lowest costs",
          "Results 3, tex 445", "per alternative: its − value Δcost interval above 0 (cost along safe trajectories, "
          "the paper's metric); cost over all agents shown, not judged (no interval)", ab.neighbour_cost),
    Claim("update_safety_falls", "Table IV: safety degrades significantly as updates become infrequent",
          "Table IV caption, tex 447-466; Results 4, tex 467",
          "essential: safety at k = ∞ significantly below k = 1; and no step of k significantly safer than the one before",
          ab.trend("safety", falls=True)),
    Claim("update_cost_rises", "Table IV: more frequent updates improve performance (cost rises as k grows)",
          "Results 4, tex 467", "essential: cost at k = ∞ significantly above k = 1; and no step of k significantly "
          "cheaper than the one before (cost along safe trajectories); cost over all agents shown, not judged",
          ab.trend("cost_time_avg", falls=False)),
    Claim("update_k5_comparable", "Table IV: k = 5 achieves comparable safety and performance to updating every step",
          "Results 4, tex 467",
          f"k1 − k5 interval within ±{100 * ab.COMPARABLE_SAFETY:g} pp of safety and ±{ab.COMPARABLE_COST:g} of cost ÷T",
          ab.k5_comparable),
    Claim("update_safety_more_sensitive", "Table IV: as the update interval increases, safety degrades much faster than "
          "performance", "Results 4, tex 467",
          "from k = 1 to k = ∞: the smallest relative safety fall the intervals allow exceeds the largest relative cost rise",
          ab.safety_more_sensitive),
)
"""every claim the table tests, in the paper's order"""
def _check_dict(c: Check) -> dict:
    return {"expected": c.expected, "observed": c.observed, "cells": list(c.cells), "paper": c.paper, "part": c.part,
            "passed": c.passed, "essential": c.essential, "reading": c.reading, "stated": c.stated, "row": c.row}


def timing_claim() -> Claim:
    """The timing claim; its checks read the neighbour-timing JSON, not the report."""
    from madpinn.evaluation.claim_timing import timing_checks
    from madpinn.evaluation.paper_consistency import raw

    ms = raw()["protocol"]["neighbour_selection_ms"]
    return Claim("neighbour_selection_time", f"The neighbour selection process takes {ms:g} ms per agent; the per-agent "
                 "online cost grows linearly with N (overall O(N))", "Results 4, tex 467; tex 346",
                 "per agent count: our selection time per agent and update at most the paper's figure; essential: the "
                 "fitted exponent of time per agent in N not significantly above 1 (measured on this machine: "
                 "paper_figures/neighbour_timing.json)", timing_checks)


def heatmap_claim() -> Claim:
    """The heatmap's reading; its checks read the heatmap job's JSON, not the report."""
    from madpinn.evaluation.claim_heatmap import heatmap_checks

    return Claim("value_heatmap", "Value heatmap: regions of high value overlap the other agents' positions; low values "
                 "are concentrated around the goal", "Setup, tex 406; Fig. value function",
                 "on the heatmap's grid (paper_figures/fig_value_heatmap.json): most cells within r of each other agent "
                 "infeasible or above the arena's median; the goal cell in the lowest decile; the lowest cell within r "
                 "of the goal", heatmap_checks)


def table2_readings_claim() -> Claim:
    """Table II over the readings the paper leaves open; its checks read the readings page's verdict."""
    from madpinn.evaluation.claim_table2_readings import readings_checks

    return Claim("table2_readings", "Table II's row (safety, safe scenarios and cost at 64 / 128 / 256 agents), under "
                 "the readings the paper leaves open (start/goal law, deployment, horizon)", "Table II, tex 410-424; Results 2, tex 427",
                 "per reading of the readings page claims.table_ii_verdict names (the protocol's: the final readings on "
                 "protocol seed 0, chosen on validation seeds, docs/findings/2026-12-01-table-ii-final-readings-plan.md): "
                 "every check of the scale fixed before the cells "
                 "(docs/findings/2026-11-28-table-ii-readings-preregistered.md §3); the protocol's reading is the stated one",
                 readings_checks)


def recipe_provenance(recipe: Mapping | None) -> str:
    """The seed-provenance line: the recipe page's choice (``vhat_recipe.json``) when given, else :data:`VHAT_PROVENANCE`."""
    from madpinn.evaluation.recipe_choice import choice_sentence

    return choice_sentence(recipe) if recipe else VHAT_PROVENANCE


def build_claims(report: Mapping, claims=CLAIMS, timing: Mapping | None = None, heatmap: Mapping | None = None,
                 readings: Mapping | None = None, recipe: Mapping | None = None) -> dict:
    """``{"claims": [...], "verdicts": {id: verdict}, "counts": {scale word: n}, "values": [...],
    "consistency": [...], "provenance": {...}}`` from a reproduction report, the neighbour-timing
    measurement, the heatmap's reading and Table II's readings (``timing``, ``heatmap``, ``readings``: their
    JSON; None: that claim is left out); ``recipe``: the V̂ recipe's choice (``vhat_recipe.json``), stated in
    the provenance."""
    from madpinn.evaluation.claim_values import rows_not_in_paper, value_rows
    from madpinn.evaluation.paper_consistency import check_paper

    extra = {"neighbour_selection_time": (timing_claim, timing), "value_heatmap": (heatmap_claim, heatmap),
             "table2_readings": (table2_readings_claim, readings)}
    inputs = {cl.id: report for cl in claims}
    listed = list(claims)
    for cid, (make, data) in extra.items():
        if data:
            listed.append(make())
            inputs[cid] = data
    out = []
    for cl in listed:
        checks = cl.checks(inputs[cl.id])
        top = headline(checks)
        out.append({"id": cl.id, "claim": cl.text, "source": cl.source, "rule": cl.rule, "verdict": claim_verdict(checks),
                    "readings": {r: verdict(cs) for r, cs in by_reading(checks).items()},
                    "passed": sum(bool(c.passed) for c in checks), "checks_total": sum(c.passed is not None for c in checks),
                    "cells": sorted({x for ch in checks for x in ch.cells}),
                    "headline": _check_dict(top) if top else None, "checks": [_check_dict(c) for c in checks]})
        if cl.id == "table2_readings" and inputs[cl.id].get("chosen_on"):   # where its readings were chosen: shown, not judged
            out[-1]["chosen_on"] = inputs[cl.id]["chosen_on"]
    verdicts = {c["id"]: c["verdict"] for c in out}
    prov = report.get("provenance", {})
    return {"claims": out, "verdicts": verdicts,
            "counts": {w: sum(scale_of(v) == w for v in verdicts.values()) for w in SCALE},
            "values": value_rows(report), "not_in_paper": rows_not_in_paper(report), "consistency": check_paper(),
            "provenance": {"config_hash": prov.get("config_hash"), "collisions": prov.get("collisions"),
                           "intervals": prov.get("intervals"), "vhat_recipe": recipe_provenance(recipe),
                           "rule": "per reading: every check passes: holds; k of n: partly (k of n); a failed essential "
                                   "check or none passing: does not hold; the claim pools the paper's own readings, and "
                                   f"reads \"{UNSTATED}\" when each paper row it tests holds under its own or one of "
                                   "our labelled readings (madpinn/evaluation/claim_checks.py)"}}


def readme_lines(claims: dict) -> list[str]:
    """The README's quotation of the verdicts (``tests/test_readme_blocks.py`` checks README against it)."""
    return [f"- {c['claim']} ({c['source'].split(';')[0]}): **{c['verdict']}**" for c in claims["claims"]]


def write_claims(report_path: str | Path, out_dir: str | Path, timing_path: str | Path | None = None,
                 heatmap_path: str | Path | None = None, readings_path: str | Path | None = None,
                 recipe_path: str | Path | None = None) -> list[Path]:
    """Read ``reproduction.json`` at ``report_path`` (and the neighbour timing, the heatmap's reading, Table II's
    readings, the V̂ recipe's choice);
    write ``claims.json``, ``claims.md`` and ``claims.html`` (the page the Snakemake report shows) into ``out_dir``."""
    from madpinn.evaluation.claims_page import to_markdown
    from madpinn.evaluation.html import markdown_page

    report = json.loads(Path(report_path).read_text())
    if not isinstance(report, dict) or "provenance" not in report:
        raise ValueError(f"{report_path} is not a reproduction report (no provenance)")
    read = lambda p: json.loads(Path(p).read_text()) if p else None   # noqa: E731
    claims = build_claims(report, timing=read(timing_path), heatmap=read(heatmap_path), readings=read(readings_path),
                          recipe=read(recipe_path))
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    js, md, page = out_dir / "claims.json", out_dir / "claims.md", out_dir / "claims.html"
    js.write_text(json.dumps(claims, indent=2, ensure_ascii=False))
    md.write_text(to_markdown(claims))
    page.write_text(markdown_page(md.read_text(), "The paper's claims, tested"))
    return [js, md, page]
