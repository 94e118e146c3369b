"""Oracle cost lower bound (SPEC §3): the smallest cost a lone agent can reach.

Problem of one agent (no other agents), offset ``x = p − g`` (m), from rest ``x(0) = x0, v(0) = 0``:

    min  ∫₀^T ‖x(t)‖ dt + ‖x(T)‖    s.t.  ẍ = u,  |u_i| ≤ u_max,  |v_i| ≤ v_max  (per axis)

Solved as two second-order cone programmes on a grid ``t_k = k·h`` (K = T/h intervals) that
sandwich the continuous optimum J*:

* **lower bound** (:func:`lower_bound`) — a relaxation. Whatever the control on an interval,
  the samples satisfy ``|v_{k+1} − v_k| ≤ u_max·h``, ``|x_{k+1} − x_k − h(v_k + v_{k+1})/2| ≤
  u_max·h²/4``, ``|x_{k+1} − x_k| ≤ v_max·h``, ``|v_k| ≤ v_max`` and the interval mean
  ``m_k = (1/h)∫x dt`` satisfies ``|m_k − (x_k + x_{k+1})/2| ≤ u_max·h²/12`` (per axis; the
  trapezoid-rule error ∫ s(h−s)/2·u ds). By Jensen, ``∫_{interval}‖x‖ ≥ h‖m_k‖``. Minimising
  ``Σ h‖m_k‖ + ‖x_K‖`` over this superset of reachable samples gives LB ≤ J*.
* **upper bound** (:func:`upper_bound`) — a feasible trajectory: piecewise-constant control
  (exact double-integrator steps; velocity is linear between samples so the box holds
  throughout), with the interval cost bounded by convexity (chord ≤ trapezoid) plus the
  quadratic's bow ``‖s(h−s)/2·u_k‖``, integrated ``h³/12·‖u_k‖``. J* ≤ UB.

The bound works on offsets of any number of axes d (the offsets' last size). A 3-D model's
scenarios are the planar ones at one altitude (:meth:`~madpinn.dynamics.AgentModel.place`), so
their offsets have no vertical part and a lone agent's optimum stays level: the planar bound is
theirs too. The scenario's bound is the mean of LB over its agents. UB − LB bounds the discretisation gap
(docs/reference/evaluation.md reports it at two resolutions). Agents of a batch are independent blocks of
one programme (cvxpy with CLARABEL), compiled once per (batch, K) and reused with parameters.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path
from typing import Mapping

import numpy as np
import pandas as pd
import torch

from madpinn.dynamics.double_integrator import hold_step
from madpinn.scenarios import UNIFORM, Arena, generate_scenario

BATCH = 64   # agents per programme (padded with zero offsets, whose cost is exactly 0)


@dataclass(frozen=True)
class OracleSettings:
    """Limits (per axis) and grid of the oracle programmes."""

    horizon_s: float   # T (s)
    u_max: float       # m/s² (``agents.u_max``)
    v_max: float       # m/s (``agents.v_max``)
    dt: float          # h (s), grid of the programmes: T / ``oracle.steps``

    def __post_init__(self):
        if self.horizon_s <= 0 or self.dt <= 0 or self.u_max <= 0 or self.v_max <= 0:
            raise ValueError(f"oracle settings must be positive: {self}")
        k = self.horizon_s / self.dt
        if abs(k - round(k)) > 1e-6:
            raise ValueError(f"oracle dt {self.dt} s must divide the horizon {self.horizon_s} s")

    @property
    def steps(self) -> int:
        return int(round(self.horizon_s / self.dt))

    @classmethod
    def from_config(cls, cfg: Mapping, arena: str) -> "OracleSettings":
        """The bound of one episode of ``arenas.<arena>``: T its length, h = T / ``oracle.steps``."""
        episode_s = float(cfg["arenas"][arena]["episode_s"])
        return cls(horizon_s=episode_s, u_max=float(cfg["agents"]["u_max"]), v_max=float(cfg["agents"]["v_max"]),
                   dt=episode_s / int(cfg["oracle"]["steps"]))


@lru_cache(maxsize=8)
def _programme(kind: str, steps: int, h: float, u_max: float, v_max: float, batch: int, d: int):
    import cvxpy as cp

    x0 = cp.Parameter((batch, d), name="x0")
    v0 = cp.Parameter((batch, d), name="v0")
    X = [cp.Variable((batch, steps + 1)) for _ in range(d)]   # per axis: offsets at t_k (m)
    V = [cp.Variable((batch, steps + 1)) for _ in range(d)]   # velocities (m/s)
    cons = []
    for a in range(d):
        x, v = X[a], V[a]
        cons += [x[:, 0] == x0[:, a], v[:, 0] == v0[:, a], cp.abs(v) <= v_max]
        dx, dv = x[:, 1:] - x[:, :-1], v[:, 1:] - v[:, :-1]
        if kind == "lower":
            cons += [cp.abs(dv) <= u_max * h,
                     cp.abs(dx - h * (v[:, :-1] + v[:, 1:]) / 2) <= u_max * h**2 / 4,
                     cp.abs(dx) <= v_max * h]
        else:
            cons += [cp.abs(dv) <= u_max * h, dx == h * (v[:, :-1] + v[:, 1:]) / 2]   # ZOH: x += h v + h²u/2
    M = [cp.Variable((batch, steps)) for _ in range(d)] if kind == "lower" else None   # interval means (m)
    if kind == "lower":
        for a in range(d):
            cons.append(cp.abs(M[a] - (X[a][:, :-1] + X[a][:, 1:]) / 2) <= u_max * h**2 / 12)
        run = cp.norm(cp.vstack([cp.vec(m, order="C") for m in M]), 2, axis=0)
        cost = h * cp.sum(run)
    else:
        node = cp.norm(cp.vstack([cp.vec(x, order="C") for x in X]), 2, axis=0)
        w = np.ones(steps + 1)
        w[[0, -1]] = 0.5                                            # trapezoid weights per block
        dv = [cp.vec(v[:, 1:] - v[:, :-1], order="C") for v in V]
        bow = h**2 / 12 * cp.sum(cp.norm(cp.vstack(dv), 2, axis=0))   # Σ h³/12·‖u_k‖, u_k = Δv_k / h
        cost = h * (np.tile(w, batch) @ node) + bow
    final = cp.norm(cp.vstack([x[:, steps] for x in X]), 2, axis=0)
    cost = cost + cp.sum(final)
    return cp.Problem(cp.Minimize(cost), cons), x0, v0, X, V, M


def _norm(axes: list[np.ndarray]) -> np.ndarray:
    """Euclidean norm over per-axis arrays (``np.hypot`` folded over the axes)."""
    return np.hypot.reduce(np.stack(axes), axis=0)


def _solve(kind: str, offsets: np.ndarray, s: OracleSettings, velocities: np.ndarray | None = None):
    """Programme ``kind`` for ``offsets`` ``[A, 2]`` = start − goal (m) and initial ``velocities``
    ``[A, 2]`` (m/s, default rest). Returns each agent's optimum ``[A]`` and first control ``[A, 2]``."""
    offsets = np.asarray(offsets, dtype=float)
    offsets = offsets.reshape(-1, offsets.shape[-1])
    vel = np.zeros_like(offsets) if velocities is None else np.asarray(velocities, dtype=float).reshape(-1, offsets.shape[-1])
    if not (np.isfinite(offsets).all() and np.isfinite(vel).all()) or vel.shape != offsets.shape:
        raise ValueError("oracle offsets and velocities must be finite arrays of the same shape [A, 2]")
    if (np.abs(vel) > s.v_max + 1e-9).any():
        raise ValueError(f"initial velocities exceed v_max = {s.v_max}")
    h, out, first_u = s.dt, np.empty(len(offsets)), np.empty_like(offsets)
    batch = min(BATCH, len(offsets))
    prob, x0, v0, X, V, M = _programme(kind, s.steps, h, s.u_max, s.v_max, batch, offsets.shape[-1])
    for first in range(0, len(offsets), batch):
        n = len(offsets[first:first + batch])
        pad = np.zeros((batch - n, offsets.shape[1]))
        x0.value = np.vstack([offsets[first:first + batch], pad])
        v0.value = np.clip(np.vstack([vel[first:first + batch], pad]), -s.v_max, s.v_max)
        prob.solve(solver="CLARABEL")
        if prob.status != "optimal":
            raise RuntimeError(f"oracle {kind} programme ended '{prob.status}'")
        # the programme is block-separable, so each agent's block is optimal alone: its own cost
        node = _norm([x.value for x in X])                            # [B, K+1] ‖x_k‖
        if kind == "lower":
            per = h * _norm([m.value for m in M]).sum(axis=1)
        else:
            dv = _norm([np.diff(v.value, axis=1) for v in V])
            per = h * (node[:, :-1] + node[:, 1:]).sum(axis=1) / 2 + h**2 / 12 * dv.sum(axis=1)
        out[first:first + n] = (per + node[:, -1])[:n]
        first_u[first:first + n] = np.stack([V[a].value[:n, 1] - V[a].value[:n, 0] for a in range(len(V))], axis=-1) / h
    return out, np.clip(first_u, -s.u_max, s.u_max)


