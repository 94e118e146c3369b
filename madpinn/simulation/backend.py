"""Simulation backends. Every backend steps all scenarios × agents at once and exposes the
state ``[S, N, 2d]`` of its agent model ``dynamics`` (planar: ``[x, y, vx, vy]``, m, m/s) after
each simulation step of ``dt`` s.

Protocol (see :class:`SimBackend`): ``reset(starts, velocities)`` -> state; ``command(accel,
duration)`` sets the policy acceleration ``[S, N, d]`` (m/s²) held for ``duration`` s (one policy
step); ``step()`` advances ``dt`` and returns the new state.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Protocol

import torch

from madpinn.dynamics import AgentModel
from madpinn.observation import pairwise_distances
from madpinn.settings import AgentSettings

if TYPE_CHECKING:
    from madpinn.simulation.settings import SimSettings


class SimBackend(Protocol):
    dt: float
    dynamics: AgentModel
    """the agents' model: the layout of the states the backend returns"""

    def reset(self, positions: torch.Tensor, velocities: torch.Tensor) -> torch.Tensor: ...

    def command(self, accel: torch.Tensor, duration: float) -> None: ...

    def step(self) -> torch.Tensor: ...


class DoubleIntegratorBackend:
    """Exact batched double-integrator dynamics (SPEC §7 ``double_integrator``).

    ``freeze_radius`` (m; ``sim.contacts``): an agent that comes within it of another agent of its
    scenario stops there (velocity 0) for the rest of the episode and stays an obstacle, the
    planar analogue of a drone knocked out by a contact. None: agents pass through each other.
    """

    def __init__(self, dynamics: AgentModel, dt: float, freeze_radius: float | None = None):
        self.dynamics = dynamics
        self.dt = float(dt)
        self.freeze_radius = None if freeze_radius is None else float(freeze_radius)
        self.state: torch.Tensor | None = None
        self._accel: torch.Tensor | None = None
        self.frozen: torch.Tensor | None = None
        """``[S, N]`` bool: agents stopped by a collision (all False without ``freeze_radius``)"""

    def reset(self, positions: torch.Tensor, velocities: torch.Tensor) -> torch.Tensor:
        self.state = self.dynamics.join(positions, velocities)
        self._accel = torch.zeros_like(positions)
        self.frozen = torch.zeros(positions.shape[:-1], dtype=torch.bool, device=positions.device)
        self._freeze_new()
        return self.state

    def command(self, accel: torch.Tensor, duration: float) -> None:
        if self.state is None:
            raise RuntimeError("reset() before command()")
        shape = self.state.shape[:-1] + (self.dynamics.control_dim,)
        if accel.shape != shape:
            raise ValueError(f"accel must be {tuple(shape)}, got {tuple(accel.shape)}")
        if not torch.isfinite(accel).all():
            raise ValueError("non-finite acceleration command")
        self._accel = self.dynamics.clip_control(accel)

    def step(self) -> torch.Tensor:
        moved = self.dynamics.step(self.state, self._accel, self.dt)
        if self.freeze_radius is None:
            self.state = moved
            return moved
        self.state = torch.where(self.frozen[..., None], self.state, moved)
        self._freeze_new()
        return self.state

    def _freeze_new(self) -> None:
        """Stop the agents that are now within ``freeze_radius`` of another (at their current position)."""
        if self.freeze_radius is None or self.state.shape[1] < 2:
            return
        hit = pairwise_distances(self.dynamics.position(self.state)).amin(dim=-1) <= self.freeze_radius
        new = hit & ~self.frozen
        if new.any():
            p, v = self.dynamics.position(self.state), self.dynamics.velocity(self.state)
            self.state = self.dynamics.join(p, torch.where(new[..., None], 0.0, v))
            self.frozen |= new


BACKEND_MODULES = {"mujoco": "madpinn.simulation.mujoco"}
"""backends in their own package: name -> the module whose ``make_backend(sim, limits, device,
dtype)`` builds it, imported by name when a cell asks for it. The module does not import this one:
the two import one way (``tests/test_import_graph.py``)."""


def _make_double_integrator(sim: SimSettings, limits: AgentSettings, device, dtype):
    return DoubleIntegratorBackend(limits.dynamics(), dt=sim.dt,
                                   freeze_radius=limits.collision_radius if sim.contacts else None)


def make_backend(name: str, sim: SimSettings, limits: AgentSettings, device, dtype) -> SimBackend:
    """The backend ``name`` (``sim.backend`` or an override) for ``sim`` and the agents' ``limits``."""
    if name == "double_integrator":
        return _make_double_integrator(sim, limits, device, dtype)
    if name not in BACKEND_MODULES:
        raise ValueError(f"unknown simulation backend '{name}' (available: {['double_integrator', *BACKEND_MODULES]})")
    import importlib

    return importlib.import_module(BACKEND_MODULES[name]).make_backend(sim, limits, device, dtype)
