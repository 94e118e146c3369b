"""Local observation of the MARL actor and critic: ego features and a masked neighbour set.

Built from the shared ego-centric layout of :mod:`madpinn.observation` with the ``K`` nearest
agents inside the sensing radius (fewer → masked phantom slots), so the network input is
translation invariant and, through the set encoder, invariant to the neighbours' order.

- ego ``[..., 4]``: ``v_ego`` (m/s), ``g_ego − p_ego`` (m, shortened into ±goal_range).
- neighbours ``[..., K, 6]``: ``p_j − p_ego`` (m), ``v_j − v_ego`` (m/s), ``g_j − p_ego`` (m).
- mask ``[..., K]``: True for a real neighbour (inside the sensing radius).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import torch

from madpinn.dynamics import AGENT
from madpinn.observation import (
    EGO_DIM,
    NEIGHBOUR_DIM,
    NEIGHBOUR_GOAL,
    NEIGHBOUR_POSITION,
    NEIGHBOUR_VELOCITY,
    ObservationSettings,
    build_observation,
    nearest_neighbours,
)

EGO_FEATURES = EGO_DIM
NEIGHBOUR_FEATURES = NEIGHBOUR_DIM


@dataclass
class LocalObs:
    """Per-agent network input; leading shape ``[...]`` = e.g. ``[envs, agents]``."""

    ego: torch.Tensor  # [..., E]
    neighbours: torch.Tensor  # [..., K, 6]
    mask: torch.Tensor  # [..., K] bool

    def flatten(self) -> "LocalObs":
        """Merge all leading dimensions into one batch dimension."""
        K = self.mask.shape[-1]
        return LocalObs(
            self.ego.reshape(-1, self.ego.shape[-1]),
            self.neighbours.reshape(-1, K, self.neighbours.shape[-1]),
            self.mask.reshape(-1, K),
        )

    def with_extra(self, extra: torch.Tensor) -> "LocalObs":
        """Append extra per-agent inputs ``[..., X]`` (e.g. DEF-MARL's z) to the ego features."""
        return LocalObs(torch.cat([self.ego, extra], dim=-1), self.neighbours, self.mask)

    def index(self, idx: torch.Tensor) -> "LocalObs":
        """Rows ``idx`` of a flattened observation."""
        return LocalObs(self.ego[idx], self.neighbours[idx], self.mask[idx])


def local_observation(state: torch.Tensor, goals: torch.Tensor, spec: ObservationSettings, k: int) -> LocalObs:
    """Global state ``[S, N, 4]``, goals ``[S, N, 2]`` -> :class:`LocalObs` with K = ``k`` slots."""
    if k < 1:
        raise ValueError(f"need at least one neighbour slot, got {k}")
    kspec = replace(spec.base_mapping(), n_neighbours=k)   # issue-14 mapping fixes are MAD-PINN's
    idx = nearest_neighbours(state, k, radius=spec.sensing_radius)
    obs = build_observation(state, goals, idx, kspec)
    ego = obs[..., :EGO_DIM]
    nbr = obs[..., EGO_DIM:].reshape(*obs.shape[:-1], k, NEIGHBOUR_DIM)
    v_rel = nbr[..., NEIGHBOUR_VELOCITY] - AGENT.velocity(state)[..., None, :]
    nbr = torch.cat([nbr[..., NEIGHBOUR_POSITION], v_rel, nbr[..., NEIGHBOUR_GOAL]], dim=-1)
    mask = idx >= 0
    nbr = nbr * mask.unsqueeze(-1)  # phantom slots carry zeros (and are masked in the encoder)
    return LocalObs(ego, nbr, mask)
