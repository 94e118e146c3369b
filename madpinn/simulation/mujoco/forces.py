"""Applying rotor thrusts to a MuJoCo world, three physically identical ways.

- ``qfrc`` (default): the rotor wrench as generalised forces of each drone's free joint: world-frame
  force ``T·b_3`` on the translational dofs, body-frame torque ``τ`` on the rotational dofs (MuJoCo
  expresses a free joint's angular dofs in the body frame). O(N) per step.
- ``xfrc``: the same wrench as a Cartesian force/torque at each body's centre of mass, world frame.
  O(N) per step, slightly slower (MuJoCo maps it through the body Jacobian).
- ``site``: four site actuators per drone (force along the rotor axis at the rotor, yaw reaction
  torque via the gear). The reference formulation; O(N²) per step in a world of N drones because
  the site transmission moments are dense. Kept for the equivalence test and the benchmark.

``tests/test_mujoco_forces.py`` checks that all three give the same trajectories.
"""

from __future__ import annotations

import mujoco
import numpy as np

from madpinn.simulation.mujoco.model import FREE_JOINT_DOFS
from madpinn.simulation.mujoco.rotations import body_z_axis, rotation_matrix

FORCE_MODES = ("qfrc", "xfrc", "site")


def apply_rotor_thrusts(mode: str, data: mujoco.MjData, thrusts: np.ndarray, quat: np.ndarray, mixer: np.ndarray) -> None:
    """Write rotor thrusts ``[n, 4]`` (N) of the n drones of ``data`` (attitudes ``quat`` ``[n, 4]``)
    into its force inputs; ``mixer`` ``[4, 4]`` maps rotor thrusts to ``[T, τx, τy, τz]``."""
    if mode == "site":
        data.ctrl[:] = thrusts.reshape(-1)
        return
    wrench = thrusts @ mixer.T
    force = body_z_axis(quat) * wrench[:, 0:1]
    if mode == "qfrc":
        qfrc = data.qfrc_applied.reshape(-1, FREE_JOINT_DOFS)
        qfrc[:, 0:3] = force
        qfrc[:, 3:6] = wrench[:, 1:4]
    elif mode == "xfrc":
        xfrc = data.xfrc_applied[1:]
        xfrc[:, 0:3] = force
        xfrc[:, 3:6] = np.einsum("nij,nj->ni", rotation_matrix(quat), wrench[:, 1:4])
    else:
        raise ValueError(f"force_application must be one of {FORCE_MODES}, got '{mode}'")
