"""``sim.mujoco`` configuration: every value from ``config.yaml``, no defaults here (issue 32)."""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, fields

from madpinn.simulation.mujoco.controller import ControllerSettings
from madpinn.simulation.mujoco.forces import FORCE_MODES
from madpinn.simulation.mujoco.model import MAX_DRONES_PER_WORLD, CrazyflieSpec
from madpinn.simulation.mujoco.readings import CONTROLLERS


@dataclass(frozen=True)
class MujocoSettings:
    """substeps: physics (and controller) steps per ``sim.dt``; force_application: see
    :mod:`~madpinn.simulation.mujoco.forces`; drones_per_world: largest world compiled (bigger
    batches use several worlds); altitude (m) of the setpoint; thrust_to_weight sets the rotor
    limit f_max = thrust_to_weight · m g / 4; max_drones: bound of S × N per backend;
    render_clips: the workflow renders one GIF per (study, run) where offscreen GL exists;
    controller: the tracking-loop reading (:mod:`~madpinn.simulation.mujoco.readings`); gains:
    the ``cascaded`` reading's gains."""

    substeps: int
    force_application: str
    drones_per_world: int
    altitude: float
    thrust_to_weight: float
    max_drones: int
    render_clips: bool
    controller: str
    gains: ControllerSettings

    @property
    def spec(self) -> CrazyflieSpec:
        return CrazyflieSpec(thrust_to_weight=self.thrust_to_weight)

    def validate(self) -> None:
        if int(self.substeps) < 1:
            raise ValueError(f"sim.mujoco.substeps must be ≥ 1, got {self.substeps}")
        if self.force_application not in FORCE_MODES:
            raise ValueError(f"sim.mujoco.force_application must be one of {FORCE_MODES}, got '{self.force_application}'")
        if not 1 <= int(self.drones_per_world) <= MAX_DRONES_PER_WORLD:
            raise ValueError(f"sim.mujoco.drones_per_world must be in 1..{MAX_DRONES_PER_WORLD}, got {self.drones_per_world}")
        if not (math.isfinite(self.altitude) and self.altitude > 0):
            raise ValueError(f"sim.mujoco.altitude must be positive, got {self.altitude}")
        if self.controller not in CONTROLLERS:
            raise ValueError(f"sim.mujoco.controller must be one of {CONTROLLERS}, got '{self.controller}'")
        if int(self.max_drones) < 1:
            raise ValueError(f"sim.mujoco.max_drones must be ≥ 1, got {self.max_drones}")
        self.spec.validate()
        self.gains.validate()

    @classmethod
    def from_config(cls, section: dict) -> "MujocoSettings":
        """Build from the ``sim.mujoco`` mapping (every key, as the schema requires)."""
        section = dict(section)
        known = {f.name for f in fields(cls)}
        unknown = set(section) - known
        if unknown:
            raise ValueError(f"unknown sim.mujoco keys {sorted(unknown)} (known: {sorted(known)})")
        gains = dict(section.pop("gains"))
        gain_names = {f.name for f in fields(ControllerSettings)}
        if set(gains) - gain_names:
            raise ValueError(f"unknown sim.mujoco.gains keys {sorted(set(gains) - gain_names)} (known: {sorted(gain_names)})")
        settings = cls(**section, gains=ControllerSettings(**{k: float(v) for k, v in gains.items()}))
        settings.validate()
        return settings

    def as_dict(self) -> dict:
        return asdict(self)
