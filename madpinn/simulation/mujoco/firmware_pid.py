"""The Crazyflie firmware's PID stack in absolute-position mode (``position_controller_pid.c`` →
``attitude_pid_controller.c`` → legacy power distribution), firmware gains and limits,
vectorised over all drones (issue 46, controller reading ``firmware_pid``).

Per physics step, for every drone (numpy float64; firmware units converted by
:mod:`~madpinn.simulation.mujoco.firmware`):

1. position loop: in absolute-position mode the firmware *replaces* the velocity setpoint by its
   position loop, ``v_sp = clip(K_p (p_d − p) [+ K_i ∫e_z], ±1.1 m/s)`` per axis; ``v_d`` and
   ``a_ff`` are not used;
2. velocity loop (PI): pitch / roll setpoints ``25 e_v + 1 ∫e_v`` deg per m/s, clamped to ±20°;
   collective thrust ``m g + (25 e_vz + 15 ∫e_vz)·1000`` counts (gravity fed forward in SI instead
   of the firmware's ``thrustBase`` = 36 000 counts, 0.273 N vs m g = 0.265 N here), at least
   20 000 counts;
3. attitude loop (PI; yaw PID): body-rate setpoints ``6 e + 3 ∫e`` (deg/s per deg) from ZYX Euler errors;
4. rate loop (PI): ``250 e_ω + 500 ∫e_ω`` counts per deg/s (yaw 120, 16.7), integrals clamped as
   the firmware's ``*_INTEGRATION_LIMIT``; counts → N·m (:func:`torque_per_count`);
5. the shared mixer.

Differences from the firmware (``docs/reference/mujoco.md``): one rate for every loop (the physics rate,
instead of 100 Hz position and 500 Hz attitude), no low-pass filters, exact state, yaw setpoint 0,
and no derivative term in the rate loop (``PID_ROLL_RATE_KD = 2.5``): our rotors have no lag, and
on them that term feeds each step's rate change back with a per-step gain ≈ 1.1 (> 1), a growing
step-to-step oscillation that the firmware's D-term filter and the real motors' lag remove.
"""

from __future__ import annotations

import math

import numpy as np

from madpinn.simulation.mujoco.controller import RotorMixer
from madpinn.simulation.mujoco.firmware import MASS_THRUST, FirmwarePidGains, torque_per_count
from madpinn.simulation.mujoco.model import GRAVITY, HORIZONTAL, CrazyflieSpec
from madpinn.simulation.mujoco.rotations import euler_zyx

COUNT_LIMIT = 32767.0
"""counts: the int16 range of the roll, pitch and yaw commands"""


class FirmwarePidController(RotorMixer):
    """Stateful (integrators, last errors): :meth:`reset` at every episode start."""

    def __init__(self, gains, spec: CrazyflieSpec, dt: float, firmware: FirmwarePidGains = FirmwarePidGains()):
        super().__init__(spec)
        self.g, self.dt = firmware, float(dt)
        self.to_torque = torque_per_count(spec)
        self.tilt_max = math.radians(firmware.tilt_max_deg)
        self.att_kp = np.array([firmware.att_kp, firmware.att_kp, firmware.yaw_kp])
        self.att_ki = np.array([firmware.att_ki, firmware.att_ki, firmware.yaw_ki])
        self.att_kd = np.array([0.0, 0.0, firmware.yaw_kd])
        self.att_i_limit = np.array([firmware.att_i_limit, firmware.att_i_limit, firmware.yaw_i_limit])
        self.rate_kp = np.array([firmware.rate_kp, firmware.rate_kp, firmware.yaw_rate_kp])
        self.rate_ki = np.array([firmware.rate_ki, firmware.rate_ki, firmware.yaw_rate_ki])
        self.rate_i_limit = np.array([firmware.rate_i_limit, firmware.rate_i_limit, firmware.yaw_rate_i_limit])
        self.reset(0)

    def reset(self, count: int) -> None:
        self.i_pos_z = np.zeros(count)
        self.i_vel = np.zeros((count, 3))
        self.i_att = np.zeros((count, 3))
        self.i_rate = np.zeros((count, 3))
        self.last_att_err: np.ndarray | None = None

    def __call__(self, pos, vel, quat, omega, p_d, v_d, a_ff) -> np.ndarray:
        """Same arguments and result as :class:`~madpinn.simulation.mujoco.controller.CascadedController`
        (``v_d`` and ``a_ff`` ignored, as in the firmware's absolute-position mode)."""
        if self.i_vel.shape[0] != pos.shape[0]:
            self.reset(pos.shape[0])
        g, dt = self.g, self.dt
        e_p = p_d - pos
        self.i_pos_z = np.clip(self.i_pos_z + e_p[:, 2] * dt, -g.pos_i_limit_z, g.pos_i_limit_z)
        v_sp = np.empty_like(pos)
        v_sp[:, HORIZONTAL] = g.pos_kp_xy * e_p[:, HORIZONTAL]
        v_sp[:, 2] = g.pos_kp_z * e_p[:, 2] + g.pos_ki_z * self.i_pos_z
        v_sp = np.clip(v_sp, -g.vel_max, g.vel_max)
        e_v = v_sp - vel
        self.i_vel = np.clip(self.i_vel + e_v * dt, -g.vel_i_limit, g.vel_i_limit)
        tilt_deg = np.clip(g.vel_kp_xy * e_v[:, HORIZONTAL] + g.vel_ki_xy * self.i_vel[:, HORIZONTAL], -g.tilt_max_deg, g.tilt_max_deg)
        counts = g.thrust_scale * (g.vel_kp_z * e_v[:, 2] + g.vel_ki_z * self.i_vel[:, 2])
        thrust = np.maximum(self.spec.mass * GRAVITY + counts / MASS_THRUST, g.thrust_min / MASS_THRUST)
        # +x acceleration: positive pitch (b_3 towards +x); +y acceleration: negative roll
        att_d = np.stack([-np.radians(tilt_deg[:, 1]), np.radians(tilt_deg[:, 0]), np.zeros(len(pos))], axis=1)
        euler = euler_zyx(quat)
        att_err = np.degrees(att_d - euler)
        att_err[:, 2] = np.degrees(np.arctan2(np.sin(att_d[:, 2] - euler[:, 2]), np.cos(att_d[:, 2] - euler[:, 2])))
        self.i_att = np.clip(self.i_att + att_err * dt, -self.att_i_limit, self.att_i_limit)
        d_att = np.zeros_like(att_err) if self.last_att_err is None else (att_err - self.last_att_err) / dt
        self.last_att_err = att_err
        rate_sp = self.att_kp * att_err + self.att_ki * self.i_att + self.att_kd * d_att   # deg/s
        rate_err = rate_sp - np.degrees(omega)
        self.i_rate = np.clip(self.i_rate + rate_err * dt, -self.rate_i_limit, self.rate_i_limit)
        cmd = self.rate_kp * rate_err + self.rate_ki * self.i_rate
        torque = np.clip(cmd, -COUNT_LIMIT, COUNT_LIMIT) * self.to_torque
        return self.mix(thrust, torque)
