"""Crazyflie firmware constants (bitcraze/crazyflie-firmware, ``platform_defaults_cf2.h``,
``controller_mellinger.c``, ``position_controller_pid.c``, ``attitude_pid_controller.c``) and
their conversion to SI for our Crazyflie model (issue 46, ``docs/reference/mujoco.md``, "Controller readings").

Units. The firmware commands each motor in PWM counts and forms torques with the legacy power
distribution (``power_distribution_quadrotor.c``: motor ``m_k = thrust ∓ roll/2 ± pitch/2 ± yaw``).
The Mellinger controller's ``massThrust = 132 000`` maps a collective thrust of 1 N to that
per-motor command, so one count is ``1 / (4 · 132 000)`` N per motor; a roll or pitch command of
one count then gives a torque ``2 · d / (4 · 132 000)`` N·m (``d`` = the rotor's lever arm about
the body axis) and a yaw count ``4 · k_m/k_f / (4 · 132 000)`` N·m. These are the only factors
used to bring the firmware's gains into SI; everything else is the firmware's number.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from madpinn.simulation.mujoco.model import CrazyflieSpec

MASS_THRUST = 132000.0
"""PWM counts per newton of collective thrust (``controller_mellinger.c`` ``massThrust``)"""


def newtons_per_count() -> float:
    """Per-motor thrust (N) of one PWM count."""
    return 1.0 / (4.0 * MASS_THRUST)


def torque_per_count(spec: CrazyflieSpec) -> np.ndarray:
    """``[3]`` N·m per count of the legacy roll, pitch and yaw commands for ``spec``'s X layout."""
    d = spec.arm / math.sqrt(2.0)
    c = newtons_per_count()
    return np.array([2.0 * d * c, 2.0 * d * c, 4.0 * spec.km_over_kf * c])


@dataclass(frozen=True)
class MellingerGains:
    """``controller_mellinger.c`` defaults (firmware units: N/m, N/(m/s), N/(m·s) for position;
    PWM counts per rad, per rad/s, per rad·s for attitude; ranges of the integrators)."""

    kp_xy: float = 0.4
    kd_xy: float = 0.2
    ki_xy: float = 0.05
    i_range_xy: float = 2.0
    kp_z: float = 1.25
    kd_z: float = 0.4
    ki_z: float = 0.05
    i_range_z: float = 0.4
    kR_xy: float = 70000.0
    kw_xy: float = 20000.0
    ki_m_xy: float = 0.0
    i_range_m_xy: float = 1.0
    kR_z: float = 60000.0
    kw_z: float = 12000.0
    ki_m_z: float = 500.0
    i_range_m_z: float = 1500.0
    kd_omega_rp: float = 200.0           # not used on lag-free rotors (mellinger.py)


@dataclass(frozen=True)
class FirmwarePidGains:
    """``platform_defaults_cf2.h`` / ``position_controller_pid.c`` defaults of the PID stack in
    absolute-position mode (firmware units: position P in (m/s)/m; velocity PI in deg per m/s and
    deg per m; z velocity PI in thrust counts/1000 per m/s; attitude PI in (deg/s)/deg; rate PID in
    counts per deg/s; limits in m/s, deg, counts)."""

    pos_kp_xy: float = 2.0
    pos_kp_z: float = 2.0
    pos_ki_z: float = 0.5
    vel_max: float = 1.0 * 1.10          # xyVelMax, zVelMax (1 m/s) × velMaxOverhead
    vel_kp_xy: float = 25.0
    vel_ki_xy: float = 1.0
    vel_kp_z: float = 25.0
    vel_ki_z: float = 15.0
    thrust_scale: float = 1000.0
    thrust_min: float = 20000.0          # counts (collective command)
    tilt_max_deg: float = 20.0           # rLimit = pLimit (PID_VEL_ROLL_MAX)
    att_kp: float = 6.0
    att_ki: float = 3.0
    att_i_limit: float = 20.0
    yaw_kp: float = 6.0
    yaw_ki: float = 1.0
    yaw_kd: float = 0.35
    yaw_i_limit: float = 360.0
    rate_kp: float = 250.0
    rate_ki: float = 500.0
    rate_kd: float = 2.5                 # not used on lag-free rotors (firmware_pid.py)
    rate_i_limit: float = 33.3
    yaw_rate_kp: float = 120.0
    yaw_rate_ki: float = 16.7
    yaw_rate_i_limit: float = 166.7
    pos_i_limit_z: float = 5000.0        # pid.c default integration limit
    vel_i_limit: float = 5000.0
