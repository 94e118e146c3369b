"""Permutation-invariant decentralised actor and critic over :class:`LocalObs`.

Deep sets: each neighbour's features pass through a shared MLP φ; masked mean and masked max
pooling over the neighbour slots give a fixed-size, order-independent summary that is
concatenated with the ego features (plus any extra inputs, e.g. DEF-MARL's z) and fed to a
trunk MLP. Agents share parameters; the batch dimension mixes environments and agents.
"""

from __future__ import annotations

import math

import torch
from torch import nn

from madpinn.marl.features import LocalObs


def mlp(sizes: list[int], activation=nn.Tanh, out_gain: float = 1.0) -> nn.Sequential:
    layers: list[nn.Module] = []
    for i in range(len(sizes) - 1):
        lin = nn.Linear(sizes[i], sizes[i + 1])
        last = i == len(sizes) - 2
        nn.init.orthogonal_(lin.weight, gain=out_gain if last else math.sqrt(2.0))
        nn.init.zeros_(lin.bias)
        layers.append(lin)
        if not last:
            layers.append(activation())
    return nn.Sequential(*layers)


class SetEncoder(nn.Module):
    """LocalObs -> ``[B, ego + 2·hidden]``: ego features ‖ masked mean ‖ masked max of φ(neighbour)."""

    def __init__(self, ego_features: int, neighbour_features: int, hidden: int):
        super().__init__()
        self.phi = mlp([neighbour_features, hidden, hidden])
        self.out_features = ego_features + 2 * hidden

    def forward(self, obs: LocalObs) -> torch.Tensor:
        h = torch.tanh(self.phi(obs.neighbours))  # [B, K, H]
        m = obs.mask.unsqueeze(-1).to(h.dtype)
        count = m.sum(-2).clamp_min(1.0)
        mean = (h * m).sum(-2) / count
        mx = h.masked_fill(~obs.mask.unsqueeze(-1), -1.0).amax(-2)  # tanh ≥ −1: empty set → −1
        return torch.cat([obs.ego, mean, mx], dim=-1)


class GaussianActor(nn.Module):
    """π(a | o): diagonal Gaussian over the normalised acceleration ``a`` (applied: clip(a)·u_max)."""

    def __init__(self, ego_features: int, neighbour_features: int, hidden: int, action_dim: int = 2, init_log_std: float = -0.5):
        super().__init__()
        self.encoder = SetEncoder(ego_features, neighbour_features, hidden)
        self.trunk = mlp([self.encoder.out_features, hidden, hidden, action_dim], out_gain=0.01)
        self.log_std = nn.Parameter(torch.full((action_dim,), float(init_log_std)))

    def forward(self, obs: LocalObs) -> torch.Tensor:
        """Mean action ``[B, A]``."""
        return self.trunk(self.encoder(obs))

    def distribution(self, obs: LocalObs) -> torch.distributions.Normal:
        mean = self(obs)
        return torch.distributions.Normal(mean, self.log_std.exp().expand_as(mean))


class ValueCritic(nn.Module):
    """V(o) with ``heads`` outputs ``[B, heads]`` (e.g. DEF-MARL's cost and constraint critics)."""

    def __init__(self, ego_features: int, neighbour_features: int, hidden: int, heads: int = 1):
        super().__init__()
        self.encoder = SetEncoder(ego_features, neighbour_features, hidden)
        self.trunk = mlp([self.encoder.out_features, hidden, hidden, heads], out_gain=1.0)

    def forward(self, obs: LocalObs) -> torch.Tensor:
        return self.trunk(self.encoder(obs))
