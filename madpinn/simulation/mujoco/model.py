"""Our own MJCF of a Crazyflie 2.x and of worlds holding many of them (SPEC §7).

Physical facts (public, see ``docs/reference/mujoco.md``): mass 0.027 kg, arm (centre to rotor axis)
0.0397 m, inertia diag(1.4e-5, 1.4e-5, 2.17e-5) kg·m², four rotors in X layout, thrust-to-weight
2.25, yaw moment / thrust ratio km/kf = 0.025 m. The body frame is x forward, y left, z up; the
centre of mass is the body origin, so rotor forces can be applied as generalised forces on the
free joint (see :mod:`madpinn.simulation.mujoco.forces`).

Contacts (``sim.contacts``): off, drones never touch each other (or anything): every geom has
``contype = conaffinity = 0`` and contacts are disabled globally, so the drones of a world are
dynamically independent. On, each drone carries the collision body of the CF2X model of the
simulator the paper cites (MuJoCo-drones-gym / gym-pybullet-drones: a cylinder of radius 0.06 m
and height 0.03 m about the centre of mass), and drones touch each other and a floor at z = 0 with
MuJoCo's default soft contacts; the backend keeps the drones of different scenarios apart by
placing each scenario at its own offset in the world (:func:`scenario_offsets`).
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import mujoco
import numpy as np

GRAVITY = 9.81  # m/s²
# MuJoCo's compile time grows as O(N²) with the number of free bodies (0.27 s for 1024 drones,
# 7.7 s for 5120), so the backend splits large batches into several worlds (``drones_per_world``);
# this is the hard upper bound of one world.
MAX_DRONES_PER_WORLD = 8192
# CF2X collision cylinder of the cited simulator (radius, half height), m: two level drones touch
# at a centre distance below 2 × 0.06 = 0.12 m.
COLLISION_CYLINDER = (0.06, 0.015)
# m between neighbouring scenarios' origins when contacts are on: far beyond any arena
# (half width ≤ 4 m here) and any drift, so drones of different scenarios never meet.
SCENARIO_SPACING = 100.0
HORIZONTAL = slice(0, 2)
"""x, y of the world frame: the plane scenarios are laid out in and the firmware's horizontal loops act in (z: altitude)"""
FREE_JOINT_DOFS = 6
"""velocity coordinates of a drone's free joint: linear (3), then angular (3)"""
ROTORS = 4


@dataclass(frozen=True)
class CrazyflieSpec:
    """Crazyflie 2.x physical parameters (SI units): ``thrust_to_weight`` from ``sim.mujoco``
    (:attr:`MujocoSettings.spec`, no default), the rest the airframe's published constants."""

    thrust_to_weight: float
    mass: float = 0.027  # kg
    arm: float = 0.0397  # m, centre to rotor axis
    inertia: tuple[float, float, float] = (1.4e-5, 1.4e-5, 2.17e-5)  # kg·m², principal
    km_over_kf: float = 0.025  # m, yaw reaction moment per newton of rotor thrust

    @property
    def max_rotor_thrust(self) -> float:
        """Per-rotor thrust limit (N): thrust_to_weight · m · g / 4."""
        return self.thrust_to_weight * self.mass * GRAVITY / 4.0

    @property
    def rotor_positions(self) -> np.ndarray:
        """Rotor centres ``[4, 2]`` (m) in the body frame, X layout: front-right, back-right,
        back-left, front-left (firmware motor order M1..M4)."""
        d = self.arm / math.sqrt(2.0)
        return np.array([[d, -d], [-d, -d], [-d, d], [d, d]])

    @property
    def rotor_spin(self) -> np.ndarray:
        """Yaw reaction sign per rotor ``[4]``: +1 pushes the body counter-clockwise (seen from
        above). M1 and M3 spin clockwise, M2 and M4 counter-clockwise."""
        return np.array([1.0, -1.0, 1.0, -1.0])

    def validate(self) -> None:
        if not (self.mass > 0 and self.arm > 0 and all(i > 0 for i in self.inertia)):
            raise ValueError(f"Crazyflie mass, arm and inertia must be positive, got {self}")
        if not self.thrust_to_weight > 1.0:
            raise ValueError(f"thrust_to_weight must exceed 1 to hover, got {self.thrust_to_weight}")
        if not self.km_over_kf > 0:
            raise ValueError(f"km_over_kf must be positive, got {self.km_over_kf}")


def mixer_matrix(spec: CrazyflieSpec) -> np.ndarray:
    """``[4, 4]`` map from rotor thrusts (N) to ``[collective thrust (N), body torques τx, τy, τz
    (N·m)]``: T = Σf, τx = Σ y_i f_i, τy = −Σ x_i f_i, τz = Σ s_i (km/kf) f_i."""
    xy = spec.rotor_positions
    return np.stack([np.ones(4), xy[:, 1], -xy[:, 0], spec.rotor_spin * spec.km_over_kf])


