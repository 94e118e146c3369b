"""Per-step episode bookkeeping: cumulative cost, collisions, separations, decimated trajectory.

Shared by the simulator and by tests that feed hand-built trajectories.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import torch

from madpinn.dynamics.agent_model import Bound, pair_threshold
from madpinn.observation import pairwise_distances
from madpinn.separation import safe_at


@dataclass
class EpisodeResult:
    """Outcome of one batched episode (S scenarios × N agents).

    cost: ``[S, N]`` cumulative cost ∫‖p−g‖dt + ‖p(T)−g‖ (m·s + m), trapezoidal in time.
    collided: ``[S, N]`` bool, agent ever within ``r`` of another agent.
    first_collision_step: ``[S, N]`` int, −1 if never.
    min_separation: ``[S, N]`` smallest distance to any other agent over the episode (m), in the
    simulation dtype: ``collided == (min_separation <= r)`` exactly, and the same test at any other
    radius ρ gives the agents a simulation recorded at ρ would call collided (:func:`safe_at`).
    collision_radius: r (m) of ``collided``, or one per agent (a pair collides within the mean of its two).
    final_distance: ``[S, N]`` distance to goal at the final time (m).
    times: ``[T']`` (s) and positions ``[T', S, N, d]`` (m) of the decimated trajectory.
    encounter_speed: ``[S, N]`` relative speed ‖v_i − v_j‖ (m/s) to the nearest agent j at agent i's
    first collision, or, for an agent that never collides, at its closest approach (the speed of
    its hardest encounter; the *closing* speed −d‖p_i − p_j‖/dt is zero at a smooth closest
    approach, so the relative speed is the one that tells encounters apart). NaN where the episode
    gave no velocities, or where the closest approach was the start (the agent never approached
    anyone).
    cost_at: ``{step: [S, N]}`` the cost of the episode cut at each horizon step (same definition as
    ``cost`` with ``T`` = that step), read from the same episode.
    """

    cost: np.ndarray
    collided: np.ndarray
    first_collision_step: np.ndarray
    min_separation: np.ndarray
    final_distance: np.ndarray
    times: np.ndarray
    positions: np.ndarray
    goals: np.ndarray
    n_steps: int
    dt: float
    collision_radius: float | tuple = float("nan")
    encounter_speed: np.ndarray | None = None
    cost_at: dict[int, np.ndarray] = field(default_factory=dict)

    def safe_at(self, radius: float) -> np.ndarray:
        """``[S, N]`` bool: agents that never came within ``radius`` (m) of another agent."""
        return safe_at(self.min_separation, radius)


class EpisodeRecorder:
    """Feed the positions ``[S, N, d]`` (and velocities, m/s) at steps 0..K with :meth:`update`, then :meth:`finish`."""

    def __init__(self, goals: torch.Tensor, dt: float, collision_radius: Bound, record_every: int = 0,
                 horizon_steps: tuple[int, ...] = ()):
        """``collision_radius``: r (m), or one radius per agent (a pair collides within the mean of its two);
        ``horizon_steps``: steps at which the cost so far is kept (:attr:`EpisodeResult.cost_at`)."""
        self.goals = goals
        self.dt = float(dt)
        self.r = float(collision_radius) if isinstance(collision_radius, (int, float)) else tuple(map(float, collision_radius))
        self.record_every = int(record_every)
        S, N, _ = goals.shape
        dev = goals.device
        self.integral = torch.zeros(S, N, dtype=torch.float64, device=dev)
        self.collided = torch.zeros(S, N, dtype=torch.bool, device=dev)
        self.first_collision = torch.full((S, N), -1, dtype=torch.long, device=dev)
        self.min_sep = torch.full((S, N), float("inf"), dtype=goals.dtype, device=dev)
        self.encounter_speed = torch.full((S, N), float("nan"), dtype=goals.dtype, device=dev)
        self.horizon_steps = frozenset(int(k) for k in horizon_steps)
        self._cost_at: dict[int, np.ndarray] = {}
        self._last_dist: torch.Tensor | None = None
        self._step = -1
        self._times: list[float] = []
        self._positions: list[np.ndarray] = []

    def update(self, positions: torch.Tensor, velocities: torch.Tensor | None = None) -> None:
        """Step ``k`` (0, 1, …): positions ``[S, N, d]`` (m), velocities ``[S, N, d]`` (m/s) or None."""
        self._step += 1
        k = self._step
        dist = torch.linalg.vector_norm(positions - self.goals, dim=-1).to(torch.float64)
        if self._last_dist is not None:
            self.integral += 0.5 * self.dt * (self._last_dist + dist)
        self._last_dist = dist
        if k in self.horizon_steps:
            self._cost_at[k] = (self.integral + dist).cpu().numpy()
        if positions.shape[1] > 1:
            d = pairwise_distances(positions)
            sep, nearest = d.min(dim=-1)
            hit = sep <= self.r if isinstance(self.r, float) else (d <= pair_threshold(self.r, d)).any(dim=-1)
            new = hit & ~self.collided
            if velocities is not None and k > 0:   # the hardest encounter so far (EpisodeResult.encounter_speed)
                rel = velocities - torch.gather(velocities, 1, nearest.unsqueeze(-1).expand_as(velocities))
                keep = new | ((sep < self.min_sep) & ~self.collided)
                self.encounter_speed = torch.where(keep, torch.linalg.vector_norm(rel, dim=-1), self.encounter_speed)
            self.min_sep = torch.minimum(self.min_sep, sep)
            self.first_collision = torch.where(new, torch.full_like(self.first_collision, k), self.first_collision)
            self.collided |= hit
        if self.record_every and k % self.record_every == 0:
            self._times.append(k * self.dt)
            self._positions.append(positions.detach().cpu().numpy().copy())

    def finish(self, final_positions: torch.Tensor | None = None) -> EpisodeResult:
        if self._last_dist is None:
            raise RuntimeError("no step recorded")
        if self.record_every and (self._step % self.record_every) != 0 and final_positions is not None:
            self._times.append(self._step * self.dt)
            self._positions.append(final_positions.detach().cpu().numpy().copy())
        cost = self.integral + self._last_dist
        positions = np.stack(self._positions) if self._positions else np.zeros((0, *self.goals.shape))
        return EpisodeResult(
            cost=cost.cpu().numpy(),
            collided=self.collided.cpu().numpy(),
            first_collision_step=self.first_collision.cpu().numpy(),
            min_separation=self.min_sep.cpu().numpy(),
            final_distance=self._last_dist.cpu().numpy(),
            times=np.asarray(self._times),
            positions=positions,
            goals=self.goals.detach().cpu().numpy(),
            n_steps=self._step,
            dt=self.dt,
            collision_radius=self.r,
            encounter_speed=self.encounter_speed.cpu().numpy(),
            cost_at=dict(self._cost_at),
        )


def record_trajectory(positions: torch.Tensor, goals: torch.Tensor, dt: float, collision_radius: float,
                      velocities: torch.Tensor | None = None, horizon_steps: tuple[int, ...] = ()) -> EpisodeResult:
    """Evaluate a full trajectory ``[K+1, S, N, d]`` (hand-built or logged; velocities of the same shape, or None)."""
    rec = EpisodeRecorder(goals, dt, collision_radius, horizon_steps=horizon_steps)
    for k, p in enumerate(positions):
        rec.update(p, None if velocities is None else velocities[k])
    return rec.finish()
