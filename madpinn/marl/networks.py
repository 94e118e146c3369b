"""Permutation-invariant decentralised actor and critic over :class:`LocalObs`.

Deep sets: each neighbour's features pass through a shared MLP φ; masked mean and masked max
pooling over the neighbour slots give a fixed-size, order-independent summary that is
concatenated with the ego features (plus any extra inputs, e.g. DEF-MARL's z) and fed to a
trunk MLP. Agents share parameters; the batch dimension mixes environments and agents.

Encoders (:data:`ENCODERS`, ``network.encoder`` of a training block): ``deepsets`` (above, the
shipped models) or ``attention`` (:class:`AttentionEncoder`: the mean pool replaced by one head
of attention over the neighbours, queried by the agent's own kinematic features — the public
DEF-MARL's graph-transformer layer, reduced to the K observed neighbours).
"""

from __future__ import annotations

import math

import torch
from torch import nn

from madpinn.marl.features import EGO_FEATURES, LocalObs

ENCODERS = ("deepsets", "attention")
DEFAULT_ENCODER = "deepsets"
"""the encoder of a training block without ``network.encoder`` and of checkpoints that do not
record one (every model trained before the option existed)"""


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


class AttentionEncoder(nn.Module):
    """LocalObs -> ``[B, ego + 2·hidden]``: ego features ‖ attention pool ‖ masked max of
    φ(neighbour). One head of scaled dot-product attention: the query comes from the agent's own
    first :data:`EGO_FEATURES` ego features (velocity, goal offset — not extras such as z, so z
    still enters only through the ego columns), keys and values from φ(neighbour); masked slots
    get no weight, an agent without neighbours pools zeros."""

    def __init__(self, ego_features: int, neighbour_features: int, hidden: int):
        super().__init__()
        self.phi = mlp([neighbour_features, hidden, hidden])
        self.query = nn.Linear(min(EGO_FEATURES, ego_features), hidden)
        self.key = nn.Linear(hidden, hidden)
        self.value = nn.Linear(hidden, hidden)
        self.scale = 1.0 / math.sqrt(hidden)
        self.out_features = ego_features + 2 * hidden

    def forward(self, obs: LocalObs) -> torch.Tensor:
        h = torch.tanh(self.phi(obs.neighbours))  # [B, K, H]
        q = self.query(obs.ego[..., : self.query.in_features])  # [B, H]
        logits = (self.key(h) * q.unsqueeze(-2)).sum(-1) * self.scale  # [B, K]
        logits = logits.masked_fill(~obs.mask, float("-inf"))
        any_nbr = obs.mask.any(-1, keepdim=True)
        w = torch.softmax(torch.where(any_nbr, logits, torch.zeros_like(logits)), dim=-1) * any_nbr
        pooled = (w.unsqueeze(-1) * self.value(h)).sum(-2)
        mx = h.masked_fill(~obs.mask.unsqueeze(-1), -1.0).amax(-2)
        return torch.cat([obs.ego, pooled, mx], dim=-1)


def make_encoder(kind: str, ego_features: int, neighbour_features: int, hidden: int) -> nn.Module:
    """The neighbour encoder ``kind`` (:data:`ENCODERS`)."""
    if kind == "deepsets":
        return SetEncoder(ego_features, neighbour_features, hidden)
    if kind == "attention":
        return AttentionEncoder(ego_features, neighbour_features, hidden)
    raise ValueError(f"encoder must be one of {ENCODERS}, got {kind!r}")


class GaussianActor(nn.Module):
    """π(a | o): diagonal Gaussian over the normalised acceleration ``a`` (applied: clip(a)·u_max)."""

    def __init__(self, ego_features: int, neighbour_features: int, hidden: int, action_dim: int = 2, init_log_std: float = -0.5,
                 encoder: str = DEFAULT_ENCODER):
        super().__init__()
        self.encoder = make_encoder(encoder, ego_features, neighbour_features, hidden)
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

    def __init__(self, ego_features: int, neighbour_features: int, hidden: int, heads: int = 1,
                 encoder: str = DEFAULT_ENCODER):
        super().__init__()
        self.encoder = make_encoder(encoder, ego_features, neighbour_features, hidden)
        self.trunk = mlp([self.encoder.out_features, hidden, hidden, heads], out_gain=1.0)

    def forward(self, obs: LocalObs) -> torch.Tensor:
        return self.trunk(self.encoder(obs))
