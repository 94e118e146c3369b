"""Settings parsed once from the validated config into small frozen dataclasses.

Values live in one place, ``config.yaml``, and bounds in ``workflow/schemas/config.schema.yaml``
(an optional key's absent value is the schema's ``default``): these classes have no defaults of
their own, ``from_config`` reads every field from the validated config, and a check a class
repeats for objects built in code uses the schema's bound (``tests/test_settings_schema.py``). Method settings live beside their method (``MadPinnSettings``,
``MPPISettings``, …); backends and policies receive these objects, never the raw config dict.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping

from madpinn.dynamics import AgentModel, DoubleIntegrator


@dataclass(frozen=True)
class AgentSettings:
    """``agents``: the agents' size and control limits (SPEC §1)."""

    collision_radius: float
    """r (m): two agents collide when their centre distance d ≤ r (the protocol's reading, SPEC §1;
    the disc reading d ≤ 2r is reported beside it from the same episodes)"""
    u_max: float
    """per-axis acceleration bound (m/s²)"""
    v_max: float
    """per-axis speed bound (m/s)"""

    @classmethod
    def from_config(cls, cfg: Mapping) -> "AgentSettings":
        a = cfg["agents"]
        return cls(collision_radius=float(a["collision_radius"]), u_max=float(a["u_max"]), v_max=float(a["v_max"]))

    def dynamics(self) -> AgentModel:
        """The agents' double integrator (the one place it is built from settings)."""
        return DoubleIntegrator(u_max=self.u_max, v_max=self.v_max)
