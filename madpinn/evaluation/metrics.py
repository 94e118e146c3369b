"""Metrics of SPEC §3.

Per scenario: safety rate (fraction of agents that never collide), whether the scenario is safe
(no agent collides), mean cumulative cost over collision-free agents (the paper's definition)
and over all agents (SPEC §3 caveat), each also divided by the episode length T (the
time-averaged cost, the quantity the paper's cost figures match). Per seed: mean over scenarios
(safe scenarios = fraction of safe scenarios). Tables: mean ± std across seeds.

Collision conventions (SPEC §1): the protocol counts a collision at centre distance d ≤ r; the
same episode also gives safety under the disc reading (discs of radius r touch at d ≤ 2r,
``*_2r`` columns) and at any other radius: each scenario row keeps every agent's minimum
separation over the episode (``agent_min_separation``) and cost (``agent_cost``), and
:func:`safety_curve` reads safety at any radius from them.

Result files written before the time-averaged columns existed still load: their missing figures
are NaN.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
import pandas as pd

from madpinn.separation import safe_at

if TYPE_CHECKING:   # annotations only: tables and figures run without importing torch
    from madpinn.simulation.recorder import EpisodeResult

SEED_METRICS = ("safety_rate", "safe_scenarios", "cost", "cost_time_avg", "cost_all", "cost_all_time_avg",
                "safety_rate_2r", "safe_scenarios_2r")
DISC_FACTOR = 2.0   # discs of radius r touch at centre distance 2r (the ``*_2r`` columns)
# seed figure -> per-scenario column it averages (safety at 2r: plain mean over scenarios)
RATE_COLUMNS = {"safety_rate_2r": "safety_rate_2r", "safe_scenarios_2r": "safe_2r"}
# seed figure -> per-scenario column it averages (costs: NaN-aware mean over scenarios)
COST_COLUMNS = {"cost": "cost_safe_mean", "cost_time_avg": "cost_safe_time_avg",
                "cost_all": "cost_all_mean", "cost_all_time_avg": "cost_all_time_avg"}


def horizon_suffix(horizon_s: float) -> str:
    """Column suffix of the figures read at an earlier horizon (``_at_6s`` for 6 s)."""
    return f"_at_{horizon_s:g}s"


def _safety_and_cost(collided: np.ndarray, cost: np.ndarray, horizon_s: float, suffix: str = "") -> dict:
    """Per-scenario safety and costs ``[S]`` of agents ``collided [S, N]`` with costs ``[S, N]`` over ``horizon_s``."""
    safe_agents = ~collided
    n_safe = safe_agents.sum(axis=1)
    cost_safe = np.where(safe_agents, cost, 0.0).sum(axis=1) / np.maximum(n_safe, 1)
    cost_safe = np.where(n_safe > 0, cost_safe, np.nan)
    return {f"safety_rate{suffix}": n_safe / collided.shape[1], f"safe{suffix}": ~collided.any(axis=1),
            f"cost_safe_mean{suffix}": cost_safe, f"cost_all_mean{suffix}": cost.mean(axis=1),
            f"cost_safe_time_avg{suffix}": cost_safe / horizon_s, f"cost_all_time_avg{suffix}": cost.mean(axis=1) / horizon_s}


def scenario_metrics(result: EpisodeResult, first_index: int = 0) -> pd.DataFrame:
    """One row per scenario of a batched episode; with ``result.cost_at``, the same safety and cost
    figures at each earlier horizon H (columns suffixed :func:`horizon_suffix`), from the same episode:
    an agent counts as collided at H when its first collision came at or before H."""
    collided = result.collided
    S, N = collided.shape
    episode_s = result.n_steps * result.dt   # T (s)
    end = _safety_and_cost(collided, result.cost, episode_s)
    safe_2r = result.safe_at(DISC_FACTOR * result.collision_radius)
    at_horizons = {}
    first = result.first_collision_step
    for k, cost in sorted(result.cost_at.items()):
        at_horizons.update(_safety_and_cost((first >= 0) & (first <= k), cost, k * result.dt, horizon_suffix(k * result.dt)))
    speed = result.encounter_speed if result.encounter_speed is not None else np.full((S, N), np.nan)
    with np.errstate(invalid="ignore"):
        speed_mean = np.array([np.nanmean(row) if np.isfinite(row).any() else np.nan for row in speed])
    return pd.DataFrame(
        {
            "scenario": np.arange(first_index, first_index + S),
            "n_agents": N,
            "n_collided": collided.sum(axis=1).astype(int),
            "safety_rate": end["safety_rate"],
            "safe": end["safe"],
            "cost_safe_mean": end["cost_safe_mean"],
            "cost_all_mean": end["cost_all_mean"],
            "episode_s": episode_s,
            "cost_safe_time_avg": end["cost_safe_time_avg"],
            "cost_all_time_avg": end["cost_all_time_avg"],
            "final_distance_mean": result.final_distance.mean(axis=1),
            "min_separation": result.min_separation.min(axis=1),
            "safety_rate_2r": safe_2r.sum(axis=1) / N,
            "safe_2r": safe_2r.all(axis=1),
            "agent_min_separation": list(result.min_separation),
            "agent_cost": list(result.cost),
            "encounter_speed_mean": speed_mean,
            "agent_encounter_speed": list(speed),
            **at_horizons,
        }
    )


def safety_curve(df: pd.DataFrame, radii) -> pd.DataFrame:
    """Safety rate and safe-scenario share at each radius ``radii`` (m) from the scenario rows'
    ``agent_min_separation``: one row per radius, means over the rows of ``df``."""
    if "agent_min_separation" not in df:
        raise ValueError("these results hold no per-agent minimum separations (written before they were recorded)")
    rows = []
    for rho in radii:
        safe = [safe_at(np.asarray(sep), rho) for sep in df["agent_min_separation"]]
        rows.append({"radius": float(rho), "safety_rate": float(np.mean([s.mean() for s in safe])),
                     "safe_scenarios": float(np.mean([s.all() for s in safe]))})
    return pd.DataFrame(rows)


def seed_summary(df: pd.DataFrame) -> dict:
    """Aggregate one seed's scenario rows into the reported figures."""
    out = {"safety_rate": float(df["safety_rate"].mean()), "safe_scenarios": float(df["safe"].mean())}
    for name, col in RATE_COLUMNS.items():   # results written before they existed: NaN
        out[name] = float(df[col].astype(float).mean()) if col in df else float("nan")
    for name, col in COST_COLUMNS.items():
        out[name] = _finite_mean(df[col] if col in df else np.full(len(df), np.nan))
    for col in df.columns:   # figures at earlier horizons (scenario_metrics): safety, safe scenarios, costs
        base, _, horizon = col.partition("_at_")
        if horizon.endswith("s") and base in _HORIZON_FIGURES:
            out[_HORIZON_FIGURES[base] + "_at_" + horizon] = _finite_mean(df[col])
    if "encounter_speed_mean" in df:
        out["encounter_speed_mean"] = _finite_mean(df["encounter_speed_mean"])
    out["n_scenarios"] = int(len(df))
    return out


