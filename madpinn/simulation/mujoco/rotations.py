"""Vectorised unit-quaternion helpers (MuJoCo order w, x, y, z; body → world)."""

from __future__ import annotations

import numpy as np


def rotation_matrix(quat: np.ndarray) -> np.ndarray:
    """quat ``[M, 4]`` -> rotation matrices ``[M, 3, 3]`` (columns = body axes in world frame)."""
    w, x, y, z = quat[:, 0], quat[:, 1], quat[:, 2], quat[:, 3]
    return np.stack(
        [
            np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], axis=1),
            np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], axis=1),
            np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], axis=1),
        ],
        axis=1,
    )


def body_z_axis(quat: np.ndarray) -> np.ndarray:
    """Third column of :func:`rotation_matrix`, ``[M, 3]``: the thrust direction."""
    w, x, y, z = quat[:, 0], quat[:, 1], quat[:, 2], quat[:, 3]
    return np.stack([2 * (x * z + w * y), 2 * (y * z - w * x), 1 - 2 * (x * x + y * y)], axis=1)


def euler_zyx(quat: np.ndarray) -> np.ndarray:
    """Roll, pitch, yaw ``[M, 3]`` (rad) with R = R_z(yaw) R_y(pitch) R_x(roll)."""
    w, x, y, z = quat[:, 0], quat[:, 1], quat[:, 2], quat[:, 3]
    roll = np.arctan2(2 * (w * x + y * z), 1 - 2 * (x * x + y * y))
    pitch = np.arcsin(np.clip(2 * (w * y - z * x), -1.0, 1.0))
    yaw = np.arctan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))
    return np.stack([roll, pitch, yaw], axis=1)
