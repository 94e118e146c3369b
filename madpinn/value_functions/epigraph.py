"""Decentralized (n+1)-agent epigraph system over the ego-centric observation plus z (SPEC §4).

Augmented state ``ô = [o, z]`` with ``o`` in the :mod:`madpinn.observation` layout
(``D = 2d + 3d·n``, d the agent model's position axes: 4 + 6n for the paper's planar model;
offsets relative to the ego position) and the cost budget ``z`` (cost units, m·s
for the running part plus m for the terminal part). Every agent is a double integrator
with ``u_a ∈ [-u_max, u_max]^d`` (a 3-D model's altitude band is not part of the system). In observation coordinates (ego at the origin)::

    d/dt v_ego            = u_0
    d/dt (g_ego − p_ego)  = −v_ego
    d/dt (p_j − p_ego)    = v_j − v_ego
    d/dt v_j              = u_j
    d/dt (g_j − p_ego)    = −v_ego
    d/dt z                = −l_d(o)

so ``f̂(ô, u) = w(ô) + B u`` with a control-free transport field ``w`` and controls entering only
the velocity coordinates. The Hamiltonian of the paper's HJB (``min_u ⟨∇V, f̂⟩``) is therefore
closed form: ``H = ⟨∇_o V, w_o⟩ − ∂_z V · l_d − u_max · Σ_a ‖∂V/∂v_a‖₁`` with the optimal
(bang-bang) control ``u_a* = −u_max · sign(∂V/∂v_a)``.

**Velocity saturation (option, ``velocity_saturation``; the paper's state constraint |v| ≤ v_max,
which the simulators enforce by clipping).** With it, a control that pushes a velocity
coordinate already at ``|v_a,k| ≥ v_max`` further out has no effect: per coordinate the control's
term in the Hamiltonian is ``−u_max·|p|`` inside, ``−u_max·max(p, 0)`` at ``v ≥ v_max`` and
``−u_max·max(−p, 0)`` at ``v ≤ −v_max`` (p = ∂V/∂v_a,k), and the optimal control there is 0 when
the bang-bang choice would point outward. Off by default: every trained V̂ so far used the
unbounded dynamics, and switching it on needs retraining.

Sampling domain (per coordinate, uniform; matches :class:`~madpinn.observation.ObservationSettings`):
velocities ``±v_max``, goal offsets ``±goal_range``, neighbour position offsets
``±offset_range``, ``z ∈ [0, z_max]``, ``t ∈ [0, T]``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import torch

from madpinn.dynamics.system import BoxControlSystem
from madpinn.observation import (
    ObservationSettings,
    constraint,
    running_cost,
    split_observation,
    terminal_cost,
)


@dataclass(frozen=True)
class EpigraphSystem(BoxControlSystem):
    """The augmented (n+1)-agent system of SPEC §4 and its box-control Hamiltonian.

    spec: observation layout and trained ranges; u_max, v_max: per-axis control (m/s²) and
    velocity (m/s) bounds; horizon: T (s); z_max: upper end of the sampled budget (cost units);
    velocity_saturation: controls pushing a velocity beyond ±v_max have no effect (module docstring).
    """

    spec: ObservationSettings
    u_max: float
    v_max: float
    horizon: float
    z_max: float
    velocity_saturation: bool

    control_mode = "min"   # the agents minimise the epigraph value (cost)
    control_ndim = 2       # one control per observed agent: [..., n+1, d]

    @property
    def control_bound(self) -> float:
        return self.u_max

    # ---- layout -------------------------------------------------------------------------
    @property
    def obs_dim(self) -> int:
        return self.spec.dim

    @property
    def state_dim(self) -> int:
        """Dimension of ô = [o, z]."""
        return self.spec.dim + 1

    def velocity_index(self) -> torch.Tensor:
        """Indices ``[n+1, d]`` of each agent's velocity inside the observation (built once, read-only)."""
        if "_velocity_index" not in self.__dict__:   # frozen dataclass: kept beside the fields
            self.__dict__["_velocity_index"] = self._build_velocity_index()
        return self.__dict__["_velocity_index"]

    def _build_velocity_index(self) -> torch.Tensor:
        lay = self.spec.layout
        ego = torch.arange(lay.ego_dim)[lay.ego_velocity]
        nbr = [lay.ego_dim + lay.neighbour_dim * j + torch.arange(lay.neighbour_dim)[lay.neighbour_velocity]
               for j in range(self.spec.n_neighbours)]
        return torch.stack([ego, *nbr])

    def half_widths(self) -> torch.Tensor:
        """Per-coordinate half width ``[D]`` of the symmetric observation domain (m, m/s)."""
        s, d = self.spec, self.spec.layout.d
        nbr = [s.offset_range] * d + [self.v_max] * d + [s.goal_range] * d
        return torch.tensor([self.v_max] * d + [s.goal_range] * d + nbr * s.n_neighbours, dtype=torch.float64)

    @staticmethod
    def default_z_max(spec: ObservationSettings, v_max: float, u_max: float, horizon: float) -> float:
        """Upper bound of the cost over the horizon on the sampled domain (cost units).

        Each agent's distance to its goal is at most its largest initial distance (ego:
        ``√d·goal_range``; neighbour: ``√d·(goal_range + offset_range)``) plus its largest
        displacement ``√d·(v_max·T + u_max·T²/2)``; the cost is ``(T + 1)`` times the sum.
        """
        diagonal = math.sqrt(float(spec.layout.d))   # per-coordinate bounds -> Euclidean
        move = diagonal * (v_max * horizon + 0.5 * u_max * horizon**2)
        ego = diagonal * spec.goal_range + move
        nbr = diagonal * (spec.goal_range + spec.offset_range) + move
        return (horizon + 1.0) * (ego + spec.n_neighbours * nbr)

    # ---- sampling -----------------------------------------------------------------------
    def sample(self, batch: int, generator: torch.Generator, dtype=torch.float32, device="cpu"):
        """Uniform samples ``(obs [B, D], z [B])`` over the training domain."""
        hw = self.half_widths().to(dtype)
        u = torch.rand(batch, self.obs_dim + 1, generator=generator, dtype=dtype)
        obs = (2.0 * u[:, :-1] - 1.0) * hw
        z = u[:, -1] * self.z_max
        return obs.to(device), z.to(device)

    # ---- costs, constraint, terminal condition ------------------------------------------
    def running_cost(self, obs: torch.Tensor) -> torch.Tensor:
        return running_cost(obs, self.spec.n_neighbours)

    def constraint(self, obs: torch.Tensor) -> torch.Tensor:
        return constraint(obs, self.spec.n_neighbours, self.spec.collision_radius)

    def terminal_parts(self, obs: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """``(φ_d(o), g_d(o))`` ``[B]`` each: the z-independent parts of :meth:`terminal_value`."""
        return terminal_cost(obs, self.spec.n_neighbours), self.constraint(obs)

    def terminal_value(self, obs: torch.Tensor, z: torch.Tensor) -> torch.Tensor:
        """``max(φ_d(o) − z, g_d(o))`` ``[B]``: the exact terminal condition of V̂."""
        phi, g = self.terminal_parts(obs)
        return torch.maximum(phi - z, g)

    def terminal_value_and_grad(self, obs: torch.Tensor, z: torch.Tensor):
        """Terminal value ``[B]`` and its gradients ``(∂/∂o [B, D], ∂/∂z [B])`` (exact, a.e.)."""
        with torch.enable_grad():
            o = obs.detach().requires_grad_(True)
            zz = z.detach().requires_grad_(True)
            val = self.terminal_value(o, zz)
            go, gz = torch.autograd.grad(val.sum(), [o, zz])
        return val.detach(), go, gz

    # ---- dynamics and Hamiltonian -------------------------------------------------------
    def transport(self, obs: torch.Tensor) -> torch.Tensor:
        """Control-free part ``w_o(o)`` ``[B, D]`` of the observation dynamics."""
        p, v, _ = split_observation(obs, self.spec.n_neighbours)
        v_ego = v[..., 0:1, :]
        lead = obs.shape[:-1]
        n = self.spec.n_neighbours
        ego = torch.cat([torch.zeros_like(v_ego[..., 0, :]), -v_ego[..., 0, :]], dim=-1)
        nbr = torch.cat([v[..., 1:, :] - v_ego, torch.zeros_like(v[..., 1:, :]), (-v_ego).expand(*lead, n, v.shape[-1])], dim=-1)
        return torch.cat([ego, nbr.flatten(-2)], dim=-1)

    def f(self, obs: torch.Tensor, z: torch.Tensor, u: torch.Tensor):
        """Augmented vector field for agent controls ``u [B, n+1, d]`` (clipped to the box):
        returns ``(d obs/dt [B, D], dz/dt [B])``."""
        u = u.clamp(-self.u_max, self.u_max)
        do = self.transport(obs).clone()
        idx = self.velocity_index().to(obs.device)
        if self.velocity_saturation:
            u = torch.where(self._outward(obs[..., idx], u), torch.zeros_like(u), u)
        do[..., idx.flatten()] = do[..., idx.flatten()] + u.flatten(-2)
        return do, -self.running_cost(obs)

    def velocity_grad(self, dv_dobs: torch.Tensor) -> torch.Tensor:
        """``∂V/∂v_a`` ``[B, n+1, d]`` from the observation gradient ``[B, D]``."""
        idx = self.velocity_index().to(dv_dobs.device)
        return dv_dobs[..., idx]

    control_grad = velocity_grad   # the controls enter the observed agents' velocities

    def _outward(self, v: torch.Tensor, u: torch.Tensor) -> torch.Tensor:
        """Where control ``u`` pushes velocity ``v`` (both ``[..., n+1, d]``) beyond ±v_max."""
        return ((v >= self.v_max) & (u > 0)) | ((v <= -self.v_max) & (u < 0))

    def hamiltonian(self, obs: torch.Tensor, dv_dobs: torch.Tensor, dv_dz: torch.Tensor) -> torch.Tensor:
        """``min_u ⟨∇V, f̂(ô, u)⟩`` ``[B]`` in closed form for box controls (derived from the box,
        :class:`~madpinn.dynamics.system.BoxControlSystem`); with ``velocity_saturation`` a control
        that would push a saturated velocity further out contributes nothing."""
        drift = (dv_dobs * self.transport(obs)).sum(-1) - dv_dz * self.running_cost(obs)
        if not self.velocity_saturation:
            return self.hamiltonian_from(drift, dv_dobs)
        p = self.velocity_grad(dv_dobs)
        u_star = -self.u_max * torch.sign(p)
        effective = torch.where(self._outward(obs[..., self.velocity_index().to(obs.device)], u_star), torch.zeros_like(p), p.abs())
        return drift - self.u_max * effective.sum((-1, -2))

    def optimal_control(self, dv_dobs: torch.Tensor, obs: torch.Tensor | None = None) -> torch.Tensor:
        """Bang-bang minimiser ``−u_max·sign(∂V/∂v_a)`` for every observed agent ``[B, n+1, d]``;
        with ``velocity_saturation`` (``obs`` then required) 0 where it would push a saturated
        velocity further out."""
        return self.velocity_control(self.velocity_grad(dv_dobs), obs)

    def velocity_control(self, dv_dv: torch.Tensor, obs: torch.Tensor | None = None) -> torch.Tensor:
        """:meth:`optimal_control` from the velocity block ``∂V/∂v_a [B, n+1, d]`` of the gradient
        (:meth:`velocity_grad`) alone."""
        u = self.bang_bang(dv_dv)
        if self.velocity_saturation:
            if obs is None:
                raise ValueError("optimal_control needs the observation when velocity_saturation is on")
            u = torch.where(self._outward(obs[..., self.velocity_index().to(obs.device)], u), torch.zeros_like(u), u)
        return u

    def hjb_residual(self, obs, z, value, dv_dt, dv_dobs, dv_dz) -> torch.Tensor:
        """Paper eq. (loss): ``min(−∂_t V − H, V − g_d(o))`` ``[B]``."""
        return torch.minimum(-dv_dt - self.hamiltonian(obs, dv_dobs, dv_dz), value - self.constraint(obs))

    @classmethod
    def from_config(cls, cfg: dict) -> "EpigraphSystem":
        spec = ObservationSettings.from_config(cfg).base_mapping()
        vcfg = cfg["value_functions"]["vhat"]
        u_max, v_max, T = float(cfg["agents"]["u_max"]), float(cfg["agents"]["v_max"]), float(vcfg["horizon"])
        z_max = vcfg["z_max"]
        z_max = cls.default_z_max(spec, v_max, u_max, T) if z_max == "auto" else float(z_max)
        return cls(spec=spec, u_max=u_max, v_max=v_max, horizon=T, z_max=z_max,
                   velocity_saturation=bool(vcfg["velocity_saturation"]))
