"""Planar double integrator (SPEC §1): s = [x, y, vx, vy] (m, m/s), u = [ax, ay] (m/s²)."""

from __future__ import annotations

from dataclasses import dataclass

import torch

STATE_DIM = 4
CONTROL_DIM = 2


@dataclass(frozen=True)
class DoubleIntegrator:
    """ṗ = v, v̇ = u, u ∈ [-u_max, u_max]², velocity components saturated to [-v_max, v_max].

    All methods broadcast over any leading batch shape ``[..., 4]`` / ``[..., 2]``. No defaults:
    the package builds it from ``agents`` (:meth:`madpinn.settings.AgentSettings.dynamics`).
    """

    u_max: float
    v_max: float

    def clip_control(self, u: torch.Tensor) -> torch.Tensor:
        return u.clamp(-self.u_max, self.u_max)

    def f(self, state: torch.Tensor, u: torch.Tensor) -> torch.Tensor:
        """Continuous-time vector field ``[..., 4]`` (no saturation)."""
        return torch.cat([state[..., 2:4], self.clip_control(u)], dim=-1)

    def step(self, state: torch.Tensor, u: torch.Tensor, dt: float) -> torch.Tensor:
        """Exact zero-order-hold integration over ``dt`` seconds, per axis, with velocity saturation.

        With v_end = clip(v + a·dt) the velocity ramps for τ = (v_end − v)/a ∈ [0, dt] and then
        cruises at v_end, so p' = p + v·τ + a·τ²/2 + v_end·(dt − τ). Without saturation τ = dt and
        this is the textbook closed form.
        """
        if state.shape[-1] != STATE_DIM or u.shape[-1] != CONTROL_DIM:
            raise ValueError(f"expected state [...,4] and control [...,2], got {tuple(state.shape)} and {tuple(u.shape)}")
        a = self.clip_control(u)
        p, v = state[..., 0:2], state[..., 2:4].clamp(-self.v_max, self.v_max)
        v_end = (v + a * dt).clamp(-self.v_max, self.v_max)
        safe_a = torch.where(a == 0, torch.ones_like(a), a)
        tau = torch.where(a == 0, torch.full_like(a, dt), ((v_end - v) / safe_a).clamp(0.0, dt))
        p_new = p + v * tau + 0.5 * a * tau * tau + v_end * (dt - tau)
        return torch.cat([p_new, v_end], dim=-1)
