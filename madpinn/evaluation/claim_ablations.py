"""The rules of the paper's Table II–IV claims (Results 2–4, tex 427, 445, 467), phrased as in
:mod:`madpinn.evaluation.claim_rules`.

Cost conventions: the paper's metric is cost "accumulated along safe trajectories" (tex, Evaluation
Metrics): cost over collision-free agents, the stated reading. Cost over all agents is an unstated
reading; the report gives it as a point value without an interval, so its checks are shown and
not judged (``passed`` None).
"""

from __future__ import annotations

from typing import Callable, Mapping

from madpinn.evaluation.claim_checks import (
    STATED, Check, above, below, cell, cost, dcost, diff, dpp, fig, label, name, ns, pct, pp, reaches, width,
)
from madpinn.evaluation.claim_rules import T2, T3, T4, paper_rows

NEIGHBOURS = ("madpinn-value", "madpinn-nearest", "madpinn-random")
UPDATES = ("madpinn-k1", "madpinn-k5", "madpinn-k10", "madpinn-k20", "madpinn-k50", "madpinn-k100",
           "madpinn-k500", "madpinn-kinf")
COMPARABLE_SAFETY = 0.01
"""equivalence margin of "comparable safety" (fraction: 1 percentage point)"""
COMPARABLE_COST = 0.02
"""equivalence margin of "comparable cost" (cost ÷T)"""
ALL_AGENTS = "cost over all agents (not the paper's metric)"


def table2_scales(rep: Mapping) -> list[Check]:
    """Per MAD-PINN run of Table II and N: safety (essential at the most agents) and safe scenarios reach the
    paper's; cost not above the paper's (our interval's lower end ≤ paper)."""
    out = []
    for run in rep.get(T2, {}):
        if not run.startswith("madpinn"):   # Ours and our labelled variants of it
            continue
        stated, lab, mine = run in paper_rows(T2), label(rep, T2, run), ns(rep, T2, run)
        reading = {"reading": STATED if stated else lab, "stated": stated, "row": "madpinn"}
        for n in mine:
            c, row = cell(rep, T2, run, n), cell(rep, T2, "madpinn", n) or {}   # the paper's row: Ours
            for key, word in (("safety", "safety"), ("safe_scenarios", "safe scenarios")):
                f, p = fig(c, key), row.get(f"paper_{key}")
                if f is not None and p is not None:
                    ok, m = reaches(f, p)
                    out.append(Check(f"N = {n}: {word} as high as the paper's {pct(p)}", f"{lab} {pp(f)}",
                                     (name(T2, run, n),), ok, pct(p), word, essential=key == "safety" and n == mine[-1],
                                     margin=m, **reading))
            f, p = fig(c, "cost_time_avg"), row.get("paper_cost")
            if f is not None and p is not None:
                ok, m = f[1] <= p, (p - f[1]) / width(f)
                out.append(Check(f"N = {n}: cost ÷T not above the paper's {p:g}", f"{lab} {cost(f)}", (name(T2, run, n),),
                                 ok, f"{p:g}", "cost", margin=m, **reading))
    return out


def neighbour_safety(rep: Mapping) -> list[Check]:
    """Value-based significantly safer than nearest; nearest's interval above random's."""
    value, nearest, random = NEIGHBOURS
    out = []
    for n in ns(rep, T3, nearest):
        c_near, c_rand = cell(rep, T3, nearest, n), cell(rep, T3, random, n)
        p = {r: (cell(rep, T3, r, n) or {}).get("paper_safety") for r in NEIGHBOURS}
        d = diff(c_near, "safety")
        if d and c_near.get("vs_ours", {}).get("reference") == value:
            ok, m = below(d, 0.0)
            out.append(Check(f"N = {n}: value-based safer than nearest", f"nearest − value Δsafety {dpp(d)}",
                             (name(T3, value, n), name(T3, nearest, n)), ok, f"{pct(p[value])} > {pct(p[nearest])}",
                             "value vs nearest", margin=m))
        fn, fr = fig(c_near, "safety"), fig(c_rand, "safety")
        if fn and fr:
            out.append(Check(f"N = {n}: nearest safer than random", f"nearest {pp(fn)}, random {pp(fr)}",
                             (name(T3, nearest, n), name(T3, random, n)), fr[2] < fn[1],
                             f"{pct(p[nearest])} > {pct(p[random])}", "nearest vs random",
                             margin=(fn[1] - fr[2]) / max(fn[2] - fn[1] + fr[2] - fr[1], 1e-3)))
    return out


