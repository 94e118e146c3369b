"""Conflict-focused training distribution for V̂ (importance sampling of near-collisions).

A uniform box over the ego-centric observation rarely puts two agents on a collision course
within the short horizon T: for the default ranges (offsets ±2 m) fewer than 5 % of uniform
samples have a pair that comes within 0.3 m during 0.2 s, yet these states carry the whole
safety decision (the kink of ``max(φ_d − z, g_d)`` and the feasible/infeasible boundary in z).
:func:`place_conflicts` rewrites the positions of a chosen fraction of a uniform batch so that one
pair among the ``n + 1`` observed agents is on a near-collision course under constant velocity:

    x_b − x_a = −(v_b − v_a)·τ + d,    τ ~ U[0, T],   d ~ U(disk of radius ρ),

i.e. the pair's constant-velocity relative position reaches the disk of radius ρ around the
origin at time τ. Velocities, goals, z and t stay uniform; the moved offset is clipped to the
trained box, so every sample stays inside the domain. With ``fraction = 0`` the batch is the
uniform batch unchanged (same generator draws), which keeps old configurations reproducible.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import torch

from madpinn.dynamics import AgentModel
from madpinn.observation import ObservationLayout, split_observation


@dataclass(frozen=True)
class ConflictSamplingSettings:
    """fraction: share of each batch on a near-collision course; radius: ρ (m) of the disk the
    pair's constant-velocity relative position reaches within the horizon.

    Speed-aware variant (issue 33; V̂ only): ``tau = (lo, hi)`` draws the time to the near miss as
    ``τ ~ U[lo·T, hi·T]`` instead of ``U[0, T]`` (fractions of the horizon; ``(0.5, 1)`` puts the
    encounter late in the horizon, where V̂ must decide early); ``closing_speed = (lo, hi)`` redraws
    the pair's relative velocity with speed ``~ U[lo, hi]`` (m/s) in a uniform direction around the
    pair's mean velocity (both then clipped to ±v_max per axis). ``None`` / ``(0, 1)`` draw exactly
    what the plain sampler draws."""

    fraction: float
    radius: float
    tau: tuple[float, float]
    closing_speed: tuple[float, float] | None

    def __post_init__(self):
        if not 0.0 <= self.fraction <= 1.0:
            raise ValueError(f"conflict sampling fraction must be in [0, 1], got {self.fraction}")
        if self.radius <= 0.0:
            raise ValueError(f"conflict sampling radius must be > 0 m, got {self.radius}")
        lo, hi = self.tau
        if not 0.0 <= lo <= hi <= 1.0:
            raise ValueError(f"conflict sampling tau must be fractions 0 <= lo <= hi <= 1 of the horizon, got {self.tau}")
        if self.closing_speed is not None and not 0.0 <= self.closing_speed[0] <= self.closing_speed[1]:
            raise ValueError(f"conflict sampling closing_speed must be 0 <= lo <= hi (m/s), got {self.closing_speed}")

    @classmethod
    def from_config(cls, vcfg: dict) -> "ConflictSamplingSettings":
        c = vcfg["conflict_sampling"]
        speed = c["closing_speed"]   # null: the uniform velocities
        return cls(fraction=float(c["fraction"]), radius=float(c["radius"]), tau=tuple(float(x) for x in c["tau"]),
                   closing_speed=None if speed is None else tuple(float(x) for x in speed))


def _velocity_columns(agent: torch.Tensor, lay: ObservationLayout) -> torch.Tensor:
    """First velocity column of observed agent ``agent`` (0 = ego) in the observation vector."""
    return torch.where(agent == 0, torch.full_like(agent, lay.ego_velocity.start),
                       lay.ego_dim + (agent - 1) * lay.neighbour_dim + lay.neighbour_velocity.start)


def _on_axes(planar: torch.Tensor, d: int) -> torch.Tensor:
    """Planar draws ``[m, 2]`` as ``[m, d]`` vectors: 0 on any axis beyond the horizontal plane
    (the conflict draws are planar by design; a 3-D model's pairs meet at equal altitude)."""
    return torch.cat([planar, planar.new_zeros(planar.shape[0], d - planar.shape[-1])], dim=-1)


def _draw_course(m: int, horizon: float, sampling: ConflictSamplingSettings, generator: torch.Generator,
                 dtype: torch.dtype, device) -> tuple[torch.Tensor, torch.Tensor]:
    """The near-collision course of ``m`` pairs: time to closest approach ``τ ~ U[lo·T, hi·T]`` (s,
    ``[m]``; ``sampling.tau``) and miss offset ``d`` uniform in the disk of radius ρ (m, ``[m, 2]``)."""
    lo, hi = sampling.tau
    tau = horizon * (lo + (hi - lo) * torch.rand(m, generator=generator, dtype=dtype)).to(device)
    radius = sampling.radius * torch.sqrt(torch.rand(m, generator=generator, dtype=dtype)).to(device)
    angle = 2.0 * math.pi * torch.rand(m, generator=generator, dtype=dtype).to(device)
    return tau, torch.stack([radius * torch.cos(angle), radius * torch.sin(angle)], -1)


def _draw_closing_velocity(m: int, speed: tuple[float, float], generator: torch.Generator, dtype: torch.dtype,
                           device) -> torch.Tensor:
    """``m`` relative velocities ``[m, 2]`` (m/s) of speed ``U[speed]`` and uniform direction."""
    w = (speed[0] + (speed[1] - speed[0]) * torch.rand(m, generator=generator, dtype=dtype)).to(device)
    phi = (2.0 * math.pi * torch.rand(m, generator=generator, dtype=dtype)).to(device)
    return torch.stack([w * torch.cos(phi), w * torch.sin(phi)], -1)


def _redraw_closing(out: torch.Tensor, a, c, va, vc, speed: tuple[float, float], v_max: float,
                    generator: torch.Generator, lay: ObservationLayout):
    """Give pair ``(a, c)`` of each row a relative velocity of speed ``U[speed]`` (m/s), uniform
    direction, around its mean velocity; both clipped to ±``v_max``; written into ``out``.
    Returns the new ``(va, vc)`` ``[m, d]``."""
    m, dtype, device = va.shape[0], va.dtype, va.device
    rel = _on_axes(_draw_closing_velocity(m, speed, generator, dtype, device), lay.d)
    mean = 0.5 * (va + vc)
    va, vc = (mean - 0.5 * rel).clamp(-v_max, v_max), (mean + 0.5 * rel).clamp(-v_max, v_max)
    rows = torch.arange(m, device=device)
    for agent, v in ((a, va), (c, vc)):
        col = _velocity_columns(agent, lay)
        for k in range(v.shape[-1]):
            out[rows, col + k] = v[:, k]
    return va, vc


def place_conflicts(obs: torch.Tensor, n_neighbours: int, horizon: float, offset_range: float,
                    sampling: ConflictSamplingSettings, generator: torch.Generator, v_max: float | None = None) -> torch.Tensor:
    """Return ``obs [B, D]`` with the first ``round(fraction·B)`` rows moved onto a
    near-collision course of one pair (uniform over the ``(n+1)n/2`` pairs; the moved agent is
    always a neighbour, so the ego stays at the origin). ``v_max`` (m/s per axis) bounds the
    velocities that ``sampling.closing_speed`` redraws (required then). Pure function of the
    generator state."""
    b = obs.shape[0]
    m = int(round(sampling.fraction * b))
    if m == 0 or n_neighbours == 0:
        return obs
    if sampling.closing_speed is not None and v_max is None:
        raise ValueError("conflict sampling with closing_speed needs v_max (the velocity bound of the domain)")
    dtype, device = obs.dtype, obs.device
    lay = ObservationLayout.of(obs.shape[-1], n_neighbours)
    pairs = [(a, c) for c in range(1, n_neighbours + 1) for a in range(c)]   # (a < c), c a neighbour
    pick = torch.randint(len(pairs), (m,), generator=generator)
    a = torch.tensor([p[0] for p in pairs])[pick].to(device)
    c = torch.tensor([p[1] for p in pairs])[pick].to(device)
    tau, d = _draw_course(m, horizon, sampling, generator, dtype, device)
    d = _on_axes(d, lay.d)
    pos, vel, _ = split_observation(obs[:m], n_neighbours)      # [m, n+1, d], ego first
    rows = torch.arange(m, device=device)
    pa, va, vc = pos[rows, a], vel[rows, a], vel[rows, c]
    out = obs.clone()
    if sampling.closing_speed is not None:
        va, vc = _redraw_closing(out, a, c, va, vc, sampling.closing_speed, v_max, generator, lay)
    pc = (pa - (vc - va) * tau[:, None] + d).clamp(-offset_range, offset_range)
    cols = lay.ego_dim + (c - 1) * lay.neighbour_dim + lay.neighbour_position.start   # position offset of neighbour c
    for k in range(pc.shape[-1]):
        out[rows, cols + k] = pc[:, k]
    return out


def place_pair_conflicts(x: torch.Tensor, horizon: float, p_range: float, sampling: ConflictSamplingSettings,
                         generator: torch.Generator, agent: type[AgentModel], v_range: float | None = None) -> torch.Tensor:
    """Return the relative pair states ``x [B, 2d] = [p, v]`` of agents of model ``agent`` with the first ``round(fraction·B)``
    rows moved onto a near-collision course: ``p = −v·τ + d``, ``τ ~ U[lo·T, hi·T]`` (``sampling.tau``),
    ``d`` uniform in the disk of radius ρ, clipped to ``|p| ≤ p_range`` (V_s's training domain).
    Velocities stay uniform unless ``sampling.closing_speed`` redraws them (speed ``U[lo, hi]`` m/s,
    uniform direction, clipped to ``±v_range``, required then); ``fraction = 0`` returns ``x``
    unchanged. Pure function of the generator state."""
    m = int(round(sampling.fraction * x.shape[0]))
    if m == 0:
        return x
    if sampling.closing_speed is not None and v_range is None:
        raise ValueError("conflict sampling with closing_speed needs v_range (the velocity bound of the domain)")
    dtype, device = x.dtype, x.device
    tau, d = _draw_course(m, horizon, sampling, generator, dtype, device)
    d = _on_axes(d, agent.position_dim)
    out = x.clone()
    if sampling.closing_speed is not None:
        rel = _on_axes(_draw_closing_velocity(m, sampling.closing_speed, generator, dtype, device), agent.position_dim)
        out[:m, agent.velocity_slice()] = rel.clamp(-v_range, v_range)
    out[:m, agent.position_slice()] = (-agent.velocity(out[:m]) * tau[:, None] + d).clamp(-p_range, p_range)
    return out


@dataclass(frozen=True)
class NearSamplingSettings:
    """fraction: share of each V_s training batch drawn uniformly from the inner box
    ``|p| ≤ p_range``, ``|v| ≤ v_range`` per axis (m, m/s), where nearby, slow pairs sit — a small
    corner of the uniform training box (|p| ≤ 2, |v| ≤ 8: the inner box 1 × 3 holds 3.5 % of it)
    that carries the collision disk, the kink of ψ and most of the grid reference's unsafe states."""

    fraction: float
    p_range: float
    v_range: float

    def __post_init__(self):
        if not 0.0 <= self.fraction <= 1.0:
            raise ValueError(f"near sampling fraction must be in [0, 1], got {self.fraction}")
        if self.p_range <= 0.0 or self.v_range <= 0.0:
            raise ValueError(f"near sampling box must be positive, got p {self.p_range} m, v {self.v_range} m/s")

    @classmethod
    def from_config(cls, vcfg: dict) -> "NearSamplingSettings":
        c = vcfg["near_sampling"]
        return cls(fraction=float(c["fraction"]), p_range=float(c["p_range"]), v_range=float(c["v_range"]))


def place_near(x: torch.Tensor, p_range: float, v_range: float, sampling: NearSamplingSettings,
               generator: torch.Generator, agent: type[AgentModel]) -> torch.Tensor:
    """Return the relative pair states ``x [B, 2d]`` of agents of model ``agent`` with the last ``round(fraction·B)`` rows redrawn
    uniformly from the inner box (clipped to the training box ``p_range``, ``v_range``); the first
    rows (where :func:`place_pair_conflicts` works) are untouched. ``fraction = 0`` returns ``x``
    unchanged without drawing. Pure function of the generator state."""
    m = int(round(sampling.fraction * x.shape[0]))
    if m == 0:
        return x
    d = agent.position_dim
    half = torch.tensor([min(sampling.p_range, p_range)] * d + [min(sampling.v_range, v_range)] * d, dtype=x.dtype)
    u = torch.rand(m, agent.state_dim, generator=generator, dtype=x.dtype)
    out = x.clone()
    out[x.shape[0] - m:] = ((2.0 * u - 1.0) * half).to(x.device)
    return out
