"""Ego-centric decentralized observation, its costs and constraint (SPEC §3, §4, §6).

One implementation shared by value-function training, policies and metrics.

Observation layout for ``n`` neighbours of agents with ``d``-dimensional positions (the agent
model's ``position_dim``, 2 for the planar double integrator), ``D = 2d + 3d·n`` (all offsets
relative to the ego position, so the observation is translation invariant; units m and m/s)::

    [ v_ego (d), g_ego - p_ego (d),
      for each neighbour j:  p_j - p_ego (d), v_j (d), g_j - p_ego (d) ]

Deployment maps a global state into this layout with :func:`build_observation`: goal offsets
beyond ``goal_range − carrot_margin`` are shortened along their direction (a carrot strictly inside
V̂'s trained box, where V̂ is more accurate than on its edge), neighbour offsets are shrunk along
their direction into the trained range, a neighbour's goal is shortened relative to the
*neighbour* (its own carrot, then cut along its own heading at the trained box, so the heading
the neighbour flies is preserved; ``neighbour_goal: ego`` restores the old shortening of
``g_j − p_ego``, which turns a far neighbour's heading), and missing neighbours are padded with
motionless phantoms sitting at their goals on the boundary of the trained box: phantom slot k
at bearing π/4 + 2πk/n (slot 0 at the corner ``(offset_range, offset_range)``, slot 1 of two
at the opposite corner). Phantoms are therefore ≥ offset_range·√2 − sensing_radius away from
any radius-limited real neighbour and pairwise apart, so they add neither cost nor constraint.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import torch

from madpinn.dynamics import AgentModel, model_class


@dataclass(frozen=True)
class ObservationLayout:
    """Where the ego's and each neighbour's parts sit in the observation of agents with ``d``-axis
    positions (module docstring): ego block ``[v (d), g − p (d)]``, neighbour block
    ``[p_j − p (d), v_j (d), g_j − p (d)]``."""

    d: int

    def block(self, k: int) -> slice:
        """The ``k``-th ``d``-wide block of an ego or a neighbour part."""
        return slice(k * self.d, (k + 1) * self.d)

    ego_velocity = property(lambda self: self.block(0))
    ego_goal = property(lambda self: self.block(1))
    neighbour_position = property(lambda self: self.block(0))
    neighbour_velocity = property(lambda self: self.block(1))
    neighbour_goal = property(lambda self: self.block(2))

    @property
    def ego_dim(self) -> int:
        return 2 * self.d

    @property
    def neighbour_dim(self) -> int:
        return 3 * self.d

    def dim(self, n_neighbours: int) -> int:
        """Observation size ``D = 2d + 3d·n``."""
        return self.ego_dim + self.neighbour_dim * n_neighbours

    @classmethod
    def of(cls, obs_dim: int, n_neighbours: int) -> "ObservationLayout":
        """The layout of observations with ``obs_dim`` features and ``n_neighbours`` neighbours
        (``d = D / (2 + 3n)``; a clear error when no d fits)."""
        d, rest = divmod(int(obs_dim), 2 + 3 * int(n_neighbours))
        if rest or d < 1:
            raise ValueError(f"an observation of {obs_dim} features is no layout of {n_neighbours} neighbours "
                             f"(D = 2d + 3d·n for d-axis agents)")
        return cls(d)


PHANTOM = -1
NEIGHBOUR_GOAL_MODES = ("neighbour", "ego")
TRAINING_MAPPING = {"carrot_margin": 0.0, "neighbour_goal": "ego"}
"""The deployment-only keys at the mapping value-function training sees (:meth:`ObservationSettings.base_mapping`)."""


@dataclass(frozen=True)
class ObservationSettings:
    """Sizes and trained ranges of the decentralized observation.

    n_neighbours: neighbours per agent (paper: 2).
    goal_range: per-coordinate bound (m) of goal offsets seen in training.
    offset_range: per-coordinate bound (m) of neighbour position offsets seen in training.
    sensing_radius: observation radius (m) used by radius-limited neighbour choices.
    collision_radius: r (m).
    model: the agents' model (``agents.model``), whose position axes d the layout has.
    carrot_margin: goal offsets are shortened into ±(goal_range − carrot_margin) (m); 0 = the
        box edge (the old mapping).
    neighbour_goal: ``"neighbour"`` shortens a neighbour's goal offset relative to the neighbour
        (heading preserved), ``"ego"`` shortens ``g_j − p_ego`` into the box (the old mapping).

    No defaults: ``from_config`` reads every field (``config.yaml``); :meth:`base_mapping` is the
    old mapping (what V̂ training and the MARL features use).
    """

    n_neighbours: int
    goal_range: float
    offset_range: float
    sensing_radius: float
    collision_radius: float
    model: str
    carrot_margin: float
    neighbour_goal: str

    def __post_init__(self):
        model_class(self.model)   # an unknown model fails here
        if not (math.isfinite(self.carrot_margin) and 0.0 <= self.carrot_margin < self.goal_range):
            raise ValueError(f"observation.carrot_margin must be in [0, goal_range = {self.goal_range}), got {self.carrot_margin}")
        if self.neighbour_goal not in NEIGHBOUR_GOAL_MODES:
            raise ValueError(f"observation.neighbour_goal must be one of {NEIGHBOUR_GOAL_MODES}, got '{self.neighbour_goal}'")

    def base_mapping(self) -> "ObservationSettings":
        """This spec with the deployment-only settings at the old mapping: what value-function
        training sees, and what the baselines (MPPI, MARL features) keep using (the fixes are
        about V̂'s trained box)."""
        return replace(self, **TRAINING_MAPPING)

    @property
    def carrot_range(self) -> float:
        """Per-coordinate bound (m) of the goal offsets given to V̂ at deployment."""
        return self.goal_range - self.carrot_margin

    @property
    def agent(self) -> type[AgentModel]:
        """The agents' model class: the state layout observations are built from."""
        return model_class(self.model)

    @property
    def layout(self) -> ObservationLayout:
        return ObservationLayout(self.agent.position_dim)

    @property
    def dim(self) -> int:
        return self.layout.dim(self.n_neighbours)

    @property
    def n_agents(self) -> int:
        return self.n_neighbours + 1

    @classmethod
    def from_config(cls, cfg: dict) -> "ObservationSettings":
        o = cfg["observation"]
        return cls(
            n_neighbours=int(o["n_neighbours"]),
            goal_range=float(o["goal_range"]),
            offset_range=float(o["offset_range"]),
            sensing_radius=float(o["sensing_radius"]),
            collision_radius=float(cfg["agents"]["collision_radius"]),
            model=str(cfg["agents"]["model"]),
            carrot_margin=float(o["carrot_margin"]),
            neighbour_goal=str(o["neighbour_goal"]),
        )


def shrink_to_box(vec: torch.Tensor, bound: float) -> torch.Tensor:
    """Scale d-vectors ``[..., d]`` along their direction so that max |coordinate| ≤ bound."""
    max_abs = vec.abs().amax(dim=-1, keepdim=True)
    scale = torch.where(max_abs > bound, bound / max_abs.clamp_min(1e-12), torch.ones_like(max_abs))
    return vec * scale


def clip_ray_to_box(origin: torch.Tensor, ray: torch.Tensor, bound: float) -> torch.Tensor:
    """Largest ``s ∈ [0, 1]`` with ``origin + s·ray`` inside ``[−bound, bound]^d`` (per row), times
    ``ray``: the ray cut at the box, direction kept. ``origin`` outside the box gives the part of
    the ray that stays no farther out than ``origin`` (s = 0 when the ray points outward).
    Shapes ``[..., d]``."""
    hi = origin.clamp_min(bound)    # an origin outside the box is never pushed further out
    lo = origin.clamp_max(-bound)
    room = torch.where(ray > 0, hi - origin, origin - lo)   # distance to the wall the ray heads for
    s = torch.where(ray.abs() > 1e-12, room / ray.abs().clamp_min(1e-12), torch.full_like(ray, float("inf")))
    s = s.amin(dim=-1, keepdim=True).clamp(0.0, 1.0)
    return ray * s


def phantom_offsets(n_neighbours: int, offset_range: float, d: int) -> torch.Tensor:
    """Phantom position (= goal) offsets ``[n, d]`` on the trained box boundary, one per slot: the
    planar bearings in the first two axes (the horizontal plane), 0 on any further axis."""
    k = torch.arange(n_neighbours, dtype=torch.float64)
    angle = math.pi / 4 + 2 * math.pi * k / max(n_neighbours, 1)
    ray = torch.stack([torch.cos(angle), torch.sin(angle)], dim=-1) * 10.0 * offset_range
    planar = shrink_to_box(ray, offset_range)
    return torch.cat([planar, planar.new_zeros(n_neighbours, d - planar.shape[-1])], dim=-1)


def gather_agents(x: torch.Tensor, idx: torch.Tensor) -> torch.Tensor:
    """x ``[S, N, F]``, idx ``[S, N, n]`` (values in 0..N-1) -> ``[S, N, n, F]``."""
    S, N, F = x.shape
    n = idx.shape[-1]
    flat = idx.reshape(S, N * n, 1).expand(S, N * n, F)
    return torch.gather(x, 1, flat).reshape(S, N, n, F)


def build_observation(
    state: torch.Tensor, goals: torch.Tensor, neighbours: torch.Tensor, spec: ObservationSettings
) -> torch.Tensor:
    """Global state ``[S, N, 2d]`` (``spec.agent``'s layout), goals ``[S, N, d]``, neighbour indices
    ``[S, N, n]`` (−1 = phantom) -> observations ``[S, N, 2d + 3d·n]``."""
    agent = spec.agent
    if state.dim() != 3 or state.shape[-1] != agent.state_dim:
        raise ValueError(f"state must be [S, N, {agent.state_dim}] ({agent.name}), got {tuple(state.shape)}")
    if goals.shape != state.shape[:-1] + (agent.position_dim,):
        raise ValueError(f"goals must be [S, N, {agent.position_dim}] matching state, got {tuple(goals.shape)}")
    if neighbours.shape != state.shape[:-1] + (spec.n_neighbours,):
        raise ValueError(f"neighbours must be [S, N, {spec.n_neighbours}], got {tuple(neighbours.shape)}")
    p, v = agent.position(state), agent.velocity(state)
    phantom = neighbours < 0
    idx = neighbours.clamp_min(0)
    p_j = gather_agents(p, idx) - p.unsqueeze(2)
    v_j = gather_agents(v, idx)
    g_j = gather_agents(goals, idx) - p.unsqueeze(2)
    if spec.neighbour_goal == "ego":
        p_j = shrink_to_box(p_j, spec.offset_range)
        g_j = shrink_to_box(g_j, spec.carrot_range)
    else:
        own = shrink_to_box(g_j - p_j, spec.carrot_range)          # the neighbour's own carrot
        p_j = shrink_to_box(p_j, spec.offset_range)
        g_j = p_j + clip_ray_to_box(p_j, own, spec.carrot_range)   # cut along its heading at the box
    slot = phantom_offsets(spec.n_neighbours, spec.offset_range, agent.position_dim).to(p_j)
    mask = phantom.unsqueeze(-1)
    p_j = torch.where(mask, slot, p_j)
    g_j = torch.where(mask, slot, g_j)
    v_j = torch.where(mask, torch.zeros_like(v_j), v_j)
    ego_goal = shrink_to_box(goals - p, spec.carrot_range)
    nbr = torch.cat([p_j, v_j, g_j], dim=-1).flatten(-2)
    return torch.cat([v, ego_goal, nbr], dim=-1)


def split_observation(obs: torch.Tensor, n_neighbours: int):
    """Observation ``[..., D]`` -> ``(positions, velocities, goals)`` each ``[..., n+1, d]``,
    relative to the ego position (ego first, at the origin)."""
    lay = ObservationLayout.of(obs.shape[-1], n_neighbours)
    lead = obs.shape[:-1]
    nbr = obs[..., lay.ego_dim:].reshape(*lead, n_neighbours, lay.neighbour_dim)
    ego_p = torch.zeros(*lead, 1, lay.d, dtype=obs.dtype, device=obs.device)
    positions = torch.cat([ego_p, nbr[..., lay.neighbour_position]], dim=-2)
    velocities = torch.cat([obs[..., None, lay.ego_velocity], nbr[..., lay.neighbour_velocity]], dim=-2)
    goals = torch.cat([obs[..., None, lay.ego_goal], nbr[..., lay.neighbour_goal]], dim=-2)
    return positions, velocities, goals


def join_observation(positions: torch.Tensor, velocities: torch.Tensor, goals: torch.Tensor) -> torch.Tensor:
    """Inverse of :func:`split_observation`: ``(positions, velocities, goals)`` each ``[..., n+1, d]``,
    relative to the ego position (the ego's own position is dropped) -> observation ``[..., D]``."""
    ego = torch.cat([velocities[..., 0, :], goals[..., 0, :]], dim=-1)
    nbr = torch.cat([positions[..., 1:, :], velocities[..., 1:, :], goals[..., 1:, :]], dim=-1).flatten(-2)
    return torch.cat([ego, nbr], dim=-1)


def running_cost(obs: torch.Tensor, n_neighbours: int) -> torch.Tensor:
    """l_d: sum over observed agents of the distance to their goal, ``[...]`` (m)."""
    positions, _, goals = split_observation(obs, n_neighbours)
    return torch.linalg.vector_norm(positions - goals, dim=-1).sum(-1)


def terminal_cost(obs: torch.Tensor, n_neighbours: int) -> torch.Tensor:
    """φ_d: same as the running cost, evaluated at the final time."""
    return running_cost(obs, n_neighbours)


def pair_indices(n_agents: int) -> tuple[list[int], list[int]]:
    rows, cols = torch.triu_indices(n_agents, n_agents, offset=1).tolist()
    return rows, cols


def constraint(obs: torch.Tensor, n_neighbours: int, collision_radius: float) -> torch.Tensor:
    """g_d = max over pairs in the observation of (r − d_jk); > 0 is failure. ``[...]`` (m)."""
    positions, _, _ = split_observation(obs, n_neighbours)
    i, j = pair_indices(n_neighbours + 1)
    d = torch.linalg.vector_norm(positions[..., i, :] - positions[..., j, :], dim=-1)
    return (collision_radius - d).amax(dim=-1)


def pairwise_distances(positions: torch.Tensor) -> torch.Tensor:
    """positions ``[S, N, d]`` -> distances ``[S, N, N]`` with +inf on the diagonal.

    Exact differences, not the matrix-product expansion (whose float32 cancellation error reaches
    millimetres at arena scale — too coarse for collision checks at r = 0.1 m).
    """
    d = torch.cdist(positions, positions, compute_mode="donot_use_mm_for_euclid_dist")
    eye = torch.eye(positions.shape[1], dtype=torch.bool, device=positions.device)
    return d.masked_fill(eye, float("inf"))


def nearest_neighbours(positions: torch.Tensor, n: int, radius: float | None = None) -> torch.Tensor:
    """Indices ``[S, N, n]`` of the n nearest other agents of agents at ``positions`` ``[S, N, d]``
    (m; −1 where fewer exist or all remaining are beyond ``radius``)."""
    S, N, _ = positions.shape
    d = pairwise_distances(positions)
    if radius is not None:
        d = d.masked_fill(d > radius, float("inf"))
    k = min(n, N - 1)
    if k > 0:
        vals, idx = torch.topk(d, k, dim=-1, largest=False)
        idx = torch.where(torch.isinf(vals), torch.full_like(idx, PHANTOM), idx)
    else:
        idx = torch.empty(S, N, 0, dtype=torch.long, device=positions.device)
    if k < n:
        pad = torch.full((S, N, n - k), PHANTOM, dtype=torch.long, device=positions.device)
        idx = torch.cat([idx, pad], dim=-1)
    return idx
