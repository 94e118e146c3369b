"""Independent grid solution of the pairwise safety value V_s (issue 15) with ``hj_reachability``.

Same problem as the PINN V_s (:mod:`madpinn.dynamics.pair`): relative state
``x = [p, v]`` ``[4]`` (m, m/s), ``ṗ = v``, ``v̇ = u``, ``u ∈ [−2u_max, 2u_max]²`` *maximising*
(the pair cooperates), target ``ψ = ‖p‖ − r``, horizon T. ``V(x, t) = sup_u min_{τ∈[t,T]} ψ``
solves ``min{∂_t V + H, ψ − V} = 0``, ``V(T) = ψ``. hj_reachability integrates
``∂_t V + max_u⟨∇V, f⟩ = 0`` backward from ``V(·, 0) = ψ`` (its time ``s = t − T ≤ 0``) and the
value postprocessor ``V ← min(V, ψ)`` after every Runge–Kutta stage gives the min-with-ψ of the
variational inequality. The grid covers ``|p| ≤ p_range``, ``|v| ≤ v_range`` per axis with an odd
number of nodes per axis (0 is a node); comparisons use only nodes of an *interior* box, where
the extrapolating boundary condition does not reach within the horizon (documented in
``docs/reference/value_functions.md`` with the two-resolution convergence check).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from madpinn.dynamics import PAPER_MODEL
from madpinn.dynamics.pair import PairSystem


@dataclass(frozen=True)
class GridSettings:
    """nodes: grid nodes per axis (odd; the coarse solution of the convergence check uses
    ``(nodes + 1) // 2``, nested in the fine grid); p_range / v_range: grid half-widths (m, m/s);
    interior_p / interior_v: half-widths of the box the metrics use (m, m/s); times: the
    times t (s) of the comparison; accuracy: hj_reachability scheme (``very_high`` = WENO5 + TVD-RK3)."""

    nodes: int
    p_range: float
    v_range: float
    interior_p: float
    interior_v: float
    times: tuple
    accuracy: str

    def __post_init__(self):
        if self.nodes < 5 or self.nodes % 2 == 0:
            raise ValueError(f"grid nodes per axis must be odd and ≥ 5 (0 a node, nested coarse grid), got {self.nodes}")
        if not (0 < self.interior_p <= self.p_range and 0 < self.interior_v <= self.v_range):
            raise ValueError("the interior box must lie inside the grid (0 < interior_p ≤ p_range, 0 < interior_v ≤ v_range)")

    @classmethod
    def from_config(cls, d: dict) -> "GridSettings":
        d = dict(d)
        if "times" in d:
            d["times"] = tuple(float(t) for t in d["times"])
        return cls(**d)


@dataclass
class GridSolution:
    """``values [len(times), n, n, n, n]`` (m) on the axes ``p_axis``, ``v_axis`` at ``times`` (s)."""

    p_axis: np.ndarray
    v_axis: np.ndarray
    times: tuple
    values: np.ndarray
    wall_s: float = 0.0
    meta: dict = field(default_factory=dict)

    def states(self) -> np.ndarray:
        """All nodes ``[n, n, n, n, 4]``."""
        g = np.meshgrid(self.p_axis, self.p_axis, self.v_axis, self.v_axis, indexing="ij")
        return np.stack(g, -1)

    def interior_mask(self, interior_p: float, interior_v: float) -> np.ndarray:
        """Boolean ``[n, n, n, n]``: nodes with ``|p| ≤ interior_p``, ``|v| ≤ interior_v`` per axis."""
        eps = 1e-9
        mp = np.abs(self.p_axis) <= interior_p + eps
        mv = np.abs(self.v_axis) <= interior_v + eps
        return mp[:, None, None, None] & mp[None, :, None, None] & mv[None, None, :, None] & mv[None, None, None, :]


def _pair_dynamics(u_rel_max: float):
    import jax.numpy as jnp
    import hj_reachability as hj

    class PairDynamics(hj.ControlAndDisturbanceAffineDynamics):
        """``ṗ = v``, ``v̇ = u``, ``u ∈ [−u_rel_max, u_rel_max]²`` maximising, no disturbance."""

        def __init__(self):
            lim = jnp.full(2, u_rel_max)
            super().__init__("max", "min", hj.sets.Box(-lim, lim), hj.sets.Box(jnp.zeros(1), jnp.zeros(1)))

        def open_loop_dynamics(self, state, time):
            return jnp.array([state[2], state[3], 0.0, 0.0])

        def control_jacobian(self, state, time):
            return jnp.array([[0.0, 0.0], [0.0, 0.0], [1.0, 0.0], [0.0, 1.0]])

        def disturbance_jacobian(self, state, time):
            return jnp.zeros((4, 1))

    return PairDynamics()


def solve_pair_grid(system: PairSystem, nodes: int, p_range: float, v_range: float, times, accuracy: str = "very_high",
                    progress: bool = False) -> GridSolution:
    """Solve V on a ``nodes⁴`` grid and return it at the requested ``times`` (s, each in [0, T))."""
    import jax
    import jax.numpy as jnp
    import hj_reachability as hj

    if system.model != PAPER_MODEL:
        raise ValueError(f"the grid reference solves the planar pair ({PAPER_MODEL}, a 4-D grid); the pair of "
                         f"{system.model} is beyond it: check its V_s on rollouts (validate-vs) instead")
    agent = system.agent
    times = tuple(sorted({float(t) for t in times}, reverse=True))
    if any(not 0.0 <= t < system.horizon for t in times):
        raise ValueError(f"grid times must lie in [0, T = {system.horizon}), got {times}")
    lo = np.array([-p_range] * agent.position_dim + [-v_range] * agent.position_dim)
    grid = hj.Grid.from_lattice_parameters_and_boundary_conditions(hj.sets.Box(jnp.array(lo), jnp.array(-lo)),
                                                                   (nodes,) * agent.state_dim)
    psi = jnp.linalg.norm(grid.states[..., agent.position_slice()], axis=-1) - system.collision_radius
    settings = hj.SolverSettings.with_accuracy(accuracy, value_postprocessor=lambda t, v: jnp.minimum(v, psi))
    hj_times = jnp.array([0.0] + [t - system.horizon for t in times])      # backward: s = t − T
    t0 = time.perf_counter()
    values = hj.solve(settings, _pair_dynamics(system.u_rel_max), grid, hj_times, psi, progress_bar=progress)
    values = np.asarray(jax.block_until_ready(values), dtype=np.float64)[1:]
    wall = time.perf_counter() - t0
    order = np.argsort(times)                                             # ascending t
    return GridSolution(p_axis=np.asarray(grid.coordinate_vectors[0], dtype=np.float64),
                        v_axis=np.asarray(grid.coordinate_vectors[2], dtype=np.float64),
                        times=tuple(times[i] for i in order), values=values[order], wall_s=wall,
                        meta={"nodes": nodes, "p_range": p_range, "v_range": v_range, "accuracy": accuracy})


def compare_values(reference: np.ndarray, predicted: np.ndarray) -> dict:
    """Metrics of ``predicted`` against ``reference`` (same shape, m): MAE, max error, sign
    agreement, share of truly unsafe states (reference ≤ 0) called safe (predicted > 0) and of
    truly safe states called unsafe."""
    ref, pred = np.asarray(reference, float).ravel(), np.asarray(predicted, float).ravel()
    err = np.abs(pred - ref)
    unsafe, safe = ref <= 0.0, ref > 0.0
    return {
        "mae": float(err.mean()), "max_error": float(err.max()), "p99_error": float(np.quantile(err, 0.99)),
        "sign_agreement": float(np.mean((pred > 0.0) == (ref > 0.0))),
        "unsafe_called_safe": float(np.mean(pred[unsafe] > 0.0)) if unsafe.any() else 0.0,
        "safe_called_unsafe": float(np.mean(pred[safe] <= 0.0)) if safe.any() else 0.0,
        "unsafe_share": float(unsafe.mean()), "states": int(ref.size),
    }


def convergence(fine: GridSolution, coarse: GridSolution, interior_p: float, interior_v: float) -> dict:
    """Per time: metrics of the coarse solution against the fine one on the shared (nested)
    interior nodes — the grid's own discretisation error estimate."""
    step = (fine.p_axis.size - 1) // (coarse.p_axis.size - 1)
    sub = fine.values[:, ::step, ::step, ::step, ::step]
    if sub.shape[1:] != coarse.values.shape[1:] or not np.allclose(fine.p_axis[::step], coarse.p_axis):
        raise ValueError("convergence check needs nested grids (fine nodes = 2·coarse nodes − 1)")
    mask = coarse.interior_mask(interior_p, interior_v)
    return {f"{t:g}": compare_values(sub[i][mask], coarse.values[i][mask]) for i, t in enumerate(coarse.times)}


def vs_on_grid(vs, solution: GridSolution, mask: np.ndarray, chunk: int = 65536) -> np.ndarray:
    """The PINN V_s at the masked nodes, per time: ``[len(times), mask.sum()]`` (m)."""
    import torch

    x = torch.as_tensor(solution.states()[mask], dtype=torch.float64)
    out = []
    for t in solution.times:
        vals = [vs.value(x[i:i + chunk], t=float(t)).double() for i in range(0, x.shape[0], chunk)]
        out.append(torch.cat(vals).cpu().numpy())
    return np.stack(out)


def solve_reference(system: PairSystem, settings: GridSettings, progress: bool = False):
    """The reference at ``settings.nodes`` and at the nested coarse resolution, and the coarse
    one's error against it on the interior nodes (the grid's own convergence check).
    Returns ``(fine, coarse, convergence)``."""
    if settings.p_range > system.p_range or settings.v_range > system.v_range:
        raise ValueError(f"grid box (|p| ≤ {settings.p_range}, |v| ≤ {settings.v_range}) exceeds V_s's trained domain "
                         f"(|p| ≤ {system.p_range}, |v| ≤ {system.v_range})")
    args = (settings.p_range, settings.v_range, settings.times, settings.accuracy, progress)
    fine = solve_pair_grid(system, settings.nodes, *args)
    coarse = solve_pair_grid(system, (settings.nodes + 1) // 2, *args)
    return fine, coarse, convergence(fine, coarse, settings.interior_p, settings.interior_v)


def save_solution(path, solution: GridSolution, system: PairSystem, settings: GridSettings, extra: dict) -> None:
    """Write the solution (float32 values) with the system and settings it solves, as ``.npz``."""
    import json
    from pathlib import Path

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    header = {"system": {"u_max": system.u_max, "collision_radius": system.collision_radius, "horizon": system.horizon},
              "settings": {**settings.__dict__, "times": list(settings.times)}, "meta": solution.meta,
              "wall_s": solution.wall_s, **extra}
    tmp = path.with_name(path.name + ".tmp.npz")
    np.savez_compressed(tmp, p_axis=solution.p_axis, v_axis=solution.v_axis, times=np.asarray(solution.times),
                        values=solution.values.astype(np.float32), header=np.asarray(json.dumps(header)))
    tmp.replace(path)


def load_solution(path) -> tuple[GridSolution, dict]:
    """``(solution, header)`` from :func:`save_solution`'s file."""
    import json

    with np.load(path, allow_pickle=False) as d:
        header = json.loads(str(d["header"]))
        sol = GridSolution(p_axis=d["p_axis"], v_axis=d["v_axis"], times=tuple(float(t) for t in d["times"]),
                           values=d["values"].astype(np.float64), wall_s=float(header["wall_s"]), meta=header["meta"])
    return sol, header


def compare_vs(vs, solution: GridSolution, header: dict) -> dict:
    """Report of the PINN ``vs`` against the grid reference on its interior nodes, per time."""
    system, settings = vs.problem.system, header["settings"]
    ref = header["system"]
    mine = {"u_max": system.u_max, "collision_radius": system.collision_radius, "horizon": system.horizon}
    if any(abs(float(ref[k]) - float(mine[k])) > 1e-12 for k in mine):
        raise ValueError(f"the grid reference solves {ref}, the V_s model {mine}: re-solve the grid for this model")
    if settings["p_range"] > system.p_range or settings["v_range"] > system.v_range:
        raise ValueError("the grid box exceeds V_s's trained domain")
    mask = solution.interior_mask(settings["interior_p"], settings["interior_v"])
    pred = vs_on_grid(vs, solution, mask)
    per_time = {f"{t:g}": compare_values(solution.values[i][mask], pred[i]) for i, t in enumerate(solution.times)}
    return {
        "grid": {**solution.meta, "interior_p": settings["interior_p"], "interior_v": settings["interior_v"],
                 "interior_nodes": int(mask.sum()), "wall_s": solution.wall_s},
        "grid_convergence": header.get("convergence"),
        "vs_vs_grid": per_time,
        "target": {"mae": 0.01, "unsafe_called_safe": 0.05},
        "meets_target": all(m["mae"] <= 0.01 and m["unsafe_called_safe"] <= 0.05 for m in per_time.values()),
        "model_iterations": vs.meta.get("iterations"),
        "model_config_hash": vs.meta.get("config_hash"),
    }
