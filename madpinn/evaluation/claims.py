"""The paper's claims, each tested on the reproduction report (issue 47).

Each :class:`Claim` quotes a claim of the paper's text or tables, names the report cells it rests
on and turns them into :class:`Check` s: one predicate each over our figures and their 95 %
intervals (:mod:`madpinn.evaluation.intervals`), never a typed result. The verdict follows one
rule (:func:`verdict`): a failed *essential* check (the claim's core, e.g. "safety falls at all")
gives "does not hold"; otherwise all checks passing give "holds", some "partly", none "does not hold".

Reading the intervals (``vs_ours``: run − Ours on the same scenarios):

- a run is *significantly safer* than Ours when its Δ safety interval lies above 0, *less safe*
  when below; *cheaper* when its Δ cost ÷T interval lies below 0, *costlier* when above;
- two cells of different scenario sets (e.g. 3 vs 16 agents) differ when their intervals do not
  overlap (conservative);
- a paper value is *reproduced* when it lies in our interval, or, where the paper gives a std over
  its 5 seeds (Table I), when its t-interval (mean ± t(0.975, 4)·std/√5) overlaps ours;
- "comparable" (Table IV, k = 1 vs 5) is equivalence within :data:`COMPARABLE_SAFETY` and
  :data:`COMPARABLE_COST`: the whole interval of the difference inside ± the margin.

:func:`build_claims` takes the report (``reproduction.json``, :func:`madpinn.evaluation.reproduction.build_report`);
:func:`write_claims` writes ``claims.json``, ``claims.md`` and ``claims.html``.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Mapping

HOLDS, PARTLY, DOES_NOT, UNMEASURED = "holds", "partly", "does not hold", "not measured"
COMPARABLE_SAFETY = 0.01
"""equivalence margin of "comparable safety" (fraction: 1 percentage point)"""
COMPARABLE_COST = 0.02
"""equivalence margin of "comparable cost" (cost ÷T; the paper's own k = 1 vs 5 cost gap)"""
PAPER_SEEDS = 5
"""seeds behind the paper's Table I mean ± std (tex: "100 distinct initial conditions across 5 seeds")"""

T1, T2, T3, T4 = "table_safety_scaling", "table_ours_scaling", "table_neighbour_ablation", "table_update_ablation"
BASELINES = ("defmarl-n3", "defmarl-n8", "safemarl", "mppi")
"""the paper's baselines (Table I rows other than Ours)"""
SAFEMARL_RUNS = ("safemarl", "safemarl-layered")
DEGRADING = ("defmarl-n3", "defmarl-n8", "mppi")
NEIGHBOURS = ("madpinn-value", "madpinn-nearest", "madpinn-random")
UPDATES = ("madpinn-k1", "madpinn-k5", "madpinn-k10", "madpinn-k20", "madpinn-k50", "madpinn-k100",
           "madpinn-k500", "madpinn-kinf")


@dataclass(frozen=True)
class Check:
    """One predicate over report cells: ``passed`` None when a cell it needs is missing."""

    what: str
    cells: tuple[str, ...]
    ours: str
    paper: str
    passed: bool | None
    essential: bool = False


@dataclass(frozen=True)
class Claim:
    """A claim of the paper: its words, where they are, and the checks that test it."""

    id: str
    text: str
    source: str
    rule: str
    checks: Callable[[Mapping], list[Check]] = field(repr=False)


def verdict(checks: list[Check]) -> str:
    """The one verdict rule (module docstring); checks whose cells are missing do not count."""
    known = [c for c in checks if c.passed is not None]
    if not known:
        return UNMEASURED
    if any(c.essential and not c.passed for c in known):
        return DOES_NOT
    if all(c.passed for c in known):
        return HOLDS
    return PARTLY if any(c.passed for c in known) else DOES_NOT


# --- reading the report ---------------------------------------------------------------------------

def _cell(rep: Mapping, table: str, run: str, n) -> dict | None:
    c = rep.get(table, {}).get(run, {}).get(str(n))
    return c if c and c.get("safety") is not None else None


def _ns(rep: Mapping, table: str, run: str) -> list[int]:
    return sorted(int(n) for n, c in rep.get(table, {}).get(run, {}).items() if c.get("safety") is not None)


def _name(table: str, run: str, n) -> str:
    return f"{table}/{run}/N={n}"


def _label(rep: Mapping, table: str, run: str) -> str:
    cells = rep.get(table, {}).get(run, {})
    return next(iter(cells.values()), {}).get("label", run) if cells else run


def _fig(c: dict, key: str) -> tuple[float, float, float] | None:
    """(mean, lo, hi) of a cell's figure; None without an interval."""
    ci = c.get(f"{key}_ci")
    return None if c.get(key) is None or not ci else (c[key], ci[0], ci[1])


def _diff(c: dict, key: str) -> tuple[float, float, float] | None:
    v = (c.get("vs_ours") or {}).get(key)
    return None if not v or v["diff"] is None or v["lo"] is None else (v["diff"], v["lo"], v["hi"])


def _pp(x: tuple[float, float, float]) -> str:
    return f"{100 * x[0]:.1f}% [{100 * x[1]:.1f}, {100 * x[2]:.1f}]"


def _dpp(x: tuple[float, float, float]) -> str:
    return f"{100 * x[0]:+.1f} pp [{100 * x[1]:+.1f}, {100 * x[2]:+.1f}]"


def _dcost(x: tuple[float, float, float]) -> str:
    return f"{x[0]:+.3f} [{x[1]:+.3f}, {x[2]:+.3f}]"


def _cost(x: tuple[float, float, float]) -> str:
    return f"{x[0]:.2f} [{x[1]:.2f}, {x[2]:.2f}]"


def _fall(x: tuple[float, float, float]) -> str:
    return f"falls {100 * x[0]:.1f} pp [{100 * x[1]:.1f}, {100 * x[2]:.1f}]"


def _paper_interval(c: dict, key: str) -> tuple[float, float] | None:
    """The paper's value as an interval: its t-interval over :data:`PAPER_SEEDS` seeds where it gives a std, else the point."""
    from scipy.stats import t

    p = c.get(f"paper_{key}")
    if p is None:
        return None
    std = c.get(f"paper_{key}_std")
    if std is None:
        return p, p
    half = float(t.ppf(0.975, PAPER_SEEDS - 1)) * std / math.sqrt(PAPER_SEEDS)
    return p - half, p + half


# --- the checks of each claim --------------------------------------------------------------------

def _beats_ours(rep: Mapping, n: int, runs=BASELINES) -> tuple[list[str], list[str], list[str]]:
    """(cells, the baselines significantly safer than Ours, … significantly cheaper) at N = n."""
    cells, safer, cheaper = [_name(T1, "madpinn", n)], [], []
    for run in runs:
        c = _cell(rep, T1, run, n)
        if c is None:
            continue
        cells.append(_name(T1, run, n))
        ds, dc = _diff(c, "safety"), _diff(c, "cost_time_avg")
        if ds and ds[1] > 0:
            safer.append(f"{_label(rep, T1, run)} Δsafety {_dpp(ds)}")
        if dc and dc[2] < 0:
            cheaper.append(f"{_label(rep, T1, run)} Δcost {_dcost(dc)}")
    return cells, safer, cheaper


def _best_tradeoff(rep: Mapping) -> list[Check]:
    out = []
    for n in _ns(rep, T1, "madpinn"):
        cells, safer, cheaper = _beats_ours(rep, n)
        if len(cells) < 2:
            continue
        out.append(Check(f"N = {n}: no baseline significantly safer nor cheaper than Ours", tuple(cells),
                         "; ".join(safer + cheaper) or "none beats Ours", "Ours safest and cheapest", not (safer or cheaper)))
    return out


def _pareto(rep: Mapping) -> list[Check]:
    out = []
    for n in _ns(rep, T1, "madpinn"):
        cells, dominating = [_name(T1, "madpinn", n)], []
        for run in BASELINES:
            c = _cell(rep, T1, run, n)
            ds, dc = (_diff(c, "safety"), _diff(c, "cost_time_avg")) if c else (None, None)
            if not (ds and dc):
                continue
            cells.append(_name(T1, run, n))
            safer, less_safe, cheaper, costlier = ds[1] > 0, ds[2] < 0, dc[2] < 0, dc[1] > 0
            if (safer and not costlier) or (cheaper and not less_safe):
                dominating.append(f"{_label(rep, T1, run)} (Δsafety {_dpp(ds)}, Δcost {_dcost(dc)})")
        if len(cells) > 1:
            out.append(Check(f"N = {n}: no baseline dominates Ours (better on one axis, not worse on the other)",
                             tuple(cells), "; ".join(dominating) or "Ours not dominated",
                             "Ours bottom-right of every baseline", not dominating))
    return out


def _drop(rep: Mapping, table: str, run: str, lo_n: int, hi_n: int, key: str = "safety"):
    """Our fall of ``key`` from N = lo_n to hi_n: (mean, conservative lo, hi) from the two cells' intervals."""
    a, b = _cell(rep, table, run, lo_n), _cell(rep, table, run, hi_n)
    fa, fb = (_fig(a, key), _fig(b, key)) if a and b else (None, None)
    if not (fa and fb):
        return None, a, b
    return (fa[0] - fb[0], fa[1] - fb[2], fa[2] - fb[1]), a, b


def _scalability(rep: Mapping) -> list[Check]:
    ns = _ns(rep, T1, "madpinn")
    if len(ns) < 2:
        return []
    lo_n, hi_n = ns[0], ns[-1]
    ours, _, _ = _drop(rep, T1, "madpinn", lo_n, hi_n)
    out = []
    for run in BASELINES:
        theirs, _, _ = _drop(rep, T1, run, lo_n, hi_n)
        if ours is None or theirs is None:
            continue
        out.append(Check(f"Ours' safety falls less than {_label(rep, T1, run)}'s from N = {lo_n} to {hi_n}",
                         tuple(_name(T1, r, n) for r in ("madpinn", run) for n in (lo_n, hi_n)),
                         f"Ours {_fall(ours)}; {_label(rep, T1, run)} {_fall(theirs)}",
                         "smaller fall than every baseline", ours[2] < theirs[1]))
    return out


def _safemarl_costlier(rep: Mapping) -> list[Check]:
    out = []
    for run in SAFEMARL_RUNS:
        for n in _ns(rep, T1, run):
            c = _cell(rep, T1, run, n)
            ds, dc = _diff(c, "safety"), _diff(c, "cost_time_avg")
            if not (ds and dc):
                continue
            out.append(Check(f"{_label(rep, T1, run)}, N = {n}: not less safe than Ours and significantly costlier",
                             (_name(T1, run, n), _name(T1, "madpinn", n)), f"Δsafety {_dpp(ds)}, Δcost {_dcost(dc)}",
                             "high safety, substantially higher cost", ds[2] >= 0 and dc[1] > 0))
    return out


def _mppi_poor(rep: Mapping) -> list[Check]:
    out = []
    for n in _ns(rep, T1, "mppi"):
        c = _cell(rep, T1, "mppi", n)
        ds, dc = _diff(c, "safety"), _diff(c, "cost_time_avg")
        if ds and dc:
            out.append(Check(f"N = {n}: MPPI significantly less safe and costlier than Ours",
                             (_name(T1, "mppi", n), _name(T1, "madpinn", n)), f"Δsafety {_dpp(ds)}, Δcost {_dcost(dc)}",
                             "poor on both metrics", ds[2] < 0 and dc[1] > 0))
    return out


def _degrade(rep: Mapping) -> list[Check]:
    out = []
    for run in DEGRADING:
        ns = _ns(rep, T1, run)
        if len(ns) < 2:
            continue
        drop, a, b = _drop(rep, T1, run, ns[0], ns[-1])
        if drop is None:
            continue
        cells = (_name(T1, run, ns[0]), _name(T1, run, ns[-1]))
        label = _label(rep, T1, run)
        out.append(Check(f"{label}: safety falls from N = {ns[0]} to {ns[-1]}", cells,
                         f"{_pp(_fig(a, 'safety'))} → {_pp(_fig(b, 'safety'))}", "falls", drop[1] > 0, essential=True))
        pa, pb = a.get("paper_safety"), b.get("paper_safety")
        if pa is not None and pb is not None:
            out.append(Check(f"{label}: the fall is as large as the paper's", cells,
                             _fall(drop),
                             f"{100 * pa:.1f} → {100 * pb:.1f}% (fall {100 * (pa - pb):.1f} pp)",
                             drop[1] <= pa - pb <= drop[2]))
    return out


def _values(table: str, keys=("safety",)) -> Callable[[Mapping], list[Check]]:
    """The paper's numbers of ``table`` reproduce: each paper value in (or its interval overlapping) ours."""
    def checks(rep: Mapping) -> list[Check]:
        from madpinn.evaluation.reproduction import paper_values

        rows = paper_values().get(table, {}).get("runs", {})
        out = []
        for run, cells in rep.get(table, {}).items():
            if run not in rows:   # our extensions compared with a paper row (``also``) are not the paper's numbers
                continue
            for n, c in cells.items():
                for key in keys:
                    ours, paper = (_fig(c, key), _paper_interval(c, key)) if c.get("safety") is not None else (None, None)
                    if ours is None or paper is None:
                        continue
                    shown = (f"{100 * c[f'paper_{key}']:.1f}%" + (f" (t-interval {100 * paper[0]:.1f}, {100 * paper[1]:.1f})"
                                                                  if paper[0] != paper[1] else ""))
                    out.append(Check(f"{c['label']}, N = {n}: {key.replace('_', ' ')} reproduces", (_name(table, run, n),),
                                     _pp(ours), shown, ours[1] <= paper[1] and paper[0] <= ours[2]))
        return out
    return checks


def _scales(rep: Mapping) -> list[Check]:
    out = []
    for n in _ns(rep, T2, "madpinn"):
        c = _cell(rep, T2, "madpinn", n)
        for key in ("safety", "safe_scenarios"):
            ours, p = _fig(c, key), c.get(f"paper_{key}")
            if ours is None or p is None:
                continue
            out.append(Check(f"N = {n}: {key.replace('_', ' ')} reaches the paper's", (_name(T2, "madpinn", n),),
                             _pp(ours), f"{100 * p:.2f}%", ours[2] >= p))
    return out


def _neighbour_safety(rep: Mapping) -> list[Check]:
    value, nearest, random = NEIGHBOURS
    out = []
    for n in _ns(rep, T3, nearest):
        c_near, c_rand = _cell(rep, T3, nearest, n), _cell(rep, T3, random, n)
        d = _diff(c_near, "safety")
        if d and c_near.get("vs_ours", {}).get("reference") == value:
            out.append(Check(f"N = {n}: value-based safer than nearest", (_name(T3, value, n), _name(T3, nearest, n)),
                             f"nearest − value Δsafety {_dpp(d)}", "99.33 > 83 %", d[2] < 0))
        if c_rand is not None:
            fn, fr = _fig(c_near, "safety"), _fig(c_rand, "safety")
            if fn and fr:
                out.append(Check(f"N = {n}: nearest safer than random", (_name(T3, nearest, n), _name(T3, random, n)),
                                 f"nearest {_pp(fn)}, random {_pp(fr)}", "83 > 33 %", fr[2] < fn[1]))
    return out


def _neighbour_cost(rep: Mapping) -> list[Check]:
    value = NEIGHBOURS[0]
    out = []
    for run in NEIGHBOURS[1:]:
        for n in _ns(rep, T3, run):
            c = _cell(rep, T3, run, n)
            d = _diff(c, "cost_time_avg")
            if d and c["vs_ours"]["reference"] == value:
                out.append(Check(f"N = {n}: value-based cheaper than {c['label'].lower()}", (_name(T3, value, n), _name(T3, run, n)),
                                 f"{c['label'].lower()} − value Δcost {_dcost(d)}",
                                 f"{c.get('paper_cost')} vs {_cell(rep, T3, value, n) and _cell(rep, T3, value, n).get('paper_cost')}",
                                 d[1] > 0))
    return out


def _trend(key: str, falls: bool) -> Callable[[Mapping], list[Check]]:
    """Table IV: ``key`` falls (``falls``) or rises as k grows: essential, significant from the first
    k to the last (non-overlapping intervals); and no step of k significantly the other way."""
    word = "falls" if falls else "rises"
    name = "safety" if key == "safety" else "cost ÷T"
    fmt = _pp if key == "safety" else _cost

    def checks(rep: Mapping) -> list[Check]:
        out = []
        runs = [r for r in UPDATES if rep.get(T4, {}).get(r)]
        ns = sorted(set.intersection(*(set(_ns(rep, T4, r)) for r in runs))) if runs else []
        for n in ns:
            figs = [(r, _fig(_cell(rep, T4, r, n), key)) for r in runs]
            figs = [(r, f) for r, f in figs if f]
            if len(figs) < 2:
                continue
            (r0, f0), (r1, f1) = figs[0], figs[-1]
            lab = lambda r: _label(rep, T4, r).split(" (")[0]   # noqa: E731
            sig = f1[2] < f0[1] if falls else f1[1] > f0[2]
            out.append(Check(f"N = {n}: {name} {word} from k = {lab(r0)} to k = {lab(r1)}", (_name(T4, r0, n), _name(T4, r1, n)),
                             f"{fmt(f0)} → {fmt(f1)}", word, sig, essential=True))
            for (ra, fa), (rb, fb) in zip(figs, figs[1:]):
                against = fb[1] > fa[2] if falls else fb[2] < fa[1]
                out.append(Check(f"N = {n}: k = {lab(ra)} → {lab(rb)}: {name} not significantly {'higher' if falls else 'lower'}",
                                 (_name(T4, ra, n), _name(T4, rb, n)), f"{fmt(fa)} → {fmt(fb)}", word, not against))
        return out
    return checks


def _k5_comparable(rep: Mapping) -> list[Check]:
    out = []
    for n in _ns(rep, T4, UPDATES[0]):
        c = _cell(rep, T4, UPDATES[0], n)
        if not c or (c.get("vs_ours") or {}).get("reference") != UPDATES[1]:
            continue
        ds, dc = _diff(c, "safety"), _diff(c, "cost_time_avg")
        cells = (_name(T4, UPDATES[0], n), _name(T4, UPDATES[1], n))
        if ds:
            out.append(Check(f"N = {n}: k = 5 as safe as k = 1 within ±{100 * COMPARABLE_SAFETY:g} pp", cells,
                             f"k1 − k5 Δsafety {_dpp(ds)}", "99.99 vs 99.33 %",
                             -COMPARABLE_SAFETY <= ds[1] and ds[2] <= COMPARABLE_SAFETY))
        if dc:
            out.append(Check(f"N = {n}: k = 5 as cheap as k = 1 within ±{COMPARABLE_COST:g}", cells,
                             f"k1 − k5 Δcost {_dcost(dc)}", "0.49 vs 0.51", -COMPARABLE_COST <= dc[1] and dc[2] <= COMPARABLE_COST))
    return out


CLAIMS = (
    Claim("best_tradeoff", "Ours attains the lowest cumulative cost while maintaining near-perfect safety rates "
          "across all settings (the best safety–performance trade-off)", "tex 425 (Results 1); Fig. 2 caption, tex 287-293",
          "per agent count: no paper baseline significantly safer (Δsafety interval > 0) nor cheaper (Δcost interval < 0) than Ours",
          _best_tradeoff),
    Claim("fig2_ordering", "Cost–safety figure: Ours consistently appears in the bottom-right region, "
          "superior to all baselines", "Fig. 2 caption, tex 287-293",
          "per agent count: no baseline dominates Ours (significantly better on one axis and not significantly worse on the other)",
          _pareto),
    Claim("fig2_scalability", "Ours' degradation with increasing agent count is minimal: better scalability than the baselines",
          "Fig. 2 caption, tex 287-293",
          "per baseline: Ours' safety fall from the fewest to the most agents significantly smaller than the baseline's "
          "(conservative interval of each fall from the two cells' intervals)", _scalability),
    Claim("safemarl_costlier", "SafeMARL maintains high safety but incurs substantially higher costs due to conservative behaviour",
          "tex 425 (Results 1)",
          "per SafeMARL run (ours and the authors' layered filter) and agent count: Δsafety interval not below 0 and "
          "Δcost interval above 0", _safemarl_costlier),
    Claim("mppi_poor", "MPPI performs poorly on both metrics (safety enforced only through soft penalties)", "tex 425 (Results 1)",
          "per agent count: MPPI's Δsafety interval below 0 and Δcost interval above 0", _mppi_poor),
    Claim("defmarl_mppi_degrade", "DEF-MARL and MPPI deteriorate rapidly with increasing density", "tex 425 (Results 1), Table I",
          "per run: essential, safety at the most agents significantly below the fewest (non-overlapping intervals); "
          "and the paper's fall inside the interval of ours", _degrade),
    Claim("table1_values", "Table I: safety per method and agent count", "Table I, tex 357-375",
          "per cell: the paper's t-interval (its mean ± std over 5 seeds) overlaps our 95 % interval", _values(T1)),
    Claim("table2_scales", "Table II: Ours maintains high safety rates and safe-scenario percentages even with 256 agents",
          "Table II, tex 410-424; Results 2, tex 427",
          "per agent count and figure: our interval reaches the paper's value (upper end ≥ paper)", _scales),
    Claim("neighbour_safety_order", "Table III: value-based neighbours are safer than nearest, nearest safer than random",
          "Table III, tex 429-443; Results 3, tex 445",
          "nearest − value Δsafety interval below 0; random's interval below nearest's", _neighbour_safety),
    Claim("neighbour_cost_least", "Table III: value-based neighbour selection achieves the lowest costs",
          "Results 3, tex 445", "per alternative: its − value Δcost interval above 0", _neighbour_cost),
    Claim("table3_values", "Table III: safety per neighbour selection", "Table III, tex 429-443",
          "per row: the paper's value inside our 95 % interval", _values(T3)),
    Claim("update_safety_falls", "Table IV: safety degrades significantly as updates become infrequent",
          "Table IV caption, tex 447-466; Results 4, tex 467",
          "essential: safety at k = ∞ significantly below k = 1; and no step of k significantly safer than the one before",
          _trend("safety", falls=True)),
    Claim("update_cost_rises", "Table IV: more frequent updates improve performance (cost rises as k grows)",
          "Results 4, tex 467", "essential: cost at k = ∞ significantly above k = 1; and no step of k significantly "
          "cheaper than the one before", _trend("cost_time_avg", falls=False)),
    Claim("update_k5_comparable", "Table IV: k = 5 achieves comparable safety and performance to updating every step",
          "Results 4, tex 467",
          f"k1 − k5 interval within ±{100 * COMPARABLE_SAFETY:g} pp of safety and ±{COMPARABLE_COST:g} of cost ÷T",
          _k5_comparable),
    Claim("table4_values", "Table IV: safety per update period k", "Table IV, tex 447-466",
          "per row: the paper's value inside our 95 % interval", _values(T4)),
)
"""every claim the table tests, in the paper's order"""


def build_claims(report: Mapping, claims=CLAIMS) -> dict:
    """``{"claims": [{id, claim, source, rule, verdict, checks: [...], cells: [...]}], "verdicts": {id: verdict},
    "provenance": {...}}`` from a reproduction report (its JSON as a dict)."""
    out = []
    for cl in claims:
        checks = cl.checks(report)
        cells = sorted({c for ch in checks for c in ch.cells})
        out.append({"id": cl.id, "claim": cl.text, "source": cl.source, "rule": cl.rule, "verdict": verdict(checks),
                    "passed": sum(bool(c.passed) for c in checks), "checks_total": len(checks), "cells": cells,
                    "checks": [{"check": c.what, "cells": list(c.cells), "ours": c.ours, "paper": c.paper,
                                "passed": c.passed, "essential": c.essential} for c in checks]})
    prov = report.get("provenance", {})
    return {"claims": out, "verdicts": {c["id"]: c["verdict"] for c in out},
            "provenance": {"config_hash": prov.get("config_hash"),
                           "collisions": prov.get("collisions"), "intervals": prov.get("intervals"),
                           "rule": "a failed essential check: does not hold; else all checks pass: holds; "
                                   "some: partly; none: does not hold (madpinn/evaluation/claims.py)"}}


def _headline(c: dict) -> str:
    """The decisive figure of a claim: its first failed essential check, else its first failed check,
    else its first; prefixed with whether that check passed (the check reads as a question)."""
    checks = c["checks"]
    if not checks:
        return "–"
    failed = [ch for ch in checks if ch["passed"] is False]
    pick = next((ch for ch in failed if ch["essential"]), failed[0] if failed else checks[0])
    mark = {True: "passed", False: "failed", None: "not tested"}[pick["passed"]]
    return f"{mark}: {pick['check']}: {pick['ours']}"


def to_markdown(claims: dict) -> str:
    prov = claims["provenance"]
    lines = ["# The paper's claims, tested", "",
             "Generated by the workflow (`snakemake -j2 claims_table`; madpinn/evaluation/claims.py) from "
             "`reproduction.json`: each claim of the paper, the report cells it rests on, our figures with their 95 % "
             "intervals, and a verdict computed by the rule written beside it, never typed. "
             f"Verdict rule: {prov['rule']}.", "",
             f"- config hash `{prov.get('config_hash')}`",
             f"- collisions: {prov.get('collisions')}", f"- intervals: {prov.get('intervals')}", "",
             "| # | Paper claim | Where | Verdict | Checks passed | Decisive figure (ours, 95 % interval) |",
             "|---|---|---|---|---|---|"]
    for i, c in enumerate(claims["claims"], 1):
        lines.append(f"| {i} | {c['claim']} | {c['source']} | **{c['verdict']}** | {c['passed']} / {c['checks_total']} "
                     f"| {_headline(c)} |")
    for i, c in enumerate(claims["claims"], 1):
        lines += ["", f"## {i}. {c['id']}: {c['verdict']}", "", f"*{c['claim']}* ({c['source']}).", "",
                  f"Rule: {c['rule']}.", "", "| check | ours | paper | passed |", "|---|---|---|---|"]
        for ch in c["checks"]:
            mark = "–" if ch["passed"] is None else ("yes" if ch["passed"] else "no")
            lines.append(f"| {ch['check']}{' (essential)' if ch['essential'] else ''} | {ch['ours']} | {ch['paper']} | {mark} |")
    return "\n".join(lines) + "\n"


def readme_lines(claims: dict) -> list[str]:
    """The README's quotation of the verdicts (``tests/test_readme_blocks.py`` checks README against it)."""
    return [f"- {c['claim']} ({c['source'].split(',')[0]}): **{c['verdict']}**" for c in claims["claims"]]


def write_claims(report_path: str | Path, out_dir: str | Path) -> list[Path]:
    """Read ``reproduction.json`` at ``report_path``; write ``claims.json``, ``claims.md`` and
    ``claims.html`` (the page the Snakemake report shows) into ``out_dir``."""
    from madpinn.evaluation.html import markdown_page

    report = json.loads(Path(report_path).read_text())
    if not isinstance(report, dict) or "provenance" not in report:
        raise ValueError(f"{report_path} is not a reproduction report (no provenance)")
    claims = build_claims(report)
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    js, md, page = out_dir / "claims.json", out_dir / "claims.md", out_dir / "claims.html"
    js.write_text(json.dumps(claims, indent=2, ensure_ascii=False))
    md.write_text(to_markdown(claims))
    page.write_text(markdown_page(md.read_text(), "The paper's claims, tested"))
    return [js, md, page]
