"""Clipped PPO update (Schulman et al. 2017) for a shared actor and a (multi-head) critic."""

from __future__ import annotations

from dataclasses import dataclass, fields

import torch
from torch import nn

from madpinn.marl.features import LocalObs
from madpinn.marl.networks import GaussianActor


@dataclass(frozen=True)
class PPOSettings:
    """iterations: rollouts (one episode per env each); agents_per_batch: E·N per rollout (E is
    chosen per agent count); epochs / minibatch: passes and samples per gradient step; lr: Adam
    step; discount γ and gae_lambda λ per policy period; clip ε; entropy_coef, value_coef: loss
    weights; max_grad_norm: global gradient clipping; init_log_std: initial log σ of the actor."""

    iterations: int
    agents_per_batch: int
    epochs: int
    minibatch: int
    lr: float
    discount: float
    gae_lambda: float
    clip: float
    entropy_coef: float
    value_coef: float
    max_grad_norm: float
    init_log_std: float

    @classmethod
    def from_config(cls, d: dict) -> "PPOSettings":
        """All fields required (the schema enforces them); ints stay ints."""
        ints = ("iterations", "agents_per_batch", "epochs", "minibatch")
        return cls(**{f.name: (int if f.name in ints else float)(d[f.name]) for f in fields(cls)})


@dataclass
class PPOBatch:
    """Flat training batch of M samples: observations (as the actor saw them), actions ``[M, A]``,
    old log-probabilities ``[M]``, advantages ``[M]``, value targets ``[M, H]``."""

    obs: LocalObs
    actions: torch.Tensor
    logp_old: torch.Tensor
    advantages: torch.Tensor
    returns: torch.Tensor

    def __len__(self) -> int:
        return self.actions.shape[0]


def ppo_update(
    actor: GaussianActor,
    critic: nn.Module,
    optimizer: torch.optim.Optimizer,
    batch: PPOBatch,
    cfg: PPOSettings,
    generator: torch.Generator,
    value_weights: torch.Tensor | None = None,
) -> dict:
    """``cfg.epochs`` passes of shuffled minibatches; returns mean losses, entropy, approx. KL and
    clip fraction. ``value_weights`` ``[H]`` weights the critic heads (default: all 1).
    Raises ``FloatingPointError`` on a non-finite loss."""
    M = len(batch)
    params = [p for g in optimizer.param_groups for p in g["params"]]
    stats = {"loss_policy": 0.0, "loss_value": 0.0, "entropy": 0.0, "approx_kl": 0.0, "clip_frac": 0.0}
    n = 0
    for epoch in range(cfg.epochs):
        perm = torch.randperm(M, generator=generator, device="cpu").to(batch.actions.device)
        for start in range(0, M, cfg.minibatch):
            idx = perm[start : start + cfg.minibatch]
            obs = batch.obs.index(idx)
            adv = batch.advantages[idx]
            adv = (adv - adv.mean()) / (adv.std() + 1e-8) if idx.numel() > 1 else adv
            dist = actor.distribution(obs)
            logp = dist.log_prob(batch.actions[idx]).sum(-1)
            log_ratio = logp - batch.logp_old[idx]
            ratio = log_ratio.exp()
            loss_pi = -torch.minimum(ratio * adv, ratio.clamp(1 - cfg.clip, 1 + cfg.clip) * adv).mean()
            entropy = dist.entropy().sum(-1).mean()
            v_err = (critic(obs) - batch.returns[idx]) ** 2
            if value_weights is not None:
                v_err = v_err * value_weights
            loss_v = v_err.sum(-1).mean()
            loss = loss_pi + cfg.value_coef * loss_v - cfg.entropy_coef * entropy
            if not torch.isfinite(loss):
                raise FloatingPointError(
                    f"non-finite PPO loss (policy {loss_pi.item()}, value {loss_v.item()}, entropy {entropy.item()}) "
                    f"in epoch {epoch}; lower the learning rate or check the reward scale"
                )
            optimizer.zero_grad(set_to_none=True)
            loss.backward()
            nn.utils.clip_grad_norm_(params, cfg.max_grad_norm)
            optimizer.step()
            with torch.no_grad():
                stats["loss_policy"] += loss_pi.item()
                stats["loss_value"] += loss_v.item()
                stats["entropy"] += entropy.item()
                stats["approx_kl"] += ((ratio - 1) - log_ratio).mean().item()
                stats["clip_frac"] += ((ratio - 1).abs() > cfg.clip).float().mean().item()
            n += 1
    return {k: v / max(n, 1) for k, v in stats.items()}
