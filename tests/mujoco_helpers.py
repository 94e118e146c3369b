"""Shared helpers of the MuJoCo backend tests (small configurations of the real code paths)."""

from __future__ import annotations

import numpy as np
import torch

from madpinn.dynamics import DoubleIntegrator
from madpinn.simulation.mujoco import MujocoBackend, MujocoSettings
from settings_helpers import mujoco_section

DT = 0.0025
DYN = DoubleIntegrator(u_max=4.0, v_max=4.0)


def make_backend(**overrides) -> MujocoBackend:
    torch.set_num_threads(1)
    return MujocoBackend(DYN, DT, MujocoSettings.from_config(mujoco_section(**overrides)), dtype=torch.float64)


def bang_bang(n_drones: int, steps: int, mean_dwell_s: float, seed: int, u_max: float = 4.0) -> torch.Tensor:
    """Random bang-bang accelerations ``[steps, 1, n, 2]``: each axis ±u_max, flipping with
    probability dt / mean_dwell_s per step."""
    rng = np.random.default_rng(seed)
    cur = rng.choice([-u_max, u_max], size=(n_drones, 2))
    out = np.empty((steps, 1, n_drones, 2))
    for k in range(steps):
        cur = np.where(rng.random((n_drones, 2)) < DT / mean_dwell_s, -cur, cur)
        out[k, 0] = cur
    return torch.from_numpy(out)


def track_reference(backend: MujocoBackend, accel: torch.Tensor) -> dict:
    """Drive ``backend`` from rest at the origin with ``accel`` ``[steps, 1, n, 2]`` and compare
    with the exact double integrator under the same accelerations. Returns errors (m) and the
    extreme rotor thrusts (N) and altitude error (m) seen."""
    steps, _, n, _ = accel.shape
    zeros = torch.zeros(1, n, 2, dtype=torch.float64)
    state = backend.reset(zeros, zeros)
    ref = state.clone()
    err, thrust_min, thrust_max, alt_err = [], np.inf, -np.inf, 0.0
    for k in range(steps):
        backend.command(accel[k], DT)
        state = backend.step()
        ref = DYN.step(ref, accel[k], DT)
        err.append(torch.linalg.vector_norm(state[..., 0:2] - ref[..., 0:2], dim=-1))
        thrust_min = min(thrust_min, backend.rotor_thrusts.min())
        thrust_max = max(thrust_max, backend.rotor_thrusts.max())
        alt_err = max(alt_err, float(np.abs(backend.poses[..., 2] - backend.settings.altitude).max()))
    err = torch.stack(err)
    return {"rms": err.pow(2).mean().sqrt().item(), "max": err.max().item(), "thrust_min": thrust_min,
            "thrust_max": thrust_max, "alt_err": alt_err}
