"""Generalised advantage estimation (Schulman et al. 2016), vectorised over everything but time."""

from __future__ import annotations

import torch


def gae(
    rewards: torch.Tensor,
    values: torch.Tensor,
    last_values: torch.Tensor,
    discount: float,
    lam: float,
    terminated: torch.Tensor | None = None,
) -> tuple[torch.Tensor, torch.Tensor]:
    """Advantages and λ-returns, both ``[T, ...]``.

    rewards, values: ``[T, ...]`` (values[t] = V(o_t)); last_values ``[...]`` = V(o_T) bootstraps
    the end of the rollout (a time-limit truncation, not a termination). ``terminated[t]`` (bool,
    optional) marks a true termination after step t: no bootstrap across it.
    """
    if rewards.shape != values.shape or last_values.shape != rewards.shape[1:]:
        raise ValueError(
            f"shape mismatch: rewards {tuple(rewards.shape)}, values {tuple(values.shape)}, last_values {tuple(last_values.shape)}"
        )
    T = rewards.shape[0]
    cont = torch.ones_like(rewards) if terminated is None else (~terminated).to(rewards.dtype)
    adv = torch.zeros_like(rewards)
    running = torch.zeros_like(last_values)
    next_v = last_values
    for t in range(T - 1, -1, -1):
        delta = rewards[t] + discount * cont[t] * next_v - values[t]
        running = delta + discount * lam * cont[t] * running
        adv[t] = running
        next_v = values[t]
    return adv, adv + values
