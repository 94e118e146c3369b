"""Relative pair system for the pairwise safety value V_s (SPEC §5).

State ``x = [p_i − p_j, v_i − v_j]`` ``[..., 2d]`` (m, m/s; d the agent model's position axes, 2
for the paper's planar model); the pair cooperates through the relative control
``u = u_i − u_j ∈ [−2u_max, 2u_max]^d``: ``ṗ = v``, ``v̇ = u``.
Target ``ψ(x) = ‖p‖ − r`` (m, ≤ 0 is collision). ``V_s(x, t) = sup_u min_{τ∈[t,T]} ψ(ξ(τ))``
solves the HJB-VI ``min{∂_t V + H_s, ψ − V} = 0``, ``V(x, T) = ψ(x)``, with the closed-form
Hamiltonian ``H_s = max_u ⟨∇V, f⟩ = ⟨∂_p V, v⟩ + 2u_max·‖∂_v V‖₁`` and the optimal relative
control ``2u_max·sign(∂_v V)`` (agent i applies ``u_max·sign``, agent j the opposite).
Training domain: ``|p| ≤ p_range``, ``|v| ≤ v_range`` per axis, ``t ∈ [0, T]``.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch

from madpinn.dynamics.agent_model import AgentModel, model_class
from madpinn.dynamics.double_integrator import hold_step
from madpinn.dynamics.system import BoxControlSystem


@dataclass(frozen=True)
class PairSystem(BoxControlSystem):
    """The relative state ``x = [p_i − p_j, v_i − v_j]`` of two agents of ``model`` (a name of
    :data:`~madpinn.dynamics.MODELS`; its layout, a double integrator's): u_max (m/s²) per axis and
    agent, collision_radius r (m), horizon T (s), sampled box ``|p| ≤ p_range``, ``|v| ≤ v_range``
    (m, m/s). No defaults: :meth:`from_config` reads ``agents`` and ``value_functions.vs``. A 3-D
    model's altitude band is not part of the pair system (relative states; V_s ignores the band)."""

    model: str
    u_max: float
    collision_radius: float
    horizon: float
    p_range: float
    v_range: float

    control_mode = "max"   # the pair maximises its safety margin

    def __post_init__(self):
        model_class(self.model)   # an unknown model fails here

    @property
    def agent(self) -> type[AgentModel]:
        """The agents' model class: the pair state has its layout."""
        return model_class(self.model)

    @property
    def control_bound(self) -> float:
        return self.u_rel_max

    def control_grad(self, dv_dx: torch.Tensor) -> torch.Tensor:
        """``∂V/∂v`` ``[..., d]``: the relative control enters the relative velocity."""
        return self.agent.velocity(dv_dx)

    @property
    def state_dim(self) -> int:
        return self.agent.state_dim

    @property
    def u_rel_max(self) -> float:
        """Bound of the relative control per axis (m/s²)."""
        return 2.0 * self.u_max

    def half_widths(self) -> torch.Tensor:
        d = self.agent.position_dim
        return torch.tensor([self.p_range] * d + [self.v_range] * d, dtype=torch.float64)

    def sample(self, batch: int, generator: torch.Generator, dtype=torch.float32, device="cpu") -> torch.Tensor:
        u = torch.rand(batch, self.state_dim, generator=generator, dtype=dtype)
        return ((2.0 * u - 1.0) * self.half_widths().to(dtype)).to(device)

    def target(self, x: torch.Tensor) -> torch.Tensor:
        """ψ(x) = ‖p‖ − r ``[...]`` (m)."""
        return torch.linalg.vector_norm(self.agent.position(x), dim=-1) - self.collision_radius

    def target_and_grad(self, x: torch.Tensor):
        """ψ ``[B]`` and ∂ψ/∂x ``[B, 2d]`` (exact away from p = 0)."""
        p = self.agent.position(x)
        norm = torch.linalg.vector_norm(p, dim=-1, keepdim=True)
        grad_p = p / norm.clamp_min(1e-12)
        return norm[..., 0] - self.collision_radius, torch.cat([grad_p, torch.zeros_like(p)], dim=-1)

    def free_drift_and_grad(self, x: torch.Tensor, remaining: float | torch.Tensor):
        """:func:`free_drift_and_grad` of this system's collision radius."""
        return free_drift_and_grad(x, remaining, self.collision_radius, self.agent)

    def f(self, x: torch.Tensor, u: torch.Tensor) -> torch.Tensor:
        """Vector field ``[..., 2d]`` for the relative control ``u [..., d]`` (clipped to ±2u_max)."""
        a = self.agent
        return a.join(a.velocity(x), u.clamp(-self.u_rel_max, self.u_rel_max))

    def hamiltonian(self, x: torch.Tensor, dv_dx: torch.Tensor) -> torch.Tensor:
        """``max_u ⟨∇V, f(x, u)⟩`` ``[B]``; the maximising (safest) relative control
        ``2u_max·sign(∂V/∂v)`` ``[B, d]`` is :meth:`optimal_control` (from the box)."""
        a = self.agent
        return self.hamiltonian_from((a.position(dv_dx) * a.velocity(x)).sum(-1), dv_dx)

    def hjb_residual(self, x, value, dv_dt, dv_dx) -> torch.Tensor:
        """Paper eq. (HJI-VI): ``min{∂_t V + H_s, ψ − V}`` ``[B]``."""
        return torch.minimum(dv_dt + self.hamiltonian(x, dv_dx), self.target(x) - value)

    def step(self, x: torch.Tensor, u: torch.Tensor, dt: float) -> torch.Tensor:
        """Exact zero-order-hold step of the relative double integrator (:func:`hold_step`, no saturation)."""
        a = self.agent
        return a.join(*hold_step(a.position(x), a.velocity(x), u.clamp(-self.u_rel_max, self.u_rel_max), dt))

    @classmethod
    def from_config(cls, cfg: dict) -> "PairSystem":
        v = cfg["value_functions"]["vs"]
        return cls(
            model=str(cfg["agents"]["model"]), u_max=float(cfg["agents"]["u_max"]), collision_radius=float(cfg["agents"]["collision_radius"]),
            horizon=float(v["horizon"]), p_range=float(v["p_range"]), v_range=float(v["v_range"]),
        )


def closest_free_drift_offset(x: torch.Tensor, remaining: float | torch.Tensor, agent: type[AgentModel]):
    """``(p + v·τ* [B, d], τ* [B])``: the closest relative offset of pair states ``x [B, 2d]`` drifting
    without control over ``τ ∈ [0, T']`` (``T'`` = ``remaining``, s) and its time."""
    p, v = agent.position(x), agent.velocity(x)
    tau = (-(p * v).sum(-1) / (v * v).sum(-1).clamp_min(1e-12)).clamp(min=0.0)
    tau = torch.minimum(tau, torch.as_tensor(remaining, dtype=x.dtype, device=x.device).expand_as(tau))
    return p + v * tau[..., None], tau


def free_drift_and_grad(x: torch.Tensor, remaining: float | torch.Tensor, radius: float, agent: type[AgentModel]):
    """``min_{τ∈[0, T']} ‖p + v·τ‖ − r`` ``[B]`` and its gradient ``[B, 2d]`` for pair states
    ``x [B, 2d]`` of agents of model ``agent`` over the remaining horizon ``T'`` (s): the safety margin with no relative
    control, a lower bound of the exact V_s (which maximises over controls); ``≤ ψ`` (τ = 0).
    Gradient by the envelope theorem at the minimiser τ*: ``(u, τ*·u)``, u the unit closest offset."""
    d, tau = closest_free_drift_offset(x, remaining, agent)
    norm = torch.linalg.vector_norm(d, dim=-1, keepdim=True)
    u = d / norm.clamp_min(1e-12)
    return norm[..., 0] - radius, torch.cat([u, tau[..., None] * u], dim=-1)
