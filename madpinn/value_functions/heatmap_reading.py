"""What the V̂ heatmap shows, in numbers (issue 61): the paper reads its Fig. "value function" as high
value where the other agents are and low value around the goal (Setup, tex 406). From the heatmap's
grid of V_d = z* over the ego position (infeasible cells: above every feasible value):

- per other agent, the share of cells within ``radius`` of it that are infeasible or above the
  median of the arena's feasible cells ("high");
- the percentile of the goal cell among the feasible cells, and the distance from the goal to the
  lowest cell ("low around the goal").
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from madpinn.value_functions.validation import HEATMAP


def heatmap_reading(axis, z_star, feasible, radius: float) -> dict:
    """The numbers above from the heatmap's ``axis`` [P] (m), ``z_star`` and ``feasible`` [P, P] (rows: y)."""
    ax = np.asarray(axis, dtype=float)
    z, ok = np.asarray(z_star, dtype=float), np.asarray(feasible, dtype=bool)
    xx, yy = np.meshgrid(ax, ax)
    median = float(np.median(z[ok])) if ok.any() else None   # None: no feasible cell (an untrained V̂)
    agents = []
    for x, y in HEATMAP["neighbours"]:
        near = np.hypot(xx - x, yy - y) <= radius
        high = (~ok | (z > median) if median is not None else ~ok) & near
        agents.append({"position": [x, y], "cells": int(near.sum()), "high_share": float(high.sum() / max(near.sum(), 1)),
                       "infeasible_share": float((~ok & near).sum() / max(near.sum(), 1))})
    gx, gy = HEATMAP["ego_goal"]
    goal = np.unravel_index(np.argmin(np.hypot(xx - gx, yy - gy)), z.shape)
    low = np.unravel_index(np.argmin(np.where(ok, z, np.inf)), z.shape) if ok.any() else None
    return {"radius": radius, "median": median, "agents": agents, "goal": [gx, gy],
            "goal_percentile": float(100 * (z[ok] < z[goal]).mean()) if ok[goal] else None,
            "lowest_at": None if low is None else [float(xx[low]), float(yy[low])],
            "lowest_to_goal": None if low is None else float(np.hypot(xx[low] - gx, yy[low] - gy)),
            "grid_step": float(ax[1] - ax[0])}


def write_reading(axis, z_star, feasible, radius: float, out: str | Path) -> list[Path]:
    out = Path(out)
    out.write_text(json.dumps(heatmap_reading(axis, z_star, feasible, radius), indent=2))
    return [out]