def _drone_xml(index: int, spec: CrazyflieSpec, actuated: bool, contacts: bool = False,
               visual: bool = True) -> tuple[str, str]:
    """One drone body (free joint, explicit inertia, rotor sites; with ``visual`` its massless
    visual-only geoms, with ``contacts`` its collision cylinder) and, when ``actuated``, its four
    site actuators. Returns ``(body_xml, actuator_xml)``."""
    ix, iy, iz = spec.inertia
    rotors, arms, acts = [], [], []
    for k, ((x, y), s) in enumerate(zip(spec.rotor_positions.tolist(), spec.rotor_spin.tolist())):
        rotors.append(
            f'<site name="d{index}r{k}" pos="{x!r} {y!r} 0.008" size="0.004"/>'
            + (f'<geom class="visual" type="cylinder" size="0.023 0.002" pos="{x!r} {y!r} 0.01" rgba="0.2 0.2 0.2 0.35"/>'
               if visual else "")
        )
        if visual:
            arms.append(f'<geom class="visual" type="capsule" size="0.003" fromto="0 0 0 {x!r} {y!r} 0"/>')
        if actuated:
            acts.append(
                f'<general site="d{index}r{k}" gear="0 0 1 0 0 {s * spec.km_over_kf!r}" '
                f'ctrllimited="true" ctrlrange="0 {spec.max_rotor_thrust!r}"/>'
            )
    body = (
        f'<body name="d{index}" pos="0 0 1"><freejoint/>'
        f'<inertial pos="0 0 0" mass="{spec.mass}" diaginertia="{ix} {iy} {iz}"/>'
        + ('<geom class="visual" type="box" size="0.015 0.015 0.006" rgba="0.85 0.85 0.85 1"/>' if visual else "")
        + (f'<geom name="d{index}hull" type="cylinder" size="{COLLISION_CYLINDER[0]!r} {COLLISION_CYLINDER[1]!r}" '
           'mass="0" contype="1" conaffinity="1" group="3" rgba="0.8 0.2 0.2 0.2"/>' if contacts else "")
        + "".join(arms) + "".join(rotors) + "</body>"
    )
    return body, "".join(acts)


def world_xml(count: int, timestep: float, spec: CrazyflieSpec, actuated: bool = False,
              contacts: bool = False, visual: bool = True) -> str:
    """MJCF of a world holding ``count`` Crazyflies (all at the origin; :class:`MujocoBackend`
    places them through ``qpos``), physics step ``timestep`` (s), semi-implicit Euler; without
    ``contacts`` nothing touches, with them drones touch each other and the floor. ``visual``
    adds the massless drawing-only geoms (rendering needs them, the dynamics do not: without them
    a step costs 20 % less, and 35 % less with contacts, whose broadphase visits every geom).

    ``actuated`` adds four site actuators per drone (control = rotor thrust, N), used only to
    check that direct force application is physically identical; site transmissions cost O(N²)
    per step in a world of N drones.
    """
    if not 1 <= int(count) <= MAX_DRONES_PER_WORLD:
        raise ValueError(f"a MuJoCo world holds 1..{MAX_DRONES_PER_WORLD} drones, got {count}")
    if not (math.isfinite(timestep) and timestep > 0):
        raise ValueError(f"physics timestep must be positive, got {timestep}")
    spec.validate()
    parts = [_drone_xml(i, spec, actuated, contacts, visual) for i in range(int(count))]
    floor_contact = 'contype="1" conaffinity="1"' if contacts else 'contype="0" conaffinity="0"'

    memory_mb = max(16, int(count) * (64 if actuated else 4) // 1024 + 16)
    return (
        '<mujoco model="crazyflie_swarm">'
        '<compiler angle="radian"/>'
        f'<size memory="{memory_mb}M"/>'
        f'<option timestep="{timestep!r}" gravity="0 0 {-GRAVITY}" integrator="Euler">'
        + ('' if contacts else '<flag contact="disable"/>') + '</option>'
        '<visual><global offwidth="640" offheight="480"/></visual>'
        '<default><default class="visual"><geom contype="0" conaffinity="0" group="1" mass="0" rgba="0.1 0.1 0.1 1"/></default></default>'
        '<worldbody><light pos="0 0 6" dir="0 0 -1" directional="true"/>'
        f'<geom name="floor" type="plane" size="10 10 0.1" {floor_contact} rgba="0.9 0.9 0.9 1"/>'
        + "".join(b for b, _ in parts)
        + "</worldbody>"
        + ("<actuator>" + "".join(a for _, a in parts) + "</actuator>" if actuated else "")
        + "</mujoco>"
    )


@functools.lru_cache(maxsize=8)
def compile_world(count: int, timestep: float, spec: CrazyflieSpec, actuated: bool = False,
                  contacts: bool = False, visual: bool = True) -> mujoco.MjModel:
    """Compiled (and cached per process) :func:`world_xml`. Models are read-only to callers."""
    return mujoco.MjModel.from_xml_string(world_xml(count, timestep, spec, actuated, contacts, visual))


def scenario_offsets(count: int, group: int) -> np.ndarray:
    """Planar offsets ``[count, 2]`` (m) that put each run of ``group`` consecutive drones (one
    scenario) on its own square of side :data:`SCENARIO_SPACING` of a grid, so drones of different
    scenarios never touch while their own coordinates stay the scenario's."""
    scenario = np.arange(int(count)) // int(group)
    cols = max(1, math.ceil(math.sqrt(scenario[-1] + 1))) if count else 1
    return SCENARIO_SPACING * np.stack([scenario % cols, scenario // cols], axis=1).astype(float)
