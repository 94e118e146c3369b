"""Settings parsed once from the validated config into small frozen dataclasses.

Values live in one place, ``config.yaml``, and bounds in ``workflow/schemas/config.schema.yaml``
(an optional key's absent value is the schema's ``default``): these classes have no defaults of
their own, ``from_config`` reads every field from the validated config, and a check a class
repeats for objects built in code uses the schema's bound (``tests/test_settings_schema.py``). Method settings live beside their method (``MadPinnSettings``,
``MPPISettings``, …); backends and policies receive these objects, never the raw config dict.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Mapping

from madpinn.dynamics import AgentModel, model_class


@dataclass(frozen=True)
class AgentSettings:
    """``agents``: the agents' model, size and control limits (SPEC §1)."""

    collision_radius: float
    """r (m): two agents collide when their centre distance d ≤ r (the protocol's reading, SPEC §1;
    the disc reading d ≤ 2r is reported beside it from the same episodes)"""
    u_max: float
    """per-axis acceleration bound (m/s²)"""
    v_max: float
    """per-axis speed bound (m/s)"""
    model: str
    """the agents' dynamics, a name of :data:`madpinn.dynamics.MODELS`"""
    altitude_band: tuple[float, float]
    """(z_lo, z_hi) (m): the altitudes of a model with one (the 3-D double integrator)"""

    def __post_init__(self):
        model_class(self.model)   # an unknown name fails here, with the known ones

    @classmethod
    def from_config(cls, cfg: Mapping) -> "AgentSettings":
        a = cfg["agents"]
        return cls(collision_radius=float(a["collision_radius"]), u_max=float(a["u_max"]), v_max=float(a["v_max"]),
                   model=str(a["model"]), altitude_band=tuple(float(z) for z in a["altitude_band"]))

    def dynamics(self) -> AgentModel:
        """The agents' model (the one place it is built from settings): ``model``'s class given the
        keys of ``agents`` it declares as fields (u_max, v_max; the 3-D model's altitude_band)."""
        cls = model_class(self.model)
        given = {"u_max": self.u_max, "v_max": self.v_max, "altitude_band": self.altitude_band}
        return cls(**{f.name: given[f.name] for f in dataclasses.fields(cls)})
