"""Acceleration-tracking response of the simulated Crazyflie (issue 14): how fast the drone
follows the policy's acceleration, and the physical bound on it.

Used by ``benchmarks/bench_tracking.py`` (figures in docs/reference/mujoco.md) and the tracking tests.
All functions drive a real :class:`~madpinn.simulation.mujoco.backend.MujocoBackend`.
"""

from __future__ import annotations

import math

import numpy as np
import torch

from madpinn.dynamics import AgentModel
from madpinn.simulation.mujoco.backend import MujocoBackend
from madpinn.simulation.mujoco.model import GRAVITY, HORIZONTAL


def reversal(backend: MujocoBackend, direction, u: float = 4.0, v0: float = -1.0, hold_s: float = 0.4,
             after_s: float = 0.2) -> dict:
    """Acceleration reversal +u → −u per axis along ``direction`` (per-axis signs, e.g. (1, 0) or
    (1, 1)) for one drone starting at velocity ``v0·direction`` (m/s). After ``hold_s`` s of +u
    the command flips; the drone's acceleration along the direction (finite difference of its
    velocity at the physics rate) gives the times (ms) until it changes sign and until it
    reaches −2 m/s². Also returns the largest rotor thrust seen (N)."""
    d = torch.tensor(np.asarray(direction, dtype=float)).reshape(1, 1, -1)   # [1, 1, d] on the model's axes
    unit = (d / d.norm()).reshape(-1).numpy()
    dt = backend.dt
    backend.reset(torch.zeros_like(d), v0 * d)
    for _ in range(int(round(hold_s / dt))):
        backend.command(u * d, dt)
        backend.step()
    h = backend.h
    v_prev = float(backend.qvel[0, HORIZONTAL] @ unit)
    t, t_sign, t_two, thrust_max = 0.0, math.inf, math.inf, 0.0
    backend.command(-u * d, dt)
    for _ in range(int(round(after_s / h))):   # one physics substep at a time (the backend's own substep)
        backend._substep()
        t += h
        v = float(backend.qvel[0, HORIZONTAL] @ unit)
        a, v_prev = (v - v_prev) / h, v
        thrust_max = max(thrust_max, float(backend.thrusts.max()))
        if t_sign == math.inf and a < 0:
            t_sign = t
        if t_two == math.inf and a <= -2.0:
            t_two = t
    return {"sign_change_ms": 1e3 * t_sign, "reach_minus2_ms": 1e3 * t_two, "rotor_thrust_max": thrust_max}


def sign_change_bound_ms(backend: MujocoBackend, direction, u: float = 4.0) -> float:
    """Approximate lower bound (ms) on the sign-change time of :func:`reversal`: the tilt of the
    +u acceleration (atan(|a|/g)) must pass through zero; with the body at rest and the rotors
    at f_max on one side of the rotation axis and 0 on the other (the largest torque the rotor
    limits allow), θ = ½ α t². Ignores the thrust needed to hold altitude, so it is optimistic."""
    spec = backend.spec
    direction = np.asarray(direction, dtype=float)
    tilt = math.atan2(u * float(np.linalg.norm(direction)), GRAVITY)
    heading = direction / np.linalg.norm(direction)          # the tilt rotates about the axis ⟂ to it
    lever = np.abs(spec.rotor_positions @ heading)            # rotor distances from that axis
    torque = 0.5 * lever.sum() * spec.max_rotor_thrust        # rotors on one side at f_max, others at 0
    alpha = torque / float(spec.inertia[0])                   # ixx = iyy: the same about every planar axis
    return 1e3 * math.sqrt(2.0 * tilt / alpha)


def velocity_hold(backend: MujocoBackend, dynamics: AgentModel, target: float = 1.0, seconds: float = 2.0,
                  n: int = 4, seed: int = 0) -> dict:
    """Closed-loop bang-bang velocity hold ``u = −u_max·sign(v − target)`` per axis at every
    ``dt``, for the drone (``mujoco``: the policy sees the measured velocity), the drone with the
    policy closing its loop on the setpoint velocity v_d instead (``mujoco_on_setpoint``; the
    drone's own velocity is measured) and the exact double integrator; returns the oscillation
    amplitude of the measured velocity (m/s, half peak-to-peak over the last half, worst drone
    and axis)."""
    dt = backend.dt
    gen = torch.Generator().manual_seed(seed)
    v0 = torch.rand(1, n, 2, generator=gen, dtype=torch.float64) * 0.5
    starts = torch.zeros(1, n, 2, dtype=torch.float64)
    out = {}
    for name in ("mujoco", "mujoco_on_setpoint", "double_integrator"):
        state = backend.reset(starts, v0) if name != "double_integrator" else dynamics.join(starts, v0)
        vs = []
        for _ in range(int(round(seconds / dt))):
            seen = (torch.from_numpy(dynamics.velocity(backend.reference)).reshape(1, n, -1) if name == "mujoco_on_setpoint"
                    else dynamics.velocity(state))
            u = -dynamics.u_max * torch.sign(seen - target)
            if name == "double_integrator":
                state = dynamics.step(state, u, dt)
            else:
                backend.command(u, dt)
                state = backend.step()
            vs.append(dynamics.velocity(state).clone())
        last = torch.stack(vs[len(vs) // 2:])
        out[name] = float(((last.amax(0) - last.amin(0)) / 2).max())
    return out


def bang_bang_tracking(backend: MujocoBackend, dynamics: AgentModel, mean_dwell_s: float, n: int = 16,
                       seconds: float = 3.0, seed: int = 0) -> dict:
    """Open-loop random bang-bang (±u_max per axis, flipping with probability dt / mean_dwell_s
    per step) from rest: planar RMS / max error (m) to the exact double integrator, largest
    rotor thrust (N) and altitude error (m)."""
    dt = backend.dt
    rng = np.random.default_rng(seed)
    cur = rng.choice([-dynamics.u_max, dynamics.u_max], size=(n, 2))
    zeros = torch.zeros(1, n, 2, dtype=torch.float64)
    state = backend.reset(zeros, zeros)
    ref = state.clone()
    err, thrust_min, thrust_max, alt = [], math.inf, 0.0, 0.0
    for _ in range(int(round(seconds / dt))):
        cur = np.where(rng.random((n, 2)) < dt / mean_dwell_s, -cur, cur)
        a = torch.from_numpy(cur).reshape(1, n, -1)
        backend.command(a, dt)
        state = backend.step()
        ref = dynamics.step(ref, a, dt)
        err.append(torch.linalg.vector_norm(dynamics.position(state) - dynamics.position(ref), dim=-1))
        thrust_min = min(thrust_min, float(backend.thrusts.min()))
        thrust_max = max(thrust_max, float(backend.thrusts.max()))
        alt = max(alt, float(np.abs(backend.qpos[:, 2] - backend.settings.altitude).max()))
    err = torch.stack(err)
    return {"rms": float(err.pow(2).mean().sqrt()), "max": float(err.max()), "thrust_min": thrust_min,
            "thrust_max": thrust_max, "alt_err": alt}
