"""Cascaded position → attitude controller with the Crazyflie firmware's structure, vectorised
over all drones in numpy (SPEC §7, ``docs/reference/mujoco.md``).

Structure of the firmware's PID controller (``position_controller_pid.c`` + ``attitude_pid_controller.c``
+ ``power_distribution``), in SI units:

1. position loop: ``v_cmd = v_d + clip(K_p ⊙ (p_d − p), ±max_vel_correction)``;
2. velocity loop: ``a_cmd = a_ff + K_v ⊙ (v_cmd − v)``, thrust vector ``F = m (a_cmd + g e_z)``
   with its tilt limited to ``max_tilt``; collective thrust ``T = F · b_3`` (current body z);
   desired attitude = roll/pitch that align b_3 with F, yaw 0;
3. attitude loop: Euler-angle error → body-rate setpoint ``ω_d = K_att ⊙ e``;
4. rate loop: ``τ = J ⊙ K_rate ⊙ (ω_d − ω)``;
5. mixer: rotor thrusts ``f = M⁻¹ [T, τ]``, each clipped to ``[0, f_max]``.

Differences from the firmware (documented in ``docs/reference/mujoco.md``): gains are SI and tuned for the
paper's 4 m/s² bang-bang accelerations (faster attitude loop), no integral terms (the model is
exact, gravity is fed forward), every loop runs at the physics rate, and the acceleration
feed-forward enters the velocity loop as in the firmware's full-state setpoints.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from madpinn.simulation.mujoco.model import GRAVITY, CrazyflieSpec, mixer_matrix
from madpinn.simulation.mujoco.rotations import body_z_axis, euler_zyx


@dataclass(frozen=True)
class ControllerSettings:
    """Loop gains (all 1/s, i.e. per-loop bandwidths) and limits."""

    pos_xy: float
    pos_z: float
    vel_xy: float
    vel_z: float
    att_rp: float
    att_yaw: float
    rate_rp: float
    rate_yaw: float
    max_tilt_deg: float  # deg, tilt limit of the thrust vector
    max_vel_correction: float  # m/s, per-axis bound of the position loop's correction

    def validate(self) -> None:
        for name in ("pos_xy", "pos_z", "vel_xy", "vel_z", "att_rp", "att_yaw", "rate_rp", "rate_yaw", "max_vel_correction"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"controller gain '{name}' must be positive and finite, got {value}")
        if not 0 < self.max_tilt_deg < 90:
            raise ValueError(f"max_tilt_deg must be in (0, 90), got {self.max_tilt_deg}")


class RotorMixer:
    """Collective thrust and body torques -> rotor thrusts, shared by every controller reading."""

    def __init__(self, spec: CrazyflieSpec):
        spec.validate()
        self.spec = spec
        self.mixer = mixer_matrix(spec)
        self._mixer_inv_t = np.linalg.inv(self.mixer).T.copy()
        self.f_max = spec.max_rotor_thrust

    def reset(self, count: int) -> None:
        """Start of an episode of ``count`` drones (stateless readings: nothing to do)."""

    def mix(self, thrust: np.ndarray, torque: np.ndarray) -> np.ndarray:
        """Collective thrust ``[M]`` (N) and body torques ``[M, 3]`` (N·m) -> rotor thrusts
        ``[M, 4]``, each clipped to ``[0, f_max]`` (no prioritisation; docs/reference/mujoco.md compares
        measured alternatives)."""
        wrench = np.concatenate([thrust[:, None], torque], axis=1)
        return np.clip(wrench @ self._mixer_inv_t, 0.0, self.f_max)


class CascadedController(RotorMixer):
    """Rotor thrusts for M drones from their state and setpoints (all numpy float64)."""

    def __init__(self, gains: ControllerSettings, spec: CrazyflieSpec, dt: float | None = None):
        gains.validate()
        super().__init__(spec)
        self.gains = gains
        self.k_pos = np.array([gains.pos_xy, gains.pos_xy, gains.pos_z])
        self.k_vel = np.array([gains.vel_xy, gains.vel_xy, gains.vel_z])
        self.k_att = np.array([gains.att_rp, gains.att_rp, gains.att_yaw])
        self.j_k_rate = np.asarray(spec.inertia) * np.array([gains.rate_rp, gains.rate_rp, gains.rate_yaw])
        self.tan_tilt = math.tan(math.radians(gains.max_tilt_deg))

    def __call__(
        self,
        pos: np.ndarray,
        vel: np.ndarray,
        quat: np.ndarray,
        omega: np.ndarray,
        p_d: np.ndarray,
        v_d: np.ndarray,
        a_ff: np.ndarray,
    ) -> np.ndarray:
        """pos, vel ``[M, 3]`` (world, m, m/s); quat ``[M, 4]`` (w, x, y, z, body → world);
        omega ``[M, 3]`` (body frame, rad/s); setpoints p_d, v_d, a_ff ``[M, 3]`` (m, m/s, m/s²),
        yaw setpoint 0. Returns rotor thrusts ``[M, 4]`` (N) in ``[0, f_max]``."""
        g = self.gains
        # position and velocity loops -> thrust vector (N)
        v_cmd = v_d + np.clip(self.k_pos * (p_d - pos), -g.max_vel_correction, g.max_vel_correction)
        force = self.spec.mass * (a_ff + self.k_vel * (v_cmd - vel))
        force[:, 2] += self.spec.mass * GRAVITY
        np.maximum(force[:, 2], 0.1 * self.spec.mass * GRAVITY, out=force[:, 2])
        horizontal = np.hypot(force[:, 0], force[:, 1])
        limit = force[:, 2] * self.tan_tilt
        scale = np.minimum(1.0, limit / np.maximum(horizontal, 1e-12))
        force[:, 0] *= scale
        force[:, 1] *= scale
        # current attitude (ZYX Euler angles) and body z axis
        b3 = body_z_axis(quat)
        euler = euler_zyx(quat)
        thrust = np.einsum("ij,ij->i", force, b3)
        # desired attitude: b3_d ∥ F with yaw 0 (R_d = R_y(pitch_d) R_x(roll_d))
        pitch_d = np.arctan2(force[:, 0], force[:, 2])
        roll_d = np.arctan2(-force[:, 1], np.hypot(force[:, 0], force[:, 2]))
        yaw = euler[:, 2]
        att_err = np.stack([roll_d - euler[:, 0], pitch_d - euler[:, 1], np.arctan2(-np.sin(yaw), np.cos(yaw))], axis=1)
        # attitude -> rate -> torque loops
        torque = self.j_k_rate * (self.k_att * att_err - omega)
        return self.mix(thrust, torque)
