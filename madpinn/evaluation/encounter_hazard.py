"""Collision hazard per encounter (issue 60 item 1): does the large arena at Table I's load behave
like Table I?

- :func:`cell_hazard`: a cell's failures per straight-line encounter, ``h = (1 − safety) /
  encounters per agent`` — the ratio of the cell's means over its scenarios
  (``safety_rate``, ``encounters_per_agent``: :mod:`madpinn.encounters`), with a percentile
  bootstrap interval over scenarios (the same resampled scenarios in numerator and denominator).
  The pre-registered rule that reads it: ``docs/findings/2026-11-28-table-ii-readings-preregistered.md``.
- :func:`hazard_by_speed`: the agents of one or more cells binned by the speed of their hardest
  encounter (``agent_encounter_speed``: relative speed at the first collision, else at the closest
  approach, m/s), each bin's share of collided agents (minimum separation ≤ r) with a Wilson interval.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

from madpinn.evaluation.metrics import CI_LEVEL, CI_RESAMPLES


def cell_hazard(frame: pd.DataFrame, level: float = CI_LEVEL, resamples: int = CI_RESAMPLES, seed: int = 0) -> dict:
    """``{hazard, low, high, encounters_per_agent, safety_rate, scenarios}`` of one cell's scenario rows."""
    if "encounters_per_agent" not in frame:
        raise ValueError("these results hold no encounters_per_agent (written before issue 60)")
    fail = 1.0 - frame["safety_rate"].to_numpy(dtype=float)
    load = frame["encounters_per_agent"].to_numpy(dtype=float)
    S = len(frame)
    out = {"encounters_per_agent": float(load.mean()), "safety_rate": float(1.0 - fail.mean()), "scenarios": S}
    out["hazard"] = float(fail.mean() / load.mean()) if load.mean() > 0 else float("nan")
    idx = np.random.default_rng(seed).integers(0, S, size=(resamples, S))
    num, den = fail[idx].mean(1), load[idx].mean(1)
    ratios = num[den > 0] / den[den > 0]
    q = (1.0 - level) / 2.0
    out["low"], out["high"] = ((float(np.quantile(ratios, q)), float(np.quantile(ratios, 1.0 - q)))
                               if ratios.size else (float("nan"), float("nan")))
    return out


def wilson(k: int, n: int, level: float = CI_LEVEL) -> tuple[float, float]:
    """Wilson score interval of a binomial share ``k / n``."""
    if n == 0:
        return float("nan"), float("nan")
    from scipy.stats import norm

    z = float(norm.ppf(0.5 + level / 2.0))
    p = k / n
    centre = (p + z * z / (2 * n)) / (1 + z * z / n)
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / (1 + z * z / n)
    return max(0.0, centre - half), min(1.0, centre + half)


def hazard_by_speed(frame: pd.DataFrame, edges, collision_radius: float, level: float = CI_LEVEL) -> pd.DataFrame:
    """One row per speed bin ``[edges[i], edges[i+1])`` (m/s; the last bin open above): agents,
    collided agents, their share and its Wilson interval. Agents with no encounter speed (NaN: they
    never approached anyone) are left out."""
    if "agent_encounter_speed" not in frame:
        raise ValueError("these results hold no agent_encounter_speed (written before issue 60)")
    speed = np.concatenate([np.asarray(v, dtype=float) for v in frame["agent_encounter_speed"]])
    collided = np.concatenate([np.asarray(v, dtype=float) for v in frame["agent_min_separation"]]) <= collision_radius
    keep = np.isfinite(speed)
    speed, collided = speed[keep], collided[keep]
    edges = [float(e) for e in edges]
    rows = []
    for i, lo in enumerate(edges):
        hi = edges[i + 1] if i + 1 < len(edges) else math.inf
        m = (speed >= lo) & (speed < hi)
        n, k = int(m.sum()), int(collided[m].sum())
        low, high = wilson(k, n, level)
        rows.append({"speed_low": lo, "speed_high": hi, "agents": n, "collided": k,
                     "hazard": k / n if n else float("nan"), "low": low, "high": high})
    return pd.DataFrame(rows)
