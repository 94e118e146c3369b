"""Epigraph-form quantities of DEF-MARL, vectorised over time, environments and agents.

Constrained problem (per team): minimise the discounted cost ``Σ_t γ^t l_t`` subject to
``h_i(x_t) ≤ 0`` for every agent i and step t. Epigraph form with the budget z:
``V(x, z) = max( max_i V_h,i(x, z), V_l(x, z) − z )``, safe and within budget iff ``V ≤ 0``;
along a rollout ``z_{t+1} = z_t − l_t`` (clipped to the training range).

- ``l_t`` (team cost per period) is the mean over agents of the negated goal-reaching reward
  of :mod:`madpinn.marl.env` without its collision term (collisions are the constraint).
- ``h_i`` from the agent's smallest separation ``s_i`` over the period (m) and the collision
  radius r: the graded margin ``g = (r − s_i)/h_clip·(1 − m)`` shifted away from 0 by the
  margin m — ``h = max(g − m, −1)`` when safe (``s_i ≥ r``: −m at contact, −1 from
  ``r + h_clip`` on), ``h = g + m`` on a collision. ``h_i > 0`` ⇔ collision; the jump of 2m at
  the collision boundary (m = 0.5, as the public implementation's cost margin) makes a grazing
  collision as visible to the discounted-max target as a deep one.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch


@dataclass(frozen=True)
class EpigraphSettings:
    """z_min, z_max: training range of the budget z (team cost units); end_mass: probability
    that an episode starts exactly at z_min or z_max (half each), the rest uniform; h_clip:
    separation margin (m) beyond which h saturates at −1; h_margin: the jump ±m of h at the
    collision boundary (0 ≤ m < 1); cost_lr: Adam step of the cost critic."""

    z_min: float
    z_max: float
    end_mass: float
    h_clip: float
    cost_lr: float
    h_margin: float

    def __post_init__(self):
        if not self.z_min < self.z_max:
            raise ValueError(f"z_min must be < z_max, got {self.z_min}, {self.z_max}")
        if not 0.0 <= self.end_mass <= 1.0 or self.h_clip <= 0 or self.cost_lr <= 0 or not 0.0 <= self.h_margin < 1.0:
            raise ValueError(f"need 0 ≤ end_mass ≤ 1, h_clip > 0, cost_lr > 0, 0 ≤ h_margin < 1 (got {self})")

    @classmethod
    def from_config(cls, d: dict) -> "EpigraphSettings":
        return cls(**{k: float(d[k]) for k in ("z_min", "z_max", "end_mass", "h_clip", "cost_lr", "h_margin")})


def sample_z(n: int, cfg: EpigraphSettings, generator: torch.Generator, dtype=torch.float32) -> torch.Tensor:
    """Initial budgets ``[n]``: z_min or z_max with probability end_mass/2 each, else uniform."""
    u = torch.rand(n, generator=generator, dtype=torch.float64)
    x = torch.rand(n, generator=generator, dtype=torch.float64)
    z = cfg.z_min + (cfg.z_max - cfg.z_min) * x
    z = torch.where(u < cfg.end_mass / 2, torch.full_like(z, cfg.z_min), z)
    z = torch.where((u >= cfg.end_mass / 2) & (u < cfg.end_mass), torch.full_like(z, cfg.z_max), z)
    return z.to(dtype)


def update_z(z: torch.Tensor, cost: torch.Tensor, cfg: EpigraphSettings) -> torch.Tensor:
    """z dynamics along a rollout: ``z' = clip(z − l, z_min, z_max)`` (``[E]``)."""
    return (z - cost).clamp(cfg.z_min, cfg.z_max)


def collision_constraint(min_sep: torch.Tensor, radius: float, h_clip: float, margin: float = 0.0) -> torch.Tensor:
    """h ``[E, N]`` from the smallest separation over the period (m); inf (alone) → −1.

    ``g = (r − s)/h_clip·(1 − margin)``; ``h = g + margin`` on a collision (s < r), else
    ``max(g − margin, −1)``: in ``[−1, −margin]`` when safe, ``> margin`` when not."""
    g = (radius - min_sep) / h_clip * (1.0 - margin)
    return torch.where(min_sep < radius, g + margin, (g - margin).clamp_min(-1.0))


