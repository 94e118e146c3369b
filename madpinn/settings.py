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

from madpinn.dynamics import DoubleIntegrator


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

    def dynamics(self) -> DoubleIntegrator:
        """The agents' double integrator (the one place it is built from settings)."""
        return DoubleIntegrator(u_max=self.u_max, v_max=self.v_max)


@dataclass(frozen=True)
class SimSettings:
    """``sim``: how episodes are simulated."""

    backend: str
    """simulation backend name (``double_integrator`` | ``mujoco``)"""
    dt: float
    """simulation step (s)"""
    policy_period_steps: int
    """simulation steps between policy queries (a method may set its own)"""
    scenario_batch: int
    """scenarios simulated together in one batch"""
    start_separation: float
    """smallest distance (m) among a scenario's starts and among its goals (SPEC §2: 2r); its own
    key so that a reading with another collision radius keeps the same scenarios"""
    record_every: int
    """trajectory recording period in simulation steps (first batch only)"""
    contacts: bool
    """agents touch (SPEC §1): MuJoCo drones carry the CF2X collision cylinder and hit each other
    and the floor; in the double integrator a collided agent (d ≤ r) stops where it is and stays
    an obstacle. False: agents pass through each other (the first protocol)"""
    mujoco: object | None
    """``sim.mujoco`` as :class:`madpinn.simulation.mujoco.MujocoSettings` (None: built in code for
    the double integrator only)"""

    @classmethod
    def from_config(cls, cfg: Mapping, study: str | None = None) -> "SimSettings":
        """``sim``, with ``studies.<study>.sim`` merged over it when ``study`` is given."""
        from madpinn.config import study_sim

        from madpinn.simulation.mujoco.settings import MujocoSettings

        s = study_sim(cfg, study)
        mujoco = MujocoSettings.from_config(s["mujoco"])
        return cls(backend=str(s["backend"]), dt=float(s["dt"]), policy_period_steps=int(s["policy_period_steps"]),
                   scenario_batch=int(s["scenario_batch"]), start_separation=float(s["start_separation"]),
                   record_every=int(s["record_every"]),
                   contacts=bool(s["contacts"]), mujoco=mujoco)

