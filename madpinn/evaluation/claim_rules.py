"""The rules of the paper's comparative claims (Results 1, Fig. 2; tex 287-293, 425): each turns the
report's cells into :class:`~madpinn.evaluation.claim_checks.Check` s phrased "expected … /
observed …", one reading per run compared (the paper's own row: stated; our labelled extensions
such as the authors' layered SafeMARL filter: unstated).

Significance (``vs_ours``: run − Ours on the same scenarios): a run is *safer* / *less safe* than
Ours when its Δ safety interval lies above / below 0, *cheaper* / *costlier* when its Δ cost ÷T
interval lies below / above 0. Two cells of different agent counts differ when their intervals do
not overlap (conservative). Cost is the paper's metric, "accumulated along safe trajectories"
(collision-free agents, ``cost_time_avg``).
"""

from __future__ import annotations

from functools import lru_cache
from typing import Mapping

from madpinn.evaluation.claim_checks import (
    STATED, Check, above, below, cell, dcost, diff, direction, dpp, drop, fall, fig, label, name, ns, pct, pp, reaches,
)

T1, T2, T3, T4 = "table_safety_scaling", "table_ours_scaling", "table_neighbour_ablation", "table_update_ablation"
BASELINE_ROWS = ("defmarl-n3", "defmarl-n8", "safemarl", "mppi")
"""the paper's baselines (Table I rows other than Ours)"""


@lru_cache(maxsize=None)
def paper_rows(table: str) -> tuple[str, ...]:
    """The runs that are rows of the paper's ``table`` (paper_values.yaml)."""
    from madpinn.evaluation.reproduction import paper_values

    return tuple(paper_values().get(table, {}).get("runs", {}))


@lru_cache(maxsize=None)
def also(table: str, run: str) -> tuple[str, ...]:
    """Our extensions compared with the paper's row ``run`` (its ``also``)."""
    from madpinn.evaluation.reproduction import paper_values

    return tuple(paper_values().get(table, {}).get("runs", {}).get(run, {}).get("also", ()))


def readings(rep: Mapping, table: str, row: str) -> list[tuple[str, bool]]:
    """(run, stated) of the paper's row and of its extensions the report holds."""
    return [(r, r == row) for r in (row, *also(table, row)) if rep.get(table, {}).get(r)]


def _reading(rep, table, run, stated, row) -> dict:
    """The reading fields of a check on ``run``, which stands for the paper's row ``row``."""
    return {"reading": STATED if stated else label(rep, table, run), "stated": stated, "row": row}


def near_perfect() -> float:
    """"Near-perfect safety", read as the lowest safety of Ours in the paper's Table I."""
    from madpinn.evaluation.reproduction import paper_values

    return min(c["safety"] for c in paper_values()[T1]["runs"]["madpinn"]["n"].values())


def best_tradeoff(rep: Mapping) -> list[Check]:
    """Per N: no baseline significantly cheaper than Ours; Ours' safety reaches :func:`near_perfect`."""
    out, bar = [], near_perfect()
    for n in ns(rep, T1, "madpinn"):
        runs = [r for r in BASELINE_ROWS if diff(cell(rep, T1, r, n), "cost_time_avg")]
        ds = {r: diff(cell(rep, T1, r, n), "cost_time_avg") for r in runs}
        cells = (name(T1, "madpinn", n), *(name(T1, r, n) for r in runs))
        if runs:
            cheaper = [f"{label(rep, T1, r)} Δcost {dcost(d)}" for r, d in ds.items() if d[2] < 0]
            m = min(d[2] / max(d[2] - d[1], 1e-3) for d in ds.values())
            out.append(Check(f"N = {n}: lowest cost: no baseline significantly cheaper than Ours",
                             "cheaper than Ours: " + "; ".join(cheaper) if cheaper else "no baseline significantly cheaper",
                             cells, not cheaper, "Ours lowest", "cost", margin=m))
        s = fig(cell(rep, T1, "madpinn", n), "safety")
        if s:
            ok, m = reaches(s, bar)
            out.append(Check(f"N = {n}: near-perfect safety: Ours' interval reaches {pct(bar)} (the paper's lowest Ours safety)",
                             f"Ours {pp(s)}", (name(T1, "madpinn", n),), ok, "near-perfect", "safety", margin=m))
    return out