def _finite_mean(values) -> float:
    """Mean of the finite entries of ``values``; NaN when there are none."""
    vals = np.asarray(values, dtype=float)
    return float(np.nanmean(vals)) if np.isfinite(vals).any() else float("nan")


_HORIZON_FIGURES = {"safety_rate": "safety_rate", "safe": "safe_scenarios", **{v: k for k, v in COST_COLUMNS.items()}}
"""per-scenario column (before its ``_at_<H>s`` suffix) -> the seed figure it gives at that horizon"""


CI_METRICS = ("safety_rate", "safe_scenarios", "cost_time_avg", "safety_rate_2r")
"""seed figures that single-seed tables show with a bootstrap interval over scenarios"""
CI_LEVEL = 0.95
CI_RESAMPLES = 2000


def bootstrap_interval(values: np.ndarray, level: float = CI_LEVEL, resamples: int = CI_RESAMPLES,
                       seed: int = 0) -> tuple[float, float]:
    """Percentile bootstrap interval of the (NaN-aware) mean of ``values [S]`` over resampled
    scenarios (``resamples`` draws of S with replacement, a fixed generator: the same rows give the
    same interval). NaN entries (e.g. the cost of a scenario where every agent collided) stay in the
    resample and drop out of its mean; resamples with no finite value are skipped."""
    v = np.asarray(values, dtype=float)
    if v.size == 0 or not np.isfinite(v).any():
        return float("nan"), float("nan")
    idx = np.random.default_rng(seed).integers(0, v.size, size=(resamples, v.size))
    draws = v[idx]
    finite = np.isfinite(draws)
    counts = finite.sum(1)
    means = np.where(finite, draws, 0.0).sum(1)[counts > 0] / counts[counts > 0]
    a = (1.0 - level) / 2.0
    return float(np.quantile(means, a)), float(np.quantile(means, 1.0 - a))


def scenario_intervals(df: pd.DataFrame) -> dict:
    """``{metric}_ci_lo`` / ``{metric}_ci_hi`` for :data:`CI_METRICS` over one seed's scenario rows
    (:func:`bootstrap_interval`); figures whose columns the rows lack are NaN."""
    cols = {"safety_rate": "safety_rate", "safe_scenarios": "safe", "safety_rate_2r": "safety_rate_2r",
            "cost_time_avg": COST_COLUMNS["cost_time_avg"]}
    out = {}
    for m in CI_METRICS:
        lo, hi = bootstrap_interval(df[cols[m]].to_numpy(dtype=float)) if cols[m] in df else (float("nan"),) * 2
        out[f"{m}_ci_lo"], out[f"{m}_ci_hi"] = lo, hi
    return out


def across_seeds(per_seed: pd.DataFrame, keys: list[str]) -> pd.DataFrame:
    """Mean and std (ddof=1 with ≥ 2 seeds, else 0) of the seed figures, grouped by ``keys``; a
    group of one seed also keeps that seed's bootstrap intervals (:func:`scenario_intervals`)."""
    rows = []
    for group, g in per_seed.groupby(keys, sort=False):
        group = group if isinstance(group, tuple) else (group,)
        row = dict(zip(keys, group))
        row["n_seeds"] = int(len(g))
        for m in SEED_METRICS:
            vals = g[m].to_numpy(dtype=float) if m in g else np.full(len(g), np.nan)   # older result files
            row[f"{m}_mean"] = float(np.nanmean(vals)) if np.isfinite(vals).any() else float("nan")
            row[f"{m}_std"] = float(np.nanstd(vals, ddof=1)) if np.isfinite(vals).sum() > 1 else 0.0
        for m in CI_METRICS:
            for end in ("lo", "hi"):
                col = f"{m}_ci_{end}"
                row[col] = float(g[col].iloc[0]) if len(g) == 1 and col in g else float("nan")
        rows.append(row)
    return pd.DataFrame(rows)
