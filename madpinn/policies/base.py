"""Policy protocol and registry.

A policy is built once per evaluation job by a factory registered under the method name, and
then driven by the simulator:

- ``reset(state [S, N, 4], goals [S, N, 2])`` at t = 0,
- ``act(state, goals, t) -> accel [S, N, 2]`` (m/s², inside the control box).

The simulator runs under ``torch.no_grad()``; a policy that needs gradients enables them locally.
Decentralization is respected by construction: each agent's control may only depend on its own
observation (ego + selected neighbours), even though all agents are computed in one batch.
"""

from __future__ import annotations

import importlib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Mapping, Protocol

import torch

from madpinn.config import ConfigError
from madpinn.dynamics import AgentModel
from madpinn.observation import ObservationSettings


class Policy(Protocol):
    def reset(self, state: torch.Tensor, goals: torch.Tensor) -> None: ...

    def act(self, state: torch.Tensor, goals: torch.Tensor, t: float) -> torch.Tensor: ...


@dataclass
class PolicyContext:
    """Everything a policy factory may need."""

    method: Any
    """the method's settings (its registered settings class, built by :func:`policy_settings`)"""
    dynamics: AgentModel
    """the agents' model (layout, bounds ``u_max`` / ``v_max``, step)"""
    obs_spec: ObservationSettings
    """decentralized observation layout and ranges"""
    device: torch.device
    dtype: torch.dtype
    seed: int
    """the policy's own seed (sampling, random neighbours)"""
    sim_dt: float
    """simulation step (s)"""
    policy_period: int
    """simulation steps between policy queries"""
    models: Mapping[str, Path] = field(default_factory=dict)
    """trained files the policy loads, by name (``--model NAME=PATH`` of the evaluate command)"""

    def model(self, name: str, method: str) -> Path:
        """The trained file ``name`` of ``method``; a clear error when the job was not given it."""
        if name not in self.models:
            raise ConfigError(f"method '{method}' loads a trained '{name}' model: pass --model {name}=PATH "
                              f"(the workflow's evaluate rule does; given: {sorted(self.models) or 'none'})")
        return Path(self.models[name])


PolicyFactory = Callable[[PolicyContext], Policy]
_REGISTRY: dict[str, PolicyFactory] = {}
_SETTINGS: dict[str, type] = {}

# Methods implemented in their own modules; imported lazily so that a method's heavy
# dependencies load only when it is used.
_MODULES = {
    "nominal": "madpinn.policies.nominal",
    "madpinn": "madpinn.policies.madpinn",
    "mppi": "madpinn.policies.mppi",
    "safemarl": "madpinn.policies.safemarl",
    "defmarl": "madpinn.policies.defmarl",
}


def register_policy(name: str, settings: type):
    """Register ``factory(ctx) -> Policy`` under method ``name``; ``settings`` is the method's
    frozen settings class, built from ``methods.<name>`` (merged with a variant) by its
    ``from_config``."""

    def deco(factory: PolicyFactory) -> PolicyFactory:
        _REGISTRY[name] = factory
        _SETTINGS[name] = settings
        return factory

    return deco


def _load(name: str) -> None:
    if name not in _REGISTRY and name in _MODULES:
        importlib.import_module(_MODULES[name])
    if name not in _REGISTRY:
        raise ValueError(f"unknown method '{name}' (available: {sorted(set(_REGISTRY) | set(_MODULES))})")


def policy_settings(name: str, method_config: Mapping) -> Any:
    """The settings object of method ``name`` from its (variant-merged) config section."""
    _load(name)
    return _SETTINGS[name].from_config(method_config)


def make_policy(name: str, ctx: PolicyContext) -> Policy:
    _load(name)
    return _REGISTRY[name](ctx)
