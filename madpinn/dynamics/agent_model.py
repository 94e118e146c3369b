"""The agent-model interface: one agent's state, control, bounds, vector field and exact step.

In the style of hj_reachability's ``Dynamics``: a model states its layout (state and control
sizes, where position and velocity live), its control-affine vector field ``f(s, u) = w(s) + B u``
(drift ``w``, control Jacobian ``B``) and its bounds; the Hamiltonian and the optimal control
follow once from :class:`~madpinn.dynamics.system.BoxControlSystem`. Everything planar in the
package (the ego-centric observation, the pair system, the epigraph system, the CBVF row, the
look-ahead, the oracle, the verification) derives its sizes and offsets from a model's layout.

Bounds are per agent where given: a scalar holds for every agent, a sequence of ``N`` values
gives agent ``i`` its own bound and broadcasts over states ``[..., N, state_dim]``
(:meth:`AgentModel.per_agent`).

Adding a model: one module in this package with a frozen dataclass implementing this class
(``name``, ``position_dim``, ``drift``, ``control_matrix``, ``step``, ``clip_state``, ``place``),
and its name in the schema's ``$defs.agent_model`` (with the methods that fly it). Nothing lists
it: a class that states its own ``name`` registers itself when it is defined
(:meth:`AgentModel.__init_subclass__`), and the package imports every one of its modules
(:data:`madpinn.dynamics.MODELS`); docs/reference/architecture.md counts the touch points.
"""

from __future__ import annotations

from typing import ClassVar, Sequence

import torch

from madpinn.dynamics.system import BoxControlSystem

Bound = float | Sequence[float]
"""A bound for every agent (scalar) or one per agent (sequence of N values)."""


def pair_threshold(radius: Bound, like: torch.Tensor) -> float | torch.Tensor:
    """Collision threshold of agent pairs from the agents' collision radii (m): a scalar unchanged,
    per-agent radii ``r [N]`` as ``(r_i + r_j)/2`` ``[N, N]`` (equal radii give r), broadcasting
    over distances ``like`` ``[..., N, N]``."""
    if isinstance(radius, (int, float)):
        return float(radius)
    r = torch.as_tensor(radius, dtype=like.dtype, device=like.device)
    return 0.5 * (r[:, None] + r[None, :])


_REGISTERED: dict[str, type["AgentModel"]] = {}
"""agent models by name, each added when its class is defined (:meth:`AgentModel.__init_subclass__`)"""


def model_class(name: str) -> type["AgentModel"]:
    """The agent model named ``name`` (a clear error for an unknown one)."""
    if name not in _REGISTERED:
        raise ValueError(f"unknown agent model {name!r}; known: {sorted(_REGISTERED)}")
    return _REGISTERED[name]


def registered_models() -> dict[str, type["AgentModel"]]:
    """Every agent model defined so far, by name (:data:`madpinn.dynamics.MODELS` once the
    package has imported its modules)."""
    return dict(sorted(_REGISTERED.items()))