def epigraph_value(vh: torch.Tensor, vl: torch.Tensor, z: torch.Tensor) -> torch.Tensor:
    """Per-agent total value ``max(V_h,i, V_l − z)``: vh ``[..., N]``, vl and z ``[...]``."""
    return torch.maximum(vh, (vl - z).unsqueeze(-1))


def discounted_max_return(h: torch.Tensor, v_last: torch.Tensor, gamma: float) -> torch.Tensor:
    """Monte-Carlo constraint target ``V_t = max(h_t, (1−γ)·h_t + γ·V_{t+1})``, ``V_T = v_last``.

    The discounted-max backup of the public implementation ("discount to max"): as γ → 1 it is
    ``max_{s ≥ t} h_s``. h ``[T, ...]``, v_last ``[...]`` → ``[T, ...]``."""
    out = torch.empty_like(h)
    nxt = v_last
    for t in range(h.shape[0] - 1, -1, -1):
        nxt = torch.maximum(h[t], (1 - gamma) * h[t] + gamma * nxt)
        out[t] = nxt
    return out


def epigraph_lambda_returns(
    h: torch.Tensor, cost: torch.Tensor, z: torch.Tensor, vh: torch.Tensor, vl: torch.Tensor, gamma: float, lam: float,
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """Dec-EFOCP λ-returns (GAE-style mixture of n-step epigraph backups).

    h ``[T, E, N]`` constraint per agent, cost ``[T, E]`` team cost, z ``[T, E]`` budget at
    each step, vh ``[T+1, E, N]`` and vl ``[T+1, E]`` critic values (index T bootstraps the
    truncated end). The n-step backups from t are
    ``Vh⁽ⁿ⁾_t = max(h_t, (1−γ)h_t + γ·Vh⁽ⁿ⁻¹⁾_{t+1})``, ``Vl⁽ⁿ⁾_t = l_t + γ·Vl⁽ⁿ⁻¹⁾_{t+1}`` (with
    ``⁽⁰⁾`` the critics) and ``V⁽ⁿ⁾_t = max(Vh⁽ⁿ⁾_t, Vl⁽ⁿ⁾_t − z_t)``; each is mixed with weights
    ``(1−λ)λ^{n−1}`` (the longest, ``n = T − t``, gets the remaining ``λ^{T−t−1}``).

    Returns the constraint targets ``[T, E, N]``, cost targets ``[T, E]`` and total
    ``Q [T, E, N]``; the advantage is ``max(vh_t, vl_t − z_t) − Q_t`` (a cost: lower is better)."""
    T = h.shape[0]
    if cost.shape != h.shape[:2] or z.shape != cost.shape or vh.shape != (T + 1,) + h.shape[1:] or vl.shape != (T + 1,) + cost.shape[1:]:
        raise ValueError(
            f"shape mismatch: h {tuple(h.shape)}, cost {tuple(cost.shape)}, z {tuple(z.shape)}, vh {tuple(vh.shape)}, vl {tuple(vl.shape)}"
        )
    row_h = torch.zeros((T + 1,) + tuple(h.shape[1:]), dtype=h.dtype, device=h.device)
    row_l = torch.zeros((T + 1,) + tuple(cost.shape[1:]), dtype=h.dtype, device=h.device)
    row_h[0], row_l[0] = vh[T], vl[T]
    qh, ql, q = torch.empty_like(h), torch.empty_like(cost), torch.empty_like(h)
    n = torch.arange(T + 1, device=h.device, dtype=h.dtype)
    for t in range(T - 1, -1, -1):
        m = T - t  # longest backup from t
        new_h = torch.empty_like(row_h)
        new_l = torch.empty_like(row_l)
        new_h[1:] = torch.maximum(h[t], (1 - gamma) * h[t] + gamma * row_h[:-1])
        new_l[1:] = cost[t] + gamma * row_l[:-1]
        new_h[0], new_l[0] = vh[t], vl[t]
        w = torch.where(n < m, (1 - lam) * lam ** (n - 1).clamp_min(0), torch.zeros_like(n))
        w[m] = lam ** (m - 1)
        w[0] = 0.0
        total = torch.maximum(new_h, (new_l - z[t]).unsqueeze(-1))
        wh = w.view(-1, *([1] * (h.dim() - 1)))
        wl = w.view(-1, *([1] * (cost.dim() - 1)))
        qh[t] = (wh * new_h).sum(0)
        ql[t] = (wl * new_l).sum(0)
        q[t] = (wh * total).sum(0)
        row_h, row_l = new_h, new_l
    return qh, ql, q
