"""Local observation of the MARL actor and critic: ego features and a masked neighbour set.

Built from the shared ego-centric layout of :mod:`madpinn.observation` with the ``K`` nearest
agents inside the sensing radius (fewer → masked phantom slots), so the network input is
translation invariant and, through the set encoder, invariant to the neighbours' order.

- ego ``[..., 4]``: ``v_ego`` (m/s), ``g_ego − p_ego`` (m, shortened into ±goal_range).
- neighbours ``[..., K, 6]``: ``p_j − p_ego`` (m), ``v_j − v_ego`` (m/s), ``g_j − p_ego`` (m).
- mask ``[..., K]``: True for a real neighbour (inside the sensing radius).

The MARL baselines (SafeMARL's nominal policy, DEF-MARL) are trained on the paper's planar agents:
their network sizes are the planar layout's, and :func:`local_observation` refuses another model.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import torch

from madpinn.dynamics import PAPER_MODEL, model_class
from madpinn.observation import ObservationLayout, ObservationSettings, build_observation, nearest_neighbours

LAYOUT = ObservationLayout(model_class(PAPER_MODEL).position_dim)
"""the observation layout of the agents the MARL baselines are trained on (the paper's planar ones)"""
EGO_FEATURES = LAYOUT.ego_dim
NEIGHBOUR_FEATURES = LAYOUT.neighbour_dim


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
    if spec.model != PAPER_MODEL:
        raise ValueError(f"the MARL baselines are trained on the paper's {PAPER_MODEL} agents, not {spec.model}")
    kspec = replace(spec.base_mapping(), n_neighbours=k)   # issue-14 mapping fixes are MAD-PINN's
    agent = spec.agent
    idx = nearest_neighbours(agent.position(state), k, radius=spec.sensing_radius)
    obs = build_observation(state, goals, idx, kspec)
    ego = obs[..., :LAYOUT.ego_dim]
    nbr = obs[..., LAYOUT.ego_dim:].reshape(*obs.shape[:-1], k, LAYOUT.neighbour_dim)
    v_rel = nbr[..., LAYOUT.neighbour_velocity] - agent.velocity(state)[..., None, :]
    nbr = torch.cat([nbr[..., LAYOUT.neighbour_position], v_rel, nbr[..., LAYOUT.neighbour_goal]], dim=-1)
    mask = idx >= 0
    nbr = nbr * mask.unsqueeze(-1)  # phantom slots carry zeros (and are masked in the encoder)
    return LocalObs(ego, nbr, mask)