def _dominates(d_s, d_c) -> bool:
    safer, less_safe, cheaper, costlier = d_s[1] > 0, d_s[2] < 0, d_c[2] < 0, d_c[1] > 0
    return (safer and not costlier) or (cheaper and not less_safe)


def fig2_ordering(rep: Mapping) -> list[Check]:
    """Per baseline and N: the baseline does not dominate Ours (better on one axis, not worse on the other)."""
    out = []
    for row in BASELINE_ROWS:
        for run, stated in readings(rep, T1, row):
            for n in ns(rep, T1, run):
                c = cell(rep, T1, run, n)
                d_s, d_c = diff(c, "safety"), diff(c, "cost_time_avg")
                if not (d_s and d_c):
                    continue
                lab = label(rep, T1, run)
                obs = (f"{lab} {direction(d_s, 'safer', 'less safe')} (Δsafety {dpp(d_s)}), "
                       f"{direction(d_c, 'costlier', 'cheaper')} (Δcost {dcost(d_c)})")
                out.append(Check(f"N = {n}: {lab} does not dominate Ours", obs, (name(T1, run, n), name(T1, "madpinn", n)),
                                 not _dominates(d_s, d_c), "Ours bottom-right", "cost and safety", **_reading(rep, T1, run, stated, row)))
    return out


def fig2_scalability(rep: Mapping) -> list[Check]:
    """Per baseline: Ours' safety fall from the fewest to the most agents significantly smaller."""
    mine = ns(rep, T1, "madpinn")
    if len(mine) < 2:
        return []
    lo_n, hi_n = mine[0], mine[-1]
    ours = drop(rep, T1, "madpinn", lo_n, hi_n)
    out = []
    for row in BASELINE_ROWS:
        for run, stated in readings(rep, T1, row):
            theirs = drop(rep, T1, run, lo_n, hi_n)
            if ours is None or theirs is None:
                continue
            lab = label(rep, T1, run)
            out.append(Check(f"N = {lo_n} → {hi_n}: Ours' safety falls less than {lab}'s",
                             f"Ours {fall(ours)}; {lab} {fall(theirs)}",
                             tuple(name(T1, r, n) for r in ("madpinn", run) for n in (lo_n, hi_n)), ours[2] < theirs[1],
                             "smaller fall than every baseline", "safety fall",
                             margin=(theirs[1] - ours[2]) / max(theirs[2] - theirs[1] + ours[2] - ours[1], 1e-3),
                             **_reading(rep, T1, run, stated, row)))
    return out


def _against_ours(rep: Mapping, row: str, safety_test, safety_text: str, safety_part: str,
                  cost_text: str, cost_part: str) -> list[Check]:
    """Per run of ``row`` and N, two paired checks against Ours: ``safety_test(Δsafety, 0)``
    (:func:`reaches` or :func:`below`) and Δcost significantly above 0."""
    out = []
    for run, stated in readings(rep, T1, row):
        lab = label(rep, T1, run)
        for n in ns(rep, T1, run):
            c = cell(rep, T1, run, n)
            d_s, d_c = diff(c, "safety"), diff(c, "cost_time_avg")
            cells = (name(T1, run, n), name(T1, "madpinn", n))
            if d_s:
                ok, m = safety_test(d_s, 0.0)
                out.append(Check(f"N = {n}: {safety_text.format(lab=lab)}",
                                 f"{lab} {direction(d_s, 'safer', 'less safe')}: Δsafety {dpp(d_s)}", cells, ok,
                                 safety_part, "safety", margin=m, **_reading(rep, T1, run, stated, row)))
            if d_c:
                ok, m = above(d_c, 0.0)
                out.append(Check(f"N = {n}: {cost_text.format(lab=lab)}",
                                 f"{lab} {direction(d_c, 'costlier', 'cheaper')}: Δcost {dcost(d_c)}", cells, ok,
                                 cost_part, "cost", margin=m, **_reading(rep, T1, run, stated, row)))
    return out


