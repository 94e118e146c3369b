"""A trained MARL actor deployed through the :class:`madpinn.policies.Policy` protocol.

The actor is queried at whatever period the simulator uses (``sim.policy_period_steps``, by
default every 0.0025 s step), although it was trained with a coarser period (``train_dt``): it
is a memoryless state feedback, so a finer period only makes it react sooner. Deterministic:
the Gaussian mean, clipped to the box.
"""

from __future__ import annotations

import torch

from madpinn.marl.features import local_observation
from madpinn.marl.networks import GaussianActor
from madpinn.marl.normalize import ObsNormalizer
from madpinn.observation import ObservationSettings


class ActorPolicy:
    """accel ``[S, N, 2]`` = clip(μ(o_i), −1, 1)·u_max for every agent i in one batch."""

    def __init__(self, actor: GaussianActor, obs_norm: ObsNormalizer, obs_spec: ObservationSettings, neighbours: int, u_max: float):
        self.actor = actor
        self.obs_norm = obs_norm
        self.obs_spec = obs_spec
        self.neighbours = int(neighbours)
        self.u_max = float(u_max)

    def reset(self, state: torch.Tensor, goals: torch.Tensor) -> None:
        pass

    @torch.no_grad()
    def act(self, state: torch.Tensor, goals: torch.Tensor, t: float) -> torch.Tensor:
        S, N, _ = state.shape
        obs = self.obs_norm(local_observation(state, goals, self.obs_spec, self.neighbours))
        return self.actor(obs.flatten()).view(S, N, self.obs_spec.agent.control_dim).clamp(-1.0, 1.0) * self.u_max