def lower_bound(offsets: np.ndarray, settings: OracleSettings) -> np.ndarray:
    """Per-agent lower bound ``[A]`` (m·s + m) of the lone-agent cost, ``offsets`` ``[A, 2]`` = start − goal.

    Solver tolerance (CLARABEL, ~1e-8 relative) is removed by subtracting ``1e-6·(1 + LB)``."""
    lb = _solve("lower", offsets, settings)[0]
    return np.maximum(lb - 1e-6 * (1.0 + lb), 0.0)


def upper_bound(offsets: np.ndarray, settings: OracleSettings) -> np.ndarray:
    """Per-agent cost ``[A]`` of a feasible piecewise-constant control (an upper bound of the optimum)."""
    return _solve("upper", offsets, settings)[0]


def scenario_bounds(arena: Arena, n_agents: int, seed: int, count: int, min_separation: float,
                    settings: OracleSettings, with_upper: bool = False, pattern: str = UNIFORM) -> pd.DataFrame:
    """One row per scenario ``0 … count−1`` of ``pattern`` (uniform or a structured conflict):
    ``oracle_cost`` (mean LB over agents), its time average ``oracle_cost_time_avg`` (÷ T) and,
    with ``with_upper``, ``oracle_upper``."""
    if abs(settings.horizon_s - arena.episode_s) > 1e-9:
        raise ValueError(f"oracle horizon {settings.horizon_s} s differs from the {arena.name} episode {arena.episode_s} s")
    offsets = np.stack([np.subtract(*generate_scenario(arena, n_agents, seed, i, min_separation, pattern))
                        for i in range(count)])
    lb = lower_bound(offsets.reshape(-1, offsets.shape[-1]), settings).reshape(count, n_agents).mean(axis=1)
    df = pd.DataFrame({"arena": arena.name, "pattern": pattern, "n_agents": int(n_agents), "seed": int(seed),
                       "scenario": np.arange(count), "oracle_cost": lb, "oracle_cost_time_avg": lb / arena.episode_s})
    if with_upper:
        df["oracle_upper"] = upper_bound(offsets.reshape(-1, offsets.shape[-1]), settings).reshape(count, n_agents).mean(axis=1)
    return df


