"""Validation of trained value functions: V_s rollouts, V̂ residuals and the grids behind the
figures (the V̂ heatmap's z* comes from the deployed search, :mod:`.z_search`). Pure computations
(figures live in :mod:`.figures`)."""

from __future__ import annotations

import torch

from madpinn.observation import build_observation
from madpinn.value_functions.z_search import min_feasible_z


@torch.no_grad()
def vs_rollouts(vs, samples: int, dt: float, seed: int = 0, chunk: int = 4096) -> dict:
    """Simulate the pair under the V_s-optimal cooperative control from uniform relative states.

    For each state: predicted ``V_s(x, 0)`` and the rollout's ``min_τ ψ`` over ``[0, T]``
    (exact ZOH steps of ``dt``, control re-evaluated each step from ``∇V_s(x, τ)``).
    False safe: ``V_s > 0`` but the rollout collides (``min ψ ≤ 0``).
    """
    system = vs.system
    gen = torch.Generator().manual_seed(20_000_003 + int(seed))
    p = next(vs.net.parameters())
    steps = max(1, round(system.horizon / dt))
    dt = system.horizon / steps
    pred, mins = [], []
    for first in range(0, samples, chunk):
        n = min(chunk, samples - first)
        x = system.sample(n, gen, p.dtype).to(p.device)
        pred.append(vs.value(x, 0.0))
        m = system.target(x)
        for k in range(steps):
            _, grad = vs.value_and_grad(x, k * dt)
            x = system.step(x, system.optimal_control(grad), dt)
            m = torch.minimum(m, system.target(x))
        mins.append(m)
    v, m = torch.cat(pred).double(), torch.cat(mins).double()
    pred_safe, collided = v > 0, m <= 0
    false_safe = pred_safe & collided
    return {
        "samples": int(v.numel()), "rollout_dt": dt, "horizon": system.horizon,
        "false_safe_rate": float(false_safe.double().mean()),
        "false_safe_given_predicted_safe": float(false_safe.sum() / pred_safe.sum().clamp_min(1)),
        "false_unsafe_rate": float((~pred_safe & ~collided).double().mean()),
        "predicted_safe_fraction": float(pred_safe.double().mean()),
        "rollout_collision_fraction": float(collided.double().mean()),
        "mean_abs_error": float((v - m).abs().mean()),
        "mean_error": float((v - m).mean()),
        "p95_abs_error": float(torch.quantile((v - m).abs(), 0.95)),
    }


def _on_axes(planar: torch.Tensor, d: int) -> torch.Tensor:
    """Planar vectors ``[..., 2]`` of a figure as ``[..., d]`` (0 on any axis beyond the horizontal
    plane: a 3-D model's slice at equal altitude and no vertical motion)."""
    return torch.cat([planar, planar.new_zeros(*planar.shape[:-1], d - planar.shape[-1])], dim=-1)


def vs_slices(vs, velocities, points: int = 161, half_width: float | None = None):
    """V_s(x, 0) on the relative-position plane ``[-h, h]²`` (``h``: ``half_width`` m, default the
    training range ``p_range``) for each planar relative velocity (m/s): returns ``(axis [P],
    values [K, P, P])`` (rows: y, columns: x); a 3-D pair is sliced at equal altitude, vz = 0."""
    system = vs.system
    agent = system.agent
    h = system.p_range if half_width is None else float(half_width)
    axis = torch.linspace(-h, h, points, dtype=torch.float64)
    yy, xx = torch.meshgrid(axis, axis, indexing="ij")
    out = []
    for vel in velocities:
        p = _on_axes(torch.stack([xx.flatten(), yy.flatten()], dim=-1), agent.position_dim)
        v = _on_axes(torch.tensor(vel, dtype=torch.float64).expand(p.shape[0], -1), agent.position_dim)
        x = agent.join(p, v)
        out.append(vs.value(x.float(), 0.0).double().cpu().reshape(points, points))
    return axis, torch.stack(out)


# The paper's heatmap configuration (Fig. value function): ego at velocity [1, 0] heading to its
# goal at [-0.5, 0]; neighbours at [-0.3, ±0.4] moving at [-1, 0]. The paper does not state the
# neighbours' goals: we put each 0.7 m ahead of it along its velocity, at [-1.0, ±0.4].
HEATMAP = {
    "ego_velocity": (1.0, 0.0), "ego_goal": (-0.5, 0.0),
    "neighbours": [(-0.3, 0.4), (-0.3, -0.4)], "neighbour_velocity": (-1.0, 0.0),
    "neighbour_goals": [(-1.0, 0.4), (-1.0, -0.4)],
}


def heatmap_observations(spec, half_width: float = 1.0, points: int = 101, cfg: dict = HEATMAP):
    """Observations ``[P*P, D]`` of the ego over a grid of its positions on ``[-hw, hw]²`` in the
    heatmap configuration, built with :func:`madpinn.observation.build_observation` (a 3-D model's
    agents all at one altitude, no vertical motion: the horizontal slice)."""
    axis = torch.linspace(-half_width, half_width, points, dtype=torch.float32)
    yy, xx = torch.meshgrid(axis, axis, indexing="ij")
    P = points * points
    ego_p = torch.stack([xx.flatten(), yy.flatten()], dim=-1)
    nb_p = torch.tensor(cfg["neighbours"], dtype=torch.float32)
    ego_v, nb_v = torch.tensor(cfg["ego_velocity"]), torch.tensor(cfg["neighbour_velocity"])
    positions = torch.cat([ego_p[:, None], nb_p.expand(P, -1, -1)], dim=1)                  # [P, 3, d]
    velocities = torch.cat([ego_v.expand(P, 1, -1), nb_v.expand(P, len(nb_p), -1)], dim=1)
    d = spec.layout.d
    state = spec.agent.join(_on_axes(positions, d), _on_axes(velocities, d))
    goals = torch.cat([torch.tensor(cfg["ego_goal"]).expand(P, 1, -1), torch.tensor(cfg["neighbour_goals"]).expand(P, -1, -1)], dim=1)
    goals = _on_axes(goals, d)
    neighbours = torch.tensor([[1, 2], [0, 2], [0, 1]]).expand(P, -1, -1)
    obs = build_observation(state, goals, neighbours, spec)[:, 0]
    return axis, obs


def heatmap_values(vhat, z_tolerance: float, half_width: float = 1.0, points: int = 101):
    """``(axis [P], V_d = z* [P, P], feasible [P, P], V̂(0, o, z=0) [P, P])`` over the ego position;
    z* from the deployed search on the grid of ``z_tolerance`` (``methods.madpinn.z_tolerance``)."""
    axis, obs = heatmap_observations(vhat.obs_spec, half_width, points)
    p = next(vhat.net.parameters())
    obs = obs.to(device=p.device, dtype=p.dtype)
    z_star, feasible = min_feasible_z(vhat, obs, z_tolerance)
    v0 = vhat.value(obs, torch.zeros(obs.shape[0], dtype=obs.dtype, device=obs.device), 0.0)
    shape = (points, points)
    return axis, z_star.reshape(shape).cpu(), feasible.reshape(shape).cpu(), v0.reshape(shape).cpu()
