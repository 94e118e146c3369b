"""Distributed deployment-time budget: each agent's smallest safe z, the team's maximum.

Agent i searches ``[z_min, z_max]`` for the smallest z with ``V_h(o_i, z) ≤ level`` (its
constraint critic predicts no violation). A larger budget lets the policy trade cost for
safety, so ``V_h`` is taken to be non-increasing in z and the search is a bisection
(``iterations`` halvings, 20 as in the public implementation) that keeps the upper end safe.

Fallbacks: ``V_h(z_min) ≤ level`` (already safe at the smallest budget) → ``z_min``;
``V_h(z_max) > level`` (no budget is predicted safe) → ``z_max``, the most safety-seeking
policy. The team then uses the maximum of its agents' z (DEF-MARL's max-consensus).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import torch


@dataclass
class RootResult:
    """z ``[B]``; all_safe / none_safe ``[B]`` bool mark the two fallbacks."""

    z: torch.Tensor
    all_safe: torch.Tensor
    none_safe: torch.Tensor


def smallest_safe_z(
    value: Callable[[torch.Tensor], torch.Tensor], batch: int, z_min: float, z_max: float, iterations: int = 20,
    level: float = 0.0, device=None, dtype=torch.float32,
) -> RootResult:
    """``value(z [B]) -> V_h [B]`` for B agents; the smallest z in the bracket with V_h ≤ level."""
    if not z_min < z_max or iterations < 0:
        raise ValueError(f"need z_min < z_max and iterations ≥ 0, got {z_min}, {z_max}, {iterations}")
    lo = torch.full((batch,), float(z_min), device=device, dtype=dtype)
    hi = torch.full((batch,), float(z_max), device=device, dtype=dtype)
    all_safe = value(lo) <= level
    none_safe = value(hi) > level
    for _ in range(iterations):
        mid = 0.5 * (lo + hi)
        safe = value(mid) <= level
        hi = torch.where(safe, mid, hi)
        lo = torch.where(safe, lo, mid)
    z = torch.where(all_safe, torch.full_like(hi, z_min), torch.where(none_safe, torch.full_like(hi, z_max), hi))
    return RootResult(z, all_safe, none_safe & ~all_safe)


CONSENSUS = ("global", "graph", "none")
"""how a team agrees on z: max over all agents | max-consensus over the communication graph | none"""


def team_budget(z_agents: torch.Tensor) -> torch.Tensor:
    """``[S, N]`` per-agent budgets → ``[S, N]`` the team maximum broadcast to every agent."""
    return z_agents.amax(-1, keepdim=True).expand_as(z_agents)


def graph_budget(z_agents: torch.Tensor, positions: torch.Tensor, radius: float) -> torch.Tensor:
    """Max-consensus of ``[S, N]`` budgets over the communication graph (agents within
    ``radius`` m of each other, positions ``[S, N, 2]``), iterated to its fixed point (at most
    N − 1 rounds): every agent ends with the maximum over its connected component."""
    from madpinn.observation import pairwise_distances

    N = z_agents.shape[-1]
    eye = torch.eye(N, dtype=torch.bool, device=positions.device)
    linked = (pairwise_distances(positions) <= radius) | eye  # [S, N, N]: i hears j
    z = z_agents
    for _ in range(max(N - 1, 0)):
        nxt = z.unsqueeze(-2).expand_as(linked).masked_fill(~linked, float("-inf")).amax(-1)
        if torch.equal(nxt, z):
            break
        z = nxt
    return z


def agree(z_agents: torch.Tensor, positions: torch.Tensor, radius: float, consensus: str) -> torch.Tensor:
    """The budgets ``[S, N]`` the agents act on under ``consensus`` (:data:`CONSENSUS`)."""
    if consensus == "global":
        return team_budget(z_agents)
    if consensus == "graph":
        return graph_budget(z_agents, positions, radius)
    if consensus == "none":
        return z_agents
    raise ValueError(f"z consensus must be one of {CONSENSUS}, got {consensus!r}")
