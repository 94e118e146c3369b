"""Vectorised multi-agent goal-reaching environment on the planar double integrator.

``E`` environments × ``N`` agents advance together in torch. Same dynamics, limits, arena,
scenario distribution, collision radius and sensing radius as the evaluation (SPEC §1–2); the
only difference is the control period: the policy acts every ``train_dt`` s (default 0.05 s,
20 simulation steps of 0.0025 s), the acceleration held over the period (exact zero-order-hold
integration, so the end state is the same as 20 simulator steps), and collisions are checked at
``substeps`` evenly spaced instants inside the period. Deployment queries the trained policy at
the simulator's own period (see :mod:`madpinn.marl.deploy`).

Agents do not stop at a collision: it is penalised and the episode goes on, as in evaluation.
Episodes have a fixed length (the arena's ``episode_s``), ended by a time limit.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch

from madpinn.dynamics import AgentModel
from madpinn.marl.features import LocalObs, local_observation
from madpinn.observation import ObservationSettings, pairwise_distances
from madpinn.scenarios import Arena, generate_scenarios

# Training scenarios come from seeds disjoint from the evaluation seeds (small integers).
TRAIN_SEED_OFFSET = 1_000_000


@dataclass(frozen=True)
class EnvSettings:
    """train_dt: policy period in training (s); substeps: collision checks per period;
    neighbours: K neighbour slots in the local observation."""

    train_dt: float
    substeps: int
    neighbours: int

    @classmethod
    def from_config(cls, d: dict) -> "EnvSettings":
        return cls(train_dt=float(d["train_dt"]), substeps=int(d["substeps"]), neighbours=int(d["neighbours"]))


@dataclass(frozen=True)
class RewardSettings:
    """Per-agent reward per period: ``progress·(d_prev − d) − distance·d·dt − control·‖u/u_max‖²·dt
    − collision·[collided during the period]`` (d: distance to goal, m; dt: train_dt, s)."""

    progress: float
    distance: float
    control: float
    collision: float

    @classmethod
    def from_config(cls, d: dict) -> "RewardSettings":
        return cls(**{k: float(d[k]) for k in ("progress", "distance", "control", "collision")})


@dataclass
class StepInfo:
    """What happened during one period, per agent ``[E, N]``: goal distance before/after (m),
    smallest separation to any other agent over the period (m), collision flag, and the
    applied acceleration ``[E, N, 2]`` (m/s², inside the box)."""

    dist_prev: torch.Tensor
    dist: torch.Tensor
    min_sep: torch.Tensor
    collided: torch.Tensor
    accel: torch.Tensor


def goal_reward(info: StepInfo, w: RewardSettings, dt: float, u_max: float) -> torch.Tensor:
    """Goal-reaching reward ``[E, N]`` of :class:`RewardSettings` (public-baseline style)."""
    control = ((info.accel / u_max) ** 2).sum(-1)
    return (
        w.progress * (info.dist_prev - info.dist)
        - w.distance * info.dist * dt
        - w.control * control * dt
        - w.collision * info.collided.to(info.dist.dtype)
    )


class GoalReachingEnv:
    """Batched episodes in ``arena``; :meth:`reset` draws fresh scenarios (SPEC §2 sampler)."""

    def __init__(
        self,
        dynamics: AgentModel,
        arena: Arena,
        obs_spec: ObservationSettings,
        cfg: EnvSettings,
        seed: int,
        device: torch.device | str = "cpu",
        dtype: torch.dtype = torch.float32,
    ):
        if cfg.train_dt <= 0 or cfg.substeps < 1:
            raise ValueError(f"train_dt must be > 0 and substeps ≥ 1, got {cfg.train_dt}, {cfg.substeps}")
        self.dynamics = dynamics
        self.arena = arena
        self.obs_spec = obs_spec
        self.cfg = cfg
        self.seed = int(seed)
        self.device = torch.device(device)
        self.dtype = dtype
        self.horizon = max(1, int(round(arena.episode_s / cfg.train_dt)))
        self.state: torch.Tensor | None = None
        self.goals: torch.Tensor | None = None
        self.t = 0
        self._drawn: dict[int, int] = {}

    def reset(self, n_envs: int, n_agents: int, fixed_seed: int | None = None) -> LocalObs:
        """Draw ``n_envs`` new scenarios of ``n_agents`` agents at rest; return the observation.

        ``fixed_seed``: instead, scenarios ``0 … n_envs−1`` of that scenario seed (a fixed
        evaluation set, e.g. for learning curves)."""
        if fixed_seed is None:
            seed, first = TRAIN_SEED_OFFSET + self.seed, self._drawn.get(n_agents, 0)
            self._drawn[n_agents] = first + n_envs
        else:
            seed, first = int(fixed_seed), 0
        starts, goals = generate_scenarios(
            self.arena, n_agents, seed, n_envs, 2.0 * self.obs_spec.collision_radius, self.device, self.dtype, first_index=first,
        )
        self.state = torch.cat([starts, torch.zeros_like(starts)], dim=-1)
        self.goals = goals
        self.t = 0
        return self.observe()

    def observe(self) -> LocalObs:
        return local_observation(self.state, self.goals, self.obs_spec, self.cfg.neighbours)

    def goal_distance(self) -> torch.Tensor:
        return torch.linalg.vector_norm(self.dynamics.position(self.state) - self.goals, dim=-1)

    @property
    def done(self) -> bool:
        return self.t >= self.horizon

    def step(self, accel: torch.Tensor) -> tuple[LocalObs, StepInfo]:
        """Hold ``accel`` ``[E, N, 2]`` (m/s², clipped to the box) for one period."""
        if self.state is None:
            raise RuntimeError("reset() before step()")
        if accel.shape != self.state.shape[:-1] + (2,):
            raise ValueError(f"accel must be {tuple(self.state.shape[:-1]) + (2,)}, got {tuple(accel.shape)}")
        u = self.dynamics.clip_control(accel)
        dist_prev = self.goal_distance()
        sub_dt = self.cfg.train_dt / self.cfg.substeps
        min_sep = torch.full_like(dist_prev, float("inf"))
        for _ in range(self.cfg.substeps):
            self.state = self.dynamics.step(self.state, u, sub_dt)
            if self.state.shape[1] > 1:
                min_sep = torch.minimum(min_sep, pairwise_distances(self.dynamics.position(self.state)).amin(-1))
        self.t += 1
        info = StepInfo(dist_prev, self.goal_distance(), min_sep, min_sep <= self.obs_spec.collision_radius, u)
        return self.observe(), info
