"""DEF-MARL's team cost critic ``V_l(x, z)``: centralised (all agents of an environment), and
invariant to the agents' order.

Each agent's local observation (z appended to its ego features) is encoded by the shared
deep-sets :class:`madpinn.marl.networks.SetEncoder` and an MLP; the agents' embeddings are
mean-pooled over the team and a second MLP returns one value per environment. Used in
training only (the advantage baseline); deployment needs the actor and ``V_h`` alone.
"""

from __future__ import annotations

import torch
from torch import nn

from madpinn.marl.features import LocalObs
from madpinn.marl.networks import DEFAULT_ENCODER, make_encoder, mlp


class TeamCostCritic(nn.Module):
    """Flat observations of ``B·N`` agents (env-major, N agents per env) → ``[B]``."""

    def __init__(self, ego_features: int, neighbour_features: int, hidden: int, encoder: str = DEFAULT_ENCODER):
        super().__init__()
        self.encoder = make_encoder(encoder, ego_features, neighbour_features, hidden)
        self.agent = mlp([self.encoder.out_features, hidden, hidden])
        self.head = mlp([hidden, hidden, 1], out_gain=1.0)

    def forward(self, obs: LocalObs, n_agents: int) -> torch.Tensor:
        e = torch.tanh(self.agent(self.encoder(obs)))  # [B·N, H]
        return self.head(e.view(-1, n_agents, e.shape[-1]).mean(1)).squeeze(-1)


def team_rows(groups: torch.Tensor, n_agents: int) -> torch.Tensor:
    """Row indices ``[G·N]`` of the agents of env-groups ``groups`` ``[G]`` in a flat batch."""
    return (groups.unsqueeze(-1) * n_agents + torch.arange(n_agents, device=groups.device)).reshape(-1)
