"""Per-cell value tables (issue 61): each paper number beside our 95 % interval, apart from the claims.

One rule for every table: the paper's value *reproduces* when its interval overlaps ours. The
paper's interval is its t-interval over its seeds (mean ± t(0.975, seeds − 1)·std/√seeds) where it
gives a std, else its point. A cell the paper reports in several tables (``same_cells`` of
paper_values.yaml: Table III's value row and Table IV's k = 5 are Table I's 12-agent cell) takes the
std that one of them gives, so the same cell is judged the same way in every table.
"""

from __future__ import annotations

import math
from typing import Mapping

from madpinn.evaluation.claim_checks import fig, pp

KEYS = (("safety", "safety"), ("safe_scenarios", "safe scenarios"), ("cost_time_avg", "cost ÷T"))


def cost_ci(x: tuple[float, float, float]) -> str:
    """A cost and its interval, ``"1.23 [1.20, 1.26]"``."""
    return f"{x[0]:.2f} [{x[1]:.2f}, {x[2]:.2f}]"


def _shared_std() -> dict[tuple[str, str, int], dict]:
    """(table, run, N) -> {figure: (std, seeds)} borrowed from the same cell in another table."""
    from madpinn.evaluation.paper_consistency import raw
    from madpinn.evaluation.reproduction import paper_values

    values, r = paper_values(), raw()
    seeds, out = r["protocol"]["seeds"], {}
    for group in r.get("same_cells", []):
        keys = [tuple(k.split("/")) for k in group]
        cells = {k: values.get(k[0], {}).get("runs", {}).get(k[1], {}).get("n", {}).get(int(k[2]), {}) for k in keys}
        stds = {f: c[f"{f}_std"] for c in cells.values() for f, _ in KEYS if c.get(f"{f}_std") is not None}
        for k in keys:
            out[(k[0], k[1], int(k[2]))] = {f: (s, seeds) for f, s in stds.items()}
    return out


def paper_interval(c: dict, key: str, std: tuple[float, int] | None = None, seeds: int = 5) -> tuple[float, float] | None:
    """The paper's value of ``key`` as an interval (module docstring)."""
    from scipy.stats import t

    p = c.get("paper_cost" if key == "cost_time_avg" else f"paper_{key}")
    if p is None:
        return None
    s = c.get(f"paper_{key}_std")
    s, k = (s, seeds) if s is not None else std if std else (None, seeds)
    if s is None:
        return p, p
    half = float(t.ppf(0.975, k - 1)) * s / math.sqrt(k)
    return p - half, p + half


def value_rows(rep: Mapping, seeds: int = 5) -> list[dict]:
    """One row per (paper table, paper row, N, figure) the report holds."""
    from madpinn.evaluation.reproduction import paper_table_numbers, paper_values

    shared, out, numbers = _shared_std(), [], paper_table_numbers()
    for table, t in paper_values().items():
        for run in t["runs"]:
            for n, c in rep.get(table, {}).get(run, {}).items():
                if c.get("safety") is None:
                    continue
                for key, word in KEYS:
                    ours = fig(c, key)
                    paper = paper_interval(c, key, shared.get((table, run, int(n)), {}).get(key), seeds)
                    if ours is None or paper is None:
                        continue
                    pct = key != "cost_time_avg"
                    p = c.get("paper_cost" if not pct else f"paper_{key}")
                    shown = (f"{100 * p:.6g} %" if pct else f"{p:g}") + (
                        f" (t-interval {100 * paper[0]:.1f}, {100 * paper[1]:.1f})" if pct and paper[0] != paper[1] else "")
                    out.append({"table": table, "paper_table": f"Table {numbers.get(table, table)}", "run": run, "label": c["label"], "n": int(n), "figure": word,
                                "ours": pp(ours) if pct else cost_ci(ours),
                                "paper": shown, "reproduces": ours[1] <= paper[1] and paper[0] <= ours[2]})
    return out


def rows_not_in_paper(rep: Mapping) -> list[dict]:
    """Our rows of the paper's tables that the paper does not have (the calibrated level, the governors,
    the sensitivity runs, the reference rows): one row per (paper table, row, N) with safety, safe
    scenarios and cost ÷T [95 %] and the paired safety / cost difference from the table's Ours; judged
    nowhere (no paper value to compare)."""
    from madpinn.evaluation.claim_checks import dcost, diff, dpp
    from madpinn.evaluation.reproduction import paper_table_numbers, paper_values

    out, numbers = [], paper_table_numbers()
    for table, t in paper_values().items():
        for run, cells in rep.get(table, {}).items():
            if run in t["runs"]:
                continue
            for n, c in cells.items():
                if c.get("safety") is None:
                    continue
                show = {key: fig(c, key) for key, _ in KEYS}
                d_safety, d_cost = diff(c, "safety"), diff(c, "cost_time_avg")
                out.append({"table": table, "paper_table": f"Table {numbers.get(table, table)}", "run": run, "label": c["label"],
                            "n": int(n),
                            "safety": pp(show["safety"]) if show["safety"] else f"{100 * c['safety']:.1f} %",
                            "safe_scenarios": pp(show["safe_scenarios"]) if show["safe_scenarios"] else
                            (f"{100 * c['safe_scenarios']:.1f} %" if c.get("safe_scenarios") is not None else "–"),
                            "cost": cost_ci(show["cost_time_avg"]) if show["cost_time_avg"] else
                            (f"{c['cost_time_avg']:.2f}" if c.get("cost_time_avg") is not None else "–"),
                            "vs_ours": "–" if not d_safety else dpp(d_safety) + (f" / {dcost(d_cost)}" if d_cost else "")})
    return out
