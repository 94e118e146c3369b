"""The Crazyflie firmware's Mellinger controller (``controller_mellinger.c``; Mellinger & Kumar,
ICRA 2011, the paper's citation for its tracking loop), vectorised over all drones (issue 46).

Per physics step, for every drone (numpy float64):

1. desired force ``F = m a_ff + k_p e_p + k_d e_v + k_i ∫e_p + m g e_z`` (``e_p = p_d − p``,
   ``e_v = v_d − v``; the integrals clamped per axis to ``i_range``); no tilt limit;
2. collective thrust ``T = F · b_3``; desired attitude ``b_3,d = F / ‖F‖`` with yaw 0;
3. attitude error ``e_R = (R_dᵀ R − Rᵀ R_d)^∨`` (the firmware's, without the ½ its gains absorb),
   ``e_ω = ω`` (rate setpoint 0);
4. moment (counts) ``M = −k_R e_R − k_ω e_ω + k_{I,m} ∫(−e_R)``, clamped to ±32 000 counts
   like the firmware, then in N·m by :func:`torque_per_count`;
5. the shared mixer (:class:`~madpinn.simulation.mujoco.controller.RotorMixer`).

Differences from the firmware (``docs/reference/mujoco.md``): standard right-handed body axes instead of the
firmware's sign flips of pitch (they cancel in the firmware), one rate for all loops (the physics
rate, instead of 500 Hz), exact state instead of the state estimator, rotors clipped by the mixer,
and no ``kd_omega_rp`` term (a derivative of the measured body rate): our rotors have no lag, and
on them that term feeds each step's rate change back with a per-step gain ``k_dω c / I_xx`` ≈ 1.5
(> 1), a growing step-to-step oscillation that the real motors' lag filters out.
"""

from __future__ import annotations

import numpy as np

from madpinn.simulation.mujoco.controller import RotorMixer
from madpinn.simulation.mujoco.firmware import MellingerGains, torque_per_count
from madpinn.simulation.mujoco.model import GRAVITY, CrazyflieSpec
from madpinn.simulation.mujoco.rotations import rotation_matrix

MOMENT_LIMIT = 32000.0
"""counts: the firmware's clamp of the roll, pitch and yaw commands"""


def attitude_error(R: np.ndarray, R_d: np.ndarray) -> np.ndarray:
    """``(R_dᵀ R − Rᵀ R_d)^∨`` ``[M, 3]`` for rotations ``[M, 3, 3]`` (columns = body axes)."""
    E = np.einsum("mji,mjk->mik", R_d, R) - np.einsum("mji,mjk->mik", R, R_d)
    return np.stack([E[:, 2, 1], E[:, 0, 2], E[:, 1, 0]], axis=1)


def desired_rotation(force: np.ndarray) -> np.ndarray:
    """``[M, 3, 3]``: body z along ``force`` ``[M, 3]``, yaw 0 (x_C = e_x), as the firmware builds it."""
    z = force / np.linalg.norm(force, axis=1, keepdims=True)
    y = np.cross(z, np.array([1.0, 0.0, 0.0]))
    y /= np.linalg.norm(y, axis=1, keepdims=True)
    x = np.cross(y, z)
    return np.stack([x, y, z], axis=2)


class MellingerController(RotorMixer):
    """Stateful (integrators): :meth:`reset` at every episode start."""

    def __init__(self, gains, spec: CrazyflieSpec, dt: float, firmware: MellingerGains = MellingerGains()):
        super().__init__(spec)
        self.g, self.dt = firmware, float(dt)
        self.k_p = np.array([firmware.kp_xy, firmware.kp_xy, firmware.kp_z])
        self.k_d = np.array([firmware.kd_xy, firmware.kd_xy, firmware.kd_z])
        self.k_i = np.array([firmware.ki_xy, firmware.ki_xy, firmware.ki_z])
        self.i_range = np.array([firmware.i_range_xy, firmware.i_range_xy, firmware.i_range_z])
        self.k_R = np.array([firmware.kR_xy, firmware.kR_xy, firmware.kR_z])
        self.k_w = np.array([firmware.kw_xy, firmware.kw_xy, firmware.kw_z])
        self.k_im = np.array([firmware.ki_m_xy, firmware.ki_m_xy, firmware.ki_m_z])
        self.i_range_m = np.array([firmware.i_range_m_xy, firmware.i_range_m_xy, firmware.i_range_m_z])
        self.to_torque = torque_per_count(spec)
        self.reset(0)

    def reset(self, count: int) -> None:
        self.i_p = np.zeros((count, 3))
        self.i_m = np.zeros((count, 3))

    def __call__(self, pos, vel, quat, omega, p_d, v_d, a_ff) -> np.ndarray:
        """Same arguments and result as :class:`~madpinn.simulation.mujoco.controller.CascadedController`."""
        if self.i_p.shape[0] != pos.shape[0]:
            self.reset(pos.shape[0])
        m = self.spec.mass
        e_p = p_d - pos
        self.i_p = np.clip(self.i_p + e_p * self.dt, -self.i_range, self.i_range)
        force = m * a_ff + self.k_p * e_p + self.k_d * (v_d - vel) + self.k_i * self.i_p
        force[:, 2] += m * GRAVITY
        R = rotation_matrix(quat)
        thrust = np.einsum("mi,mi->m", force, R[:, :, 2])
        e_R = attitude_error(R, desired_rotation(force))
        self.i_m = np.clip(self.i_m - e_R * self.dt, -self.i_range_m, self.i_range_m)
        moment = -self.k_R * e_R - self.k_w * omega + self.k_im * self.i_m
        torque = np.clip(moment, -MOMENT_LIMIT, MOMENT_LIMIT) * self.to_torque
        return self.mix(np.maximum(thrust, 0.0), torque)
