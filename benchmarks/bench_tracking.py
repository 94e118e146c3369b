"""How fast does the simulated Crazyflie follow the policy's acceleration? (issue 14)

    PYTHONPATH=$PWD python benchmarks/bench_tracking.py [--config config.yaml] [--set gains.att_rp=40 ...]

Three measurements on the MuJoCo backend (``sim.mujoco`` of the config, ``--set`` overrides
``sim.mujoco`` keys), each beside the exact double integrator where it applies:

1. **Reversal**: from v = −1 m/s, hold +4 m/s² for 0.4 s, then −4 m/s²; the drone's planar
   acceleration (finite difference of its velocity at the physics rate) is read after the
   switch: time until it changes sign and until it reaches −2 m/s². Along x (one rotation
   axis) and along the diagonal (both axes ±4, 5.66 m/s²). The physical lower bound of the
   sign-change time (rotors bang-bang at 0 / f_max, tilt through zero) is printed beside it.
2. **Bang-bang velocity hold**: the policy ``u = −4 sign(v − 1 m/s)`` per axis at every
   ``sim.dt`` on the measured velocity, 2 s; the oscillation amplitude (half peak-to-peak of
   v over the last second), drone vs double integrator.
3. **Tracking RMS under bang-bang**: open-loop random bang-bang (±4 m/s² per axis, mean dwell
   0.02 s and 0.25 s, 16 drones, 3 s, seed 0): planar RMS error to the exact double integrator.
"""

from __future__ import annotations

import argparse
import json
import math

import numpy as np
import torch
import yaml

from madpinn.config import load_config
from madpinn.dynamics import DoubleIntegrator
from madpinn.simulation.mujoco import MujocoBackend, MujocoSettings
from madpinn.simulation.mujoco.model import GRAVITY


def _set(section: dict, dotted: str) -> None:
    key, value = dotted.split("=", 1)
    *parents, leaf = key.split(".")
    for p in parents:
        section = section.setdefault(p, {})
    section[leaf] = yaml.safe_load(value)


def make_backend(cfg: dict, overrides: list[str] = ()) -> tuple[MujocoBackend, DoubleIntegrator, float]:
    section = json.loads(json.dumps(cfg["sim"].get("mujoco") or {}))
    for o in overrides:
        _set(section, o)
    dyn = DoubleIntegrator(cfg["agents"]["u_max"], cfg["agents"]["v_max"])
    dt = float(cfg["sim"]["dt"])
    return MujocoBackend(dyn, dt, MujocoSettings.from_config(section), dtype=torch.float64), dyn, dt


def reversal(backend: MujocoBackend, dt: float, direction: np.ndarray, u: float = 4.0) -> dict:
    """Acceleration reversal +u → −u along ``direction`` (per-axis signs, e.g. (1, 0) or (1, 1));
    times (ms) after the switch until the drone's acceleration along it changes sign / reaches −2."""
    d = torch.tensor(direction, dtype=torch.float64).reshape(1, 1, 2)
    unit = d / d.norm()
    state = backend.reset(torch.zeros(1, 1, 2, dtype=torch.float64), -1.0 * d)
    for _ in range(int(round(0.4 / dt))):
        backend.command(u * d, dt)
        state = backend.step()
    h = backend.h
    v_prev = float((backend.qvel[0, 0:2] * unit[0, 0].numpy()).sum())
    t, t_sign, t_two, acc = 0.0, None, None, []
    backend.command(-u * d, dt)
    backend.settings  # substeps run inside step(); step the physics one substep at a time here
    for _ in range(int(round(0.2 / h))):
        backend._substep()
        t += h
        v = float((backend.qvel[0, 0:2] * unit[0, 0].numpy()).sum())
        a = (v - v_prev) / h
        v_prev = v
        acc.append(a)
        if t_sign is None and a < 0:
            t_sign = t
        if t_two is None and a <= -2.0:
            t_two = t
    return {"sign_change_ms": 1e3 * t_sign if t_sign else math.inf, "reach_minus2_ms": 1e3 * t_two if t_two else math.inf,
            "accel_before": float(u * float(d.norm())), "accel_after_200ms": float(np.mean(acc[-10:]))}