class AgentModel(BoxControlSystem):
    """One agent's dynamics, vectorised over any leading batch shape (scenarios, agents).

    State ``[..., state_dim]`` = ``[position (position_dim), velocity (position_dim), …]`` (m, m/s),
    control ``[..., control_dim]`` entering the velocity (m/s²). The control maximises nothing
    of its own: ``control_mode`` is "min" (a value the agent minimises, e.g. its cost).
    """

    name: ClassVar[str]
    """the model's name in :data:`madpinn.dynamics.MODELS` and in ``agents.model``"""
    position_dim: ClassVar[int]
    """d: position coordinates (m); the velocity has d coordinates (m/s) right after them"""
    control_dim: ClassVar[int]
    """m: control coordinates (m/s²)"""
    state_dim: ClassVar[int]
    """n: state coordinates"""
    control_mode = "min"

    u_max: Bound
    v_max: Bound

    def __init_subclass__(cls, **kwargs):
        """A subclass that states its own ``name`` is a model of its own: registered under it
        (two classes of one name are refused)."""
        super().__init_subclass__(**kwargs)
        if "name" in vars(cls):
            if cls.name in _REGISTERED and _REGISTERED[cls.name] is not cls:
                raise ValueError(f"two agent models are named {cls.name!r}: {_REGISTERED[cls.name].__module__} and {cls.__module__}")
            _REGISTERED[cls.name] = cls

    # ---- layout ---------------------------------------------------------------------------
    @classmethod
    def position_slice(cls) -> slice:
        return slice(0, cls.position_dim)

    @classmethod
    def velocity_slice(cls) -> slice:
        return slice(cls.position_dim, 2 * cls.position_dim)

    @classmethod
    def position(cls, state: torch.Tensor) -> torch.Tensor:
        """Positions ``[..., d]`` (m) of states ``[..., n]``."""
        return state[..., cls.position_slice()]

    @classmethod
    def velocity(cls, state: torch.Tensor) -> torch.Tensor:
        """Velocities ``[..., d]`` (m/s) of states ``[..., n]``."""
        return state[..., cls.velocity_slice()]

    @classmethod
    def join(cls, position: torch.Tensor, velocity: torch.Tensor) -> torch.Tensor:
        """States ``[..., n]`` from positions and velocities ``[..., d]`` each."""
        return torch.cat([position, velocity], dim=-1)

    def place(self, points: torch.Tensor) -> torch.Tensor:
        """Positions ``[..., d]`` (m) of the points ``[..., 2]`` the planar scenario generators draw
        (starts and goals of :mod:`madpinn.scenarios`; a 3-D model lifts them into its space)."""
        raise NotImplementedError

    # ---- bounds ---------------------------------------------------------------------------
    @staticmethod
    def per_agent(bound: Bound, like: torch.Tensor) -> float | torch.Tensor:
        """``bound`` as it broadcasts over ``like`` ``[..., N, k]``: a float unchanged, a sequence of
        N values as a tensor ``[N, 1]`` (agent i's bound on every coordinate of agent i)."""
        if isinstance(bound, (int, float)):
            return float(bound)
        return torch.as_tensor(bound, dtype=like.dtype, device=like.device)[:, None]

    def require_uniform_bounds(self, user: str) -> None:
        """Raise for per-agent bounds where ``user`` (a policy, a backend) holds one box for all agents."""
        if not all(isinstance(b, (int, float)) for b in (self.u_max, self.v_max)):
            raise ValueError(f"{user} needs one u_max and v_max for all agents, got u_max={self.u_max}, v_max={self.v_max}")

    @property
    def control_bound(self) -> float:
        """ū of :class:`BoxControlSystem` (a scalar bound; per-agent bounds clip in :meth:`clip_control`)."""
        return self.u_max

    def clip_control(self, u: torch.Tensor) -> torch.Tensor:
        """Controls ``[..., N, m]`` clipped to each agent's box ``[-u_max, u_max]^m``."""
        b = self.per_agent(self.u_max, u)
        return u.clamp(-b, b)

    # ---- vector field ---------------------------------------------------------------------
    def drift(self, state: torch.Tensor) -> torch.Tensor:
        """Control-free part ``w(s)`` ``[..., n]``."""
        raise NotImplementedError

    def control_matrix(self) -> torch.Tensor:
        """Control Jacobian ``B`` ``[n, m]`` (constant)."""
        raise NotImplementedError

    def f(self, state: torch.Tensor, u: torch.Tensor) -> torch.Tensor:
        """Vector field ``w(s) + B·clip(u)`` ``[..., n]`` (no state clipping)."""
        return self.drift(state) + self.clip_control(u) @ self.control_matrix().to(u).T

    def control_grad(self, grad: torch.Tensor) -> torch.Tensor:
        """``Bᵀ∇V`` ``[..., m]`` of a value gradient ``[..., n]``."""
        return grad @ self.control_matrix().to(grad)

    def hamiltonian(self, state: torch.Tensor, grad: torch.Tensor) -> torch.Tensor:
        """``min_u ⟨∇V, f(s, u)⟩`` ``[...]`` (derived from the box)."""
        return self.hamiltonian_from((grad * self.drift(state)).sum(-1), grad)

    # ---- integration ----------------------------------------------------------------------
    def clip_state(self, state: torch.Tensor) -> torch.Tensor:
        """States ``[..., N, n]`` projected onto the admissible set (e.g. velocity bounds)."""
        raise NotImplementedError

    def step(self, state: torch.Tensor, u: torch.Tensor, dt: float) -> torch.Tensor:
        """Exact step over ``dt`` s under the held control ``u`` ``[..., m]``, bounds enforced."""
        raise NotImplementedError
