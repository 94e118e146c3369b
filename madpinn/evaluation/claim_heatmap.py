"""The paper's reading of its value heatmap (Setup, tex 406): "Regions of high value (red) correspond
to unsafe states overlapping with the positions of other agents ... regions of low value (blue) are
concentrated around the goal", tested on the numbers the heatmap job writes beside the figure
(:mod:`madpinn.value_functions.heatmap_reading`, ``paper_figures/fig_value_heatmap.json``)."""

from __future__ import annotations

from typing import Mapping

from madpinn.evaluation.claim_checks import Check

LOW_PERCENTILE = 10.0
""""low": the goal cell among the lowest this-many percent of the feasible cells"""


def heatmap_checks(reading: Mapping | None) -> list[Check]:
    """Per other agent: most cells within r of it high (infeasible or above the median); the goal cell
    low (lowest decile); the lowest cell within r of the goal."""
    if not reading:
        return []
    r = reading["radius"]
    out = [Check(f"high value at the other agent at {tuple(a['position'])}: most cells within r = {r:g} m infeasible "
                 "or above the arena's median", f"{100 * a['high_share']:.0f} % high ({100 * a['infeasible_share']:.0f} % "
                 f"infeasible) of {a['cells']} cells", (), a["high_share"] > 0.5, "red over the agents", "high value",
                 margin=a["high_share"] - 0.5) for a in reading["agents"]]
    p = reading["goal_percentile"]
    out.append(Check(f"low value around the goal: the goal cell among the lowest {LOW_PERCENTILE:g} % of feasible cells",
                     "goal cell infeasible" if p is None else f"goal cell at the {p:.1f}th percentile", (),
                     p is not None and p <= LOW_PERCENTILE, "blue around the goal", "low value",
                     margin=None if p is None else (LOW_PERCENTILE - p) / 100))
    d = reading["lowest_to_goal"]
    out.append(Check(f"the lowest value within r = {r:g} m of the goal",
                     "no feasible cell" if d is None else f"lowest cell at {d:.3f} m from the goal", (),
                     d is not None and d <= r, "blue around the goal", "low value",
                     margin=None if d is None else (r - d) / r))
    return out