def write_bounds(out: str | Path, arena: Arena, n_agents: int, seed: int, count: int, min_separation: float,
                 settings: OracleSettings, pattern: str = UNIFORM) -> Path:
    """Cache file of :func:`scenario_bounds` (Parquet); scenarios are pure functions of their index,
    so a study with fewer scenarios reads the first rows."""
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    df = scenario_bounds(arena, n_agents, seed, count, min_separation, settings, pattern=pattern)
    df["oracle_dt"] = settings.dt
    df.to_parquet(out, index=False)
    return out


def receding_horizon_cost(offsets: np.ndarray, episode_s: float, horizon_s: float = 0.2, dt: float = 0.025,
                          u_max: float = 4.0, v_max: float = 4.0, substeps: int = 10) -> np.ndarray:
    """Closed-loop cost ``[A]`` of a lone agent that re-solves the ``horizon_s`` problem
    (min ∫₀^H‖x‖dt + ‖x(H)‖, exact piecewise-constant programme) every ``dt`` and applies its first
    control (exact double-integrator step; cost by the trapezoid rule on ``substeps`` per step).
    What a receding horizon as short as V̂'s (0.2 s) costs without any other agent."""
    x = np.asarray(offsets, dtype=float)
    x = x.reshape(-1, x.shape[-1]).copy()
    v = np.zeros_like(x)
    s = OracleSettings(horizon_s=horizon_s, u_max=u_max, v_max=v_max, dt=dt)
    steps = int(round(episode_s / dt))
    if abs(steps * dt - episode_s) > 1e-9:
        raise ValueError(f"dt {dt} s must divide the episode {episode_s} s")
    tau = np.linspace(0.0, dt, substeps + 1)[:, None, None]
    cost = np.zeros(len(x))
    for _ in range(steps):
        u = _solve("upper", x, s, v)[1]
        path, vel = (a.numpy() for a in hold_step(*(torch.from_numpy(a) for a in (x[None], v[None], u[None], tau))))
        d = np.linalg.norm(path, axis=-1)                           # path [substeps+1, A, d]
        cost += (dt / substeps) * (d[:-1] + d[1:]).sum(axis=0) / 2
        x, v = path[-1], np.clip(vel[-1], -v_max, v_max)            # tau[-1] = dt
    return cost + np.linalg.norm(x, axis=-1)
