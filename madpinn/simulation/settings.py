"""``sim`` as a frozen settings object (:class:`SimSettings`): how episodes are simulated. Lives
under :mod:`madpinn.simulation` with the MuJoCo settings it holds (issue 48: no upward arrow from
a top-level module into the simulation package). ``sim.mujoco`` is parsed by
:class:`madpinn.simulation.mujoco.settings.MujocoSettings`, imported where it is built: the MuJoCo
package registers itself with :mod:`madpinn.simulation.backend`, which names this class."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Mapping

if TYPE_CHECKING:
    from madpinn.simulation.mujoco.settings import MujocoSettings


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
    mujoco: MujocoSettings | None
    """``sim.mujoco`` (None: built in code for the double integrator only)"""

    @classmethod
    def from_config(cls, cfg: Mapping, study: str | None = None) -> "SimSettings":
        """``sim``, with ``studies.<study>.sim`` merged over it when ``study`` is given."""
        from madpinn.config import study_sim

        return cls.from_section(study_sim(cfg, study))

    @classmethod
    def from_section(cls, s: Mapping) -> "SimSettings":
        """From a resolved ``sim`` section (e.g. :attr:`madpinn.config.RunSettings.sim`)."""
        from madpinn.simulation.mujoco.settings import MujocoSettings   # here: the mujoco package imports the backends

        mujoco = MujocoSettings.from_config(s["mujoco"])
        return cls(backend=str(s["backend"]), dt=float(s["dt"]), policy_period_steps=int(s["policy_period_steps"]),
                   scenario_batch=int(s["scenario_batch"]), start_separation=float(s["start_separation"]),
                   record_every=int(s["record_every"]),
                   contacts=bool(s["contacts"]), mujoco=mujoco)

