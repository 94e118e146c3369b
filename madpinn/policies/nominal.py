"""Nominal goal-reaching controller: bounded PD, no safety. A reference row, not a method."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping

import torch

from madpinn.dynamics import AgentModel
from madpinn.policies.base import PolicyContext, register_policy


class NominalPD:
    """u = clip(kp·(g − p) − kd·v, ±u_max) per axis (kp in 1/s², kd in 1/s)."""

    def __init__(self, dynamics: AgentModel, kp: float, kd: float):
        self.dynamics = dynamics
        self.kp = float(kp)
        self.kd = float(kd)

    def reset(self, state: torch.Tensor, goals: torch.Tensor) -> None:
        pass

    def act(self, state: torch.Tensor, goals: torch.Tensor, t: float) -> torch.Tensor:
        u = self.kp * (goals - self.dynamics.position(state)) - self.kd * self.dynamics.velocity(state)
        return self.dynamics.clip_control(u)


@dataclass(frozen=True)
class NominalSettings:
    """``methods.nominal``."""

    kp: float
    """position gain (1/s²)"""
    kd: float
    """velocity gain (1/s)"""

    @classmethod
    def from_config(cls, m: Mapping) -> "NominalSettings":
        return cls(kp=float(m["kp"]), kd=float(m["kd"]))


@register_policy("nominal", NominalSettings)
def make_nominal(ctx: PolicyContext) -> NominalPD:
    return NominalPD(ctx.dynamics, kp=ctx.method.kp, kd=ctx.method.kd)