def safemarl_costlier(rep: Mapping) -> list[Check]:
    """Per SafeMARL run and N: not significantly less safe than Ours, and significantly costlier."""
    return _against_ours(rep, "safemarl", reaches, "high safety: {lab} not significantly less safe than Ours",
                         "high safety", "substantially higher cost: {lab} significantly costlier than Ours",
                         "substantially higher costs")


def mppi_poor(rep: Mapping) -> list[Check]:
    """Per MPPI run and N: significantly less safe than Ours; significantly costlier than Ours."""
    return _against_ours(rep, "mppi", below, "poor safety: {lab} significantly less safe than Ours",
                         "poor on both metrics", "poor cost: {lab} significantly costlier than Ours",
                         "poor on both metrics")


def degrade(rep: Mapping) -> list[Check]:
    """Per DEF-MARL / MPPI run: safety and safe scenarios fall significantly from the fewest to the
    most agents (safety: essential), and fall more than Ours' (the paper's comparison)."""
    out = []
    for row in ("defmarl-n3", "defmarl-n8", "mppi"):
        for run, stated in readings(rep, T1, row):
            mine = ns(rep, T1, run)
            if len(mine) < 2:
                continue
            lo_n, hi_n, lab = mine[0], mine[-1], label(rep, T1, run)
            for key, word in (("safety", "safety"), ("safe_scenarios", "safe scenarios")):
                theirs, ours = drop(rep, T1, run, lo_n, hi_n, key), drop(rep, T1, "madpinn", lo_n, hi_n, key)
                if theirs is None:
                    continue
                cells = (name(T1, run, lo_n), name(T1, run, hi_n))
                ok, m = above(theirs, 0.0)
                out.append(Check(f"N = {lo_n} → {hi_n}: {lab}'s {word} falls", f"{lab} {fall(theirs)}", cells, ok,
                                 "deteriorate rapidly", word, essential=key == "safety", margin=m,
                                 **_reading(rep, T1, run, stated, row)))
                if ours is not None:
                    w = max(theirs[2] - theirs[1] + ours[2] - ours[1], 1e-3)
                    out.append(Check(f"N = {lo_n} → {hi_n}: {lab}'s {word} falls more than Ours'",
                                     f"{lab} {fall(theirs)}; Ours {fall(ours)}",
                                     (*cells, name(T1, "madpinn", lo_n), name(T1, "madpinn", hi_n)), theirs[1] > ours[2],
                                     "rapidly, unlike Ours", word, margin=(theirs[1] - ours[2]) / w,
                                     **_reading(rep, T1, run, stated, row)))
    return out


def safe_scenarios_high(rep: Mapping) -> list[Check]:
    """Per N: Ours' (and its extensions') safe-scenario interval reaches the paper's Table I value."""
    out = []
    row = "madpinn"
    for run, stated in readings(rep, T1, row):
        for n in ns(rep, T1, run):
            c = cell(rep, T1, run, n)
            f, p = fig(c, "safe_scenarios"), c.get("paper_safe_scenarios")
            if f is None or p is None:
                continue
            ok, m = reaches(f, p)
            out.append(Check(f"N = {n}: safe scenarios reach the paper's {pct(p)}", f"{label(rep, T1, run)} {pp(f)}",
                             (name(T1, run, n),), ok, pct(p), "safe scenarios", margin=m, **_reading(rep, T1, run, stated, row)))
    return out