def sign_change_bound(backend: MujocoBackend, direction: np.ndarray, u: float = 4.0) -> float:
    """Lower bound (ms) on the time for the tilt to pass through zero from the steady tilt of
    the +u acceleration: rotors at 0 / f_max give the largest torque about the rotation axis,
    the body starts at rest (θ = ½ α t²)."""
    spec = backend.spec
    a = u * float(np.linalg.norm(direction))
    tilt = math.atan2(a, GRAVITY)
    xy = spec.rotor_positions
    axis = np.array([-direction[1], direction[0]], dtype=float)
    axis /= np.linalg.norm(axis)
    lever = np.abs(xy @ np.array([-axis[1], axis[0]]))  # distance of each rotor from the rotation axis
    torque = lever.sum() / 2 * spec.max_rotor_thrust  # half the rotors at f_max on one side, rest at 0
    inertia = float(np.asarray(spec.inertia)[0])     # ixx = iyy: the same about every planar axis
    return 1e3 * math.sqrt(2 * tilt / (torque / inertia))


def velocity_hold(backend: MujocoBackend, dyn: DoubleIntegrator, dt: float, target: float = 1.0, seconds: float = 2.0) -> dict:
    """Closed-loop bang-bang velocity hold on the drone and on the double integrator."""
    n = 4
    gen = torch.Generator().manual_seed(0)
    v0 = torch.rand(1, n, 2, generator=gen, dtype=torch.float64) * 0.5
    starts = torch.zeros(1, n, 2, dtype=torch.float64)
    out = {}
    for name in ("mujoco", "double_integrator"):
        state = backend.reset(starts, v0) if name == "mujoco" else torch.cat([starts, v0], -1)
        vs = []
        for _ in range(int(round(seconds / dt))):
            u = -dyn.u_max * torch.sign(state[..., 2:4] - target)
            if name == "mujoco":
                backend.command(u, dt)
                state = backend.step()
            else:
                state = dyn.step(state, u, dt)
            vs.append(state[..., 2:4].clone())
        last = torch.stack(vs[len(vs) // 2:])
        out[name] = float(((last.amax(0) - last.amin(0)) / 2).max())
    return out


def tracking_rms(backend: MujocoBackend, dyn: DoubleIntegrator, dt: float, mean_dwell: float, n: int = 16,
                 seconds: float = 3.0, seed: int = 0) -> float:
    rng = np.random.default_rng(seed)
    u = dyn.u_max
    cur = rng.choice([-u, u], size=(n, 2))
    zeros = torch.zeros(1, n, 2, dtype=torch.float64)
    state = backend.reset(zeros, zeros)
    ref = state.clone()
    err = []
    for _ in range(int(round(seconds / dt))):
        cur = np.where(rng.random((n, 2)) < dt / mean_dwell, -cur, cur)
        a = torch.from_numpy(cur).reshape(1, n, 2)
        backend.command(a, dt)
        state = backend.step()
        ref = dyn.step(ref, a, dt)
        err.append(torch.linalg.vector_norm(state[..., 0:2] - ref[..., 0:2], dim=-1))
    return float(torch.stack(err).pow(2).mean().sqrt())


def measure(cfg: dict, overrides: list[str] = ()) -> dict:
    backend, dyn, dt = make_backend(cfg, overrides)
    res = {}
    for name, direction in (("x", np.array([1.0, 0.0])), ("diagonal", np.array([1.0, 1.0]))):
        r = reversal(backend, dt, direction, dyn.u_max)
        r["sign_change_bound_ms"] = sign_change_bound(backend, direction, dyn.u_max)
        res[f"reversal_{name}"] = r
    res["velocity_hold_amplitude"] = velocity_hold(backend, dyn, dt)
    res["tracking_rms_m"] = {f"dwell_{d}": tracking_rms(backend, dyn, dt, d) for d in (0.02, 0.25)}
    return res


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--config", nargs="+", default=["config.yaml"])
    ap.add_argument("--set", nargs="*", default=[], help="sim.mujoco overrides, e.g. gains.att_rp=40")
    args = ap.parse_args()
    torch.set_num_threads(1)
    res = measure(load_config(args.config), args.set)
    for k in ("reversal_x", "reversal_diagonal"):
        r = res[k]
        print(f"{k}: sign change {r['sign_change_ms']:.1f} ms (physical bound {r['sign_change_bound_ms']:.1f} ms), "
              f"−2 m/s² after {r['reach_minus2_ms']:.1f} ms")
    h = res["velocity_hold_amplitude"]
    print(f"bang-bang velocity hold: ±{h['mujoco']:.3f} m/s (double integrator ±{h['double_integrator']:.3f} m/s)")
    t = res["tracking_rms_m"]
    print(f"bang-bang tracking RMS: {100 * t['dwell_0.02']:.2f} cm (dwell 0.02 s), {100 * t['dwell_0.25']:.2f} cm (dwell 0.25 s)")
    print(json.dumps(res))


if __name__ == "__main__":
    main()
