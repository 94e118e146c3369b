"""Planar double integrator (SPEC §1): s = [x, y, vx, vy] (m, m/s), u = [ax, ay] (m/s²).

:func:`hold_step` is the package's one exact zero-order-hold step of a double integrator (any
number of axes): the agents' simulation, the pair system, the look-ahead, the V̂ verification and
the oracle's receding-horizon check all integrate with it.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import torch

from madpinn.dynamics.agent_model import AgentModel, Bound


def hold_step(position: torch.Tensor, velocity: torch.Tensor, accel: torch.Tensor, dt,
              v_max: float | torch.Tensor | None = None) -> tuple[torch.Tensor, torch.Tensor]:
    """Exact zero-order hold of ``ṗ = v, v̇ = a`` over ``dt`` (s; a float or a tensor broadcasting
    against the states), per axis: ``(p', v')`` shaped like ``position`` / ``velocity``.

    ``v_max`` None: the textbook closed form ``p + v·dt + a·dt²/2``, ``v + a·dt`` (``accel`` as
    given). Otherwise (a bound broadcasting over the axes, e.g. per agent ``[N, 1]``) the velocity
    is first clipped, then with ``v_end = clip(v + a·dt)`` it ramps for ``τ = (v_end − v)/a ∈ [0, dt]``
    and cruises at ``v_end``: ``p' = p + v·τ + a·τ²/2 + v_end·(dt − τ)``; without saturation ``τ = dt``.
    """
    if v_max is None:
        return position + velocity * dt + 0.5 * accel * (dt * dt), velocity + accel * dt
    v = velocity.clamp(-v_max, v_max)
    v_end = (v + accel * dt).clamp(-v_max, v_max)
    safe_a = torch.where(accel == 0, torch.ones_like(accel), accel)
    tau = torch.where(accel == 0, torch.full_like(accel, dt), ((v_end - v) / safe_a).clamp(0.0, dt))
    return position + v * tau + 0.5 * accel * tau * tau + v_end * (dt - tau), v_end


@dataclass(frozen=True)
class DoubleIntegrator(AgentModel):
    """ṗ = v, v̇ = u, u ∈ [-u_max, u_max]^d, velocity components saturated to [-v_max, v_max].

    Bounds: scalars, or one per agent (:data:`~madpinn.dynamics.agent_model.Bound`). All methods
    broadcast over any leading batch shape ``[..., 2d]`` / ``[..., d]``. No defaults: the package
    builds it from ``agents`` (:meth:`madpinn.settings.AgentSettings.dynamics`).
    """

    u_max: Bound
    v_max: Bound

    name: ClassVar[str] = "double_integrator"
    position_dim: ClassVar[int] = 2
    control_dim: ClassVar[int] = 2
    state_dim: ClassVar[int] = 4

    def place(self, points: torch.Tensor) -> torch.Tensor:
        """Positions ``[..., d]`` (m) of points ``[..., 2]`` drawn by the planar scenario
        generators (:mod:`madpinn.scenarios`): the planar model takes them as they are."""
        return points

    def drift(self, state: torch.Tensor) -> torch.Tensor:
        """``w(s) = [v, 0]`` ``[..., 2d]``."""
        v = self.velocity(state)
        return torch.cat([v, torch.zeros_like(v)], dim=-1)

    def control_matrix(self) -> torch.Tensor:
        """``B = [0; I]`` ``[2d, d]``: the control is the acceleration."""
        d = self.position_dim
        return torch.cat([torch.zeros(d, d), torch.eye(d)], dim=0)

    def control_grad(self, grad: torch.Tensor) -> torch.Tensor:
        """``Bᵀ∇V = ∂V/∂v`` ``[..., d]``."""
        return self.velocity(grad)

    def f(self, state: torch.Tensor, u: torch.Tensor) -> torch.Tensor:
        """Continuous-time vector field ``[..., 2d]`` (no saturation)."""
        return torch.cat([self.velocity(state), self.clip_control(u)], dim=-1)

    def clip_state(self, state: torch.Tensor) -> torch.Tensor:
        """Velocities clipped to ±v_max (per agent where given)."""
        v = self.velocity(state)
        b = self.per_agent(self.v_max, v)
        return self.join(self.position(state), v.clamp(-b, b))

    def step(self, state: torch.Tensor, u: torch.Tensor, dt: float) -> torch.Tensor:
        """Exact zero-order-hold step over ``dt`` seconds with velocity saturation (:func:`hold_step`)."""
        if state.shape[-1] != self.state_dim or u.shape[-1] != self.control_dim:
            raise ValueError(f"expected state [...,{self.state_dim}] and control [...,{self.control_dim}], "
                             f"got {tuple(state.shape)} and {tuple(u.shape)}")
        p, v = hold_step(self.position(state), self.velocity(state), self.clip_control(u), dt,
                         self.per_agent(self.v_max, state))
        return self.join(p, v)