def neighbour_cost(rep: Mapping) -> list[Check]:
    """Per alternative: its − value Δcost interval above 0 (stated); all-agent cost point values shown."""
    value = NEIGHBOURS[0]
    out = []
    for run in NEIGHBOURS[1:]:
        for n in ns(rep, T3, run):
            c, v = cell(rep, T3, run, n), cell(rep, T3, value, n)
            d = diff(c, "cost_time_avg")
            cells = (name(T3, value, n), name(T3, run, n))
            paper = f"{c.get('paper_cost')} vs {(v or {}).get('paper_cost')}"
            if d and c["vs_ours"]["reference"] == value:
                ok, m = above(d, 0.0)
                out.append(Check(f"N = {n}: lowest cost: value-based significantly cheaper than {c['label'].lower()}",
                                 f"{c['label'].lower()} − value Δcost {dcost(d)}", cells, ok, paper, "cost", margin=m))
            if v and c.get("cost_all_time_avg") is not None and v.get("cost_all_time_avg") is not None:
                out.append(Check(f"N = {n}: value-based cheaper than {c['label'].lower()}, cost over all agents",
                                 f"{c['label'].lower()} {c['cost_all_time_avg']:.3f}, value {v['cost_all_time_avg']:.3f} "
                                 "(point values, no interval: not judged)", cells, None, paper, "cost",
                                 reading=ALL_AGENTS, stated=False))
    return out


def _series(rep: Mapping, key: str) -> list[tuple[int, list[tuple[str, tuple]]]]:
    runs = [r for r in UPDATES if rep.get(T4, {}).get(r)]
    common = sorted(set.intersection(*(set(ns(rep, T4, r)) for r in runs))) if runs else []
    out = []
    for n in common:
        figs = [(r, fig(cell(rep, T4, r, n), key)) for r in runs]
        figs = [(r, f) for r, f in figs if f]
        if len(figs) >= 2:
            out.append((n, figs))
    return out


def _k(rep, r) -> str:
    return label(rep, T4, r).split(" (")[0]


def trend(key: str, falls: bool) -> Callable[[Mapping], list[Check]]:
    """Table IV: ``key`` falls (``falls``) or rises as k grows: essential, significantly from the first
    k to the last; and no step of k significantly the other way."""
    word, name_ = ("falls" if falls else "rises"), ("safety" if key == "safety" else "cost ÷T")
    fmt = pp if key == "safety" else cost

    def checks(rep: Mapping) -> list[Check]:
        out = []
        for n, figs in _series(rep, key):
            (r0, f0), (r1, f1) = figs[0], figs[-1]
            ok, m = below(f1, f0[1]) if falls else above(f1, f0[2])
            out.append(Check(f"N = {n}: {name_} {word} from k = {_k(rep, r0)} to k = {_k(rep, r1)}",
                             f"{fmt(f0)} → {fmt(f1)}", (name(T4, r0, n), name(T4, r1, n)), ok, word, name_,
                             essential=True, margin=m))
            for (ra, fa), (rb, fb) in zip(figs, figs[1:]):
                gap = fa[2] - fb[1] if falls else fb[2] - fa[1]   # < 0: significantly the other way
                out.append(Check(f"N = {n}: k = {_k(rep, ra)} → {_k(rep, rb)}: {name_} not significantly "
                                 f"{'higher' if falls else 'lower'}", f"{fmt(fa)} → {fmt(fb)}",
                                 (name(T4, ra, n), name(T4, rb, n)), gap >= 0, word, name_,
                                 margin=gap / max(fa[2] - fa[1] + fb[2] - fb[1], 1e-3)))
            if key == "cost_time_avg":
                c0, c1 = cell(rep, T4, r0, n), cell(rep, T4, r1, n)
                a, b = c0.get("cost_all_time_avg"), c1.get("cost_all_time_avg")
                if a is not None and b is not None:
                    out.append(Check(f"N = {n}: cost over all agents rises from k = {_k(rep, r0)} to k = {_k(rep, r1)}",
                                     f"{a:.3f} → {b:.3f} (point values, no interval: not judged)",
                                     (name(T4, r0, n), name(T4, r1, n)), None, word, name_,
                                     reading=ALL_AGENTS, stated=False))
        return out
    return checks


