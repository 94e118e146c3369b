"""Control-barrier value-function (CBVF) safety filter on the learned pairwise safety value V_s.

Per agent i, every policy step:

1. Candidates: the ``candidates`` nearest agents inside the sensing radius; their relative
   states ``x_ij = [p_i − p_j, v_i − v_j]`` and ``V_s(x_ij)`` (m, larger = safer).
2. The ``critical_neighbours`` lowest-V_s candidates give one constraint row each,
   ``∇V_s·f(x_ij, u_i) + γ·V_s ≥ 0`` with the relative dynamics ``f = [v_i − v_j, u_i − u_j]`` in
   which the neighbour's control is taken as ``u_j = 0`` (agent i cannot know it; each agent of a
   pair filters its own control, so both contribute): ``∇_v V_s·u_i ≥ −γ·V_s − ∇_p V_s·(v_i − v_j)``.
3. ``u_i = argmin ‖u − u_nom‖²`` over the control box subject to those rows — solved exactly by
   :func:`madpinn.policies.cbvf_qp.solve_box_qp`, all agents in one batch.
4. If the QP is infeasible, or the smallest V_s is below ``threshold``, the V_s-optimal (safest)
   control against the most critical neighbour: ``u_max·sign(∂V_s/∂v)`` per axis.

Without neighbours in the sensing radius the nominal control passes unchanged.

Two settings give the authors' filter design (Layered-Safe-MARL, Choi, Aloor, Li et al. 2025;
run ``safemarl-layered``, docs/reference/marl.md), together with ``critical_neighbours = 1``:

- ``neighbour_control = "joint"``: each row is agent i's share of the pair's *joint* QP
  ``min ‖u_i − û_i‖² + ‖u_j − û_j‖²  s.t.  a·(u_i − u_j) ≥ b`` around both nominal controls
  (û_j: the neighbour's nominal control, computed by every agent before filtering). Its unboxed
  solution moves each agent by half the correction, so agent i's row becomes
  ``a·u_i ≥ (b + a·(û_i + û_j))/2``; it is then solved with the box like any other row (the
  authors solve the joint QP unboxed and clip afterwards). ``"zero"``: ``u_j = 0`` as above.
- ``coordination_range``: the filter acts only when the nearest neighbour is within this
  distance (m); otherwise the nominal control passes (``None``: the sensing radius). Used by SafeMARL
(:mod:`madpinn.policies.safemarl`, nominal = MARL actor) and by the ``safety_filter`` option of
MAD-PINN (:mod:`madpinn.policies.madpinn`, nominal = the MAD-PINN policy; not in the paper).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping

import torch

from madpinn.observation import gather_agents, nearest_neighbours
from madpinn.policies.base import Policy
from madpinn.policies.cbvf_qp import solve_box_qp


@dataclass
class FilterStats:
    """Counts over all agent-steps: filtered (QP changed u), fallback (safest control)."""

    steps: int = 0
    active: int = 0
    fallback: int = 0


class CBVFFilter:
    """Batched per-agent CBVF safety filter on a pairwise value ``vs`` with ``value(x [B,4]) -> [B]``
    and ``value_and_grad(x [B,4]) -> (V [B], dV/dx [B,4])``."""

    NEIGHBOUR_CONTROLS = ("zero", "joint")

    def __init__(self, vs, u_max: float, gamma: float, critical: int, candidates: int, threshold: float, sensing_radius: float,
                 neighbour_control: str = "zero", coordination_range: float | None = None):
        if not isinstance(u_max, (int, float)):   # its QP and fallback hold one box; V_s is trained for one u_max
            raise ValueError(f"the CBVF filter needs one u_max for all agents, got {u_max}")
        if critical > candidates:
            raise ValueError(f"critical_neighbours ({critical}) must not exceed candidates ({candidates})")
        if neighbour_control not in self.NEIGHBOUR_CONTROLS:
            raise ValueError(f"neighbour_control must be one of {self.NEIGHBOUR_CONTROLS}, got {neighbour_control!r}")
        if coordination_range is not None and not 0.0 < coordination_range <= sensing_radius:
            raise ValueError(f"coordination_range ({coordination_range} m) must be in (0, sensing radius {sensing_radius} m]: "
                             "agents cannot coordinate with neighbours they do not sense")
        self.vs = vs
        self.u_max = float(u_max)
        self.gamma = float(gamma)
        self.critical = int(critical)
        self.candidates = int(candidates)
        self.threshold = float(threshold)
        self.sensing_radius = float(sensing_radius)
        self.neighbour_control = neighbour_control
        self.coordination_range = None if coordination_range is None else float(coordination_range)
        self.stats = FilterStats()

    def constraint_rows(self, state: torch.Tensor, u_nom: torch.Tensor | None = None):
        """state ``[S, N, 2d]`` (V_s's agent model's layout; and, for ``neighbour_control = "joint"``,
        the clipped nominal controls ``u_nom [S, N, d]`` of all agents) -> ``a [S, N, k, d]``,
        ``b [S, N, k]``, ``active [S, N, k]``, ``V [S, N, k]``, ``dV/dv [S, N, k, d]``, rows sorted by increasing V_s (most critical first);
        ``active`` is False for empty slots and for every row of an agent gated by ``coordination_range``."""
        S, N, n = state.shape
        agent = self.vs.system.agent
        if n != agent.state_dim:
            raise ValueError(f"state must be [S, N, {agent.state_dim}] (V_s's {agent.name}), got {tuple(state.shape)}")
        idx = nearest_neighbours(agent.position(state), self.candidates, radius=self.sensing_radius)  # [S, N, C]
        real = idx >= 0
        x_rel = state.unsqueeze(2) - gather_agents(state, idx.clamp_min(0))  # [S, N, C, 2d]
        if self.coordination_range is not None:  # gate on the nearest neighbour's distance
            dist = agent.position(x_rel).norm(dim=-1).masked_fill(~real, float("inf"))
            real = real & (dist.amin(-1, keepdim=True) <= self.coordination_range)
        C = idx.shape[-1]
        v_all = self.vs.value(x_rel.reshape(-1, n), t=0.0, reuse_buffers=True).reshape(S, N, C)   # bitwise as without
        v_all = v_all.masked_fill(~real, float("inf"))
        k = min(self.critical, C)
        _, order = torch.topk(v_all, k, dim=-1, largest=False)  # [S, N, k]
        active = torch.gather(real, 2, order)
        x_k = torch.gather(x_rel, 2, order.unsqueeze(-1).expand(S, N, k, n))
        V, dV = self.vs.value_and_grad(x_k.reshape(-1, n), t=0.0, reuse_buffers=True)
        V = V.reshape(S, N, k).to(state.dtype)
        dV = dV.reshape(S, N, k, n).to(state.dtype)
        a = agent.velocity(dV)                                       # Bᵀ∇V_s: u_i enters v_i
        b = -self.gamma * V - (agent.position(dV) * agent.velocity(x_k)).sum(-1)   # −γV − ⟨∇V_s, w(x)⟩
        if self.neighbour_control == "joint":
            if u_nom is None:
                raise ValueError("neighbour_control 'joint' needs the nominal controls u_nom [S, N, d] of all agents")
            j = torch.gather(idx.clamp_min(0), 2, order)  # [S, N, k] neighbour indices
            u_j = gather_agents(u_nom, j).to(state.dtype)  # [S, N, k, d]
            b = 0.5 * (b + (a * (u_nom.unsqueeze(2).to(state.dtype) + u_j)).sum(-1))
        return a, b, active, V, a

    def __call__(self, state: torch.Tensor, u_nom: torch.Tensor) -> torch.Tensor:
        """state ``[S, N, 2d]``, nominal controls ``[S, N, d]`` -> filtered controls ``[S, N, d]`` (in the box)."""
        S, N, _ = state.shape
        u_nom = u_nom.clamp(-self.u_max, self.u_max)
        if N < 2:
            return u_nom
        a, b, active, V, grad_v = self.constraint_rows(state, u_nom)
        k = a.shape[2]
        m = self.vs.system.agent.control_dim
        u, feasible = solve_box_qp(u_nom.reshape(-1, m), a.reshape(-1, k, m), b.reshape(-1, k), self.u_max, active.reshape(-1, k))
        u, feasible = u.reshape(S, N, m), feasible.reshape(S, N)
        any_nbr = active[..., 0]
        safest = self.u_max * torch.sign(grad_v[..., 0, :])
        fallback = any_nbr & (~feasible | (V[..., 0] < self.threshold))
        u = torch.where(fallback.unsqueeze(-1), safest, u)
        self.stats.steps += S * N
        self.stats.active += int(((u - u_nom).abs().amax(-1) > 1e-6).sum())
        self.stats.fallback += int(fallback.sum())
        return u


class SafetyFilteredPolicy:
    """Any nominal :class:`Policy` followed by a :class:`CBVFFilter` (``None``: unfiltered)."""

    def __init__(self, nominal: Policy, safety_filter: CBVFFilter | None):
        self.nominal = nominal
        self.filter = safety_filter

    def reset(self, state: torch.Tensor, goals: torch.Tensor) -> None:
        self.nominal.reset(state, goals)

    def act(self, state: torch.Tensor, goals: torch.Tensor, t: float) -> torch.Tensor:
        u = self.nominal.act(state, goals, t)
        return u if self.filter is None else self.filter(state, u)


@dataclass(frozen=True)
class CBVFSettings:
    """A CBVF filter block (``methods.safemarl``, ``methods.madpinn.safety_filter``)."""

    gamma: float
    """γ (1/s) in ∇V_s·f + γ·V_s ≥ 0 (``cbvf_gamma``)"""
    critical_neighbours: int
    """QP rows: the neighbours with the lowest V_s"""
    candidates: int
    """nearest neighbours inside the sensing radius whose V_s is evaluated"""
    threshold: float
    """V_s below it (m): the V_s-optimal (safest) control instead of the QP"""
    neighbour_control: str
    """the neighbour's control in each row: ``zero`` (u_j = 0, agent i corrects alone) or ``joint``
    (agent i's share of the pair's joint QP around both nominal controls, Layered-Safe-MARL)"""
    coordination_range: float | None
    """m; filter only when the nearest neighbour is this close (None: the sensing radius)"""

    @classmethod
    def from_config(cls, block: Mapping) -> "CBVFSettings":
        rng = block["coordination_range"]
        return cls(gamma=float(block["cbvf_gamma"]), critical_neighbours=int(block["critical_neighbours"]),
                   candidates=int(block["candidates"]), threshold=float(block["threshold"]),
                   neighbour_control=str(block["neighbour_control"]), coordination_range=None if rng is None else float(rng))


def make_cbvf_filter(vs, params: CBVFSettings, u_max: float, sensing_radius: float) -> CBVFFilter:
    """A :class:`CBVFFilter` on ``vs`` from its settings."""
    return CBVFFilter(vs, u_max=u_max, gamma=params.gamma, critical=params.critical_neighbours,
                      candidates=params.candidates, threshold=params.threshold, sensing_radius=sensing_radius,
                      neighbour_control=params.neighbour_control, coordination_range=params.coordination_range)