def k5_comparable(rep: Mapping) -> list[Check]:
    """k1 − k5 intervals within ± :data:`COMPARABLE_SAFETY` and ± :data:`COMPARABLE_COST`."""
    k1, k5 = UPDATES[0], UPDATES[1]
    out = []
    for n in ns(rep, T4, k1):
        c, c5 = cell(rep, T4, k1, n), cell(rep, T4, k5, n) or {}
        if not c or (c.get("vs_ours") or {}).get("reference") != k5:
            continue
        cells = (name(T4, k1, n), name(T4, k5, n))
        for key, margin, fmt, shown, paper in (
                ("safety", COMPARABLE_SAFETY, dpp, f"±{100 * COMPARABLE_SAFETY:g} pp",
                 f"{pct(c.get('paper_safety'))} vs {pct(c5.get('paper_safety'))}"),
                ("cost_time_avg", COMPARABLE_COST, dcost, f"±{COMPARABLE_COST:g}",
                 f"{c.get('paper_cost')} vs {c5.get('paper_cost')}")):
            d = diff(c, key)
            if d:
                ok = -margin <= d[1] and d[2] <= margin
                what = "safety" if key == "safety" else "cost ÷T"
                out.append(Check(f"N = {n}: k = 5 as good as k = 1 on {what} within {shown}", f"k1 − k5 Δ{what} {fmt(d)}",
                                 cells, ok, paper, what, margin=(margin - max(abs(d[1]), abs(d[2]))) / max(d[2] - d[1], 1e-3)))
    return out


def safety_more_sensitive(rep: Mapping) -> list[Check]:
    """k = 1 → ∞: safety's relative fall larger than cost's relative rise (conservative ends)."""
    out = []
    s_series, c_series = dict(_series(rep, "safety")), dict(_series(rep, "cost_time_avg"))
    for n in sorted(set(s_series) & set(c_series)):
        (r0, s0), (r1, s1) = s_series[n][0], s_series[n][-1]
        (_, c0), (_, c1) = c_series[n][0], c_series[n][-1]
        s_fall = (s0[1] - s1[2]) / s0[2]          # smallest relative safety fall the intervals allow
        c_rise = (c1[2] - c0[1]) / c0[1]          # largest relative cost rise the intervals allow
        out.append(Check(f"N = {n}: k = {_k(rep, r0)} → {_k(rep, r1)}: safety falls by a larger share than cost rises",
                         f"safety changes by ≤ {-100 * s_fall:+.1f} %, cost by ≤ {100 * c_rise:+.1f} %",
                         (name(T4, r0, n), name(T4, r1, n)), s_fall > c_rise, "safety much more sensitive",
                         "sensitivity", margin=s_fall - c_rise))
    return out


PROPORTIONAL = "cost ratio at most the arena side ratio (our reading: the paper states no tolerance)"


def cost_proportional(rep: Mapping) -> list[Check]:
    """Per Table II N: Ours' cost ÷T over its Table I cost ÷T at the most agents, conservative interval
    from the two cells' intervals, not significantly above the arena side ratio (paper_values.yaml)."""
    from madpinn.evaluation.claim_rules import T1
    from madpinn.evaluation.paper_consistency import raw

    sides = raw()["protocol"]["arena_side"]
    side = sides["large"] / sides["small"]
    small_ns = ns(rep, T1, "madpinn")
    base = fig(cell(rep, T1, "madpinn", small_ns[-1]), "cost_time_avg") if small_ns else None
    out = []
    for n in ns(rep, T2, "madpinn") if base else []:
        f = fig(cell(rep, T2, "madpinn", n), "cost_time_avg")
        if f is None:
            continue
        r = (f[0] / base[0], f[1] / base[2], f[2] / base[1])
        out.append(Check(f"N = {n}: cost ÷T at most {side:g}× Table I's at N = {small_ns[-1]} (arena side {sides['small']:g} "
                         f"→ {sides['large']:g} m)", f"ratio {r[0]:.2f} [{r[1]:.2f}, {r[2]:.2f}]",
                         (name(T2, "madpinn", n), name(T1, "madpinn", small_ns[-1])), r[1] <= side,
                         f"paper: Table II {(cell(rep, T2, 'madpinn', n) or {}).get('paper_cost')}; Table I cost only plotted",
                         "cost", margin=(side - r[1]) / max(r[2] - r[1], 1e-3), reading=PROPORTIONAL, stated=False))
    return out
