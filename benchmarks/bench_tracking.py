"""How fast does the simulated Crazyflie follow the policy's acceleration? (issue 14)

    PYTHONPATH=$PWD python benchmarks/bench_tracking.py [--config config.yaml] [--set gains.att_rp=40 ...]

Measurements of :mod:`madpinn.simulation.mujoco.response` on the MuJoCo backend (``sim.mujoco``
of the config; ``--set`` overrides ``sim.mujoco`` keys, e.g. ``thrust_to_weight=4.5``):

1. reversal +4 → −4 m/s² along x and along the diagonal, from v = −1 m/s after 0.4 s of +4:
   time until the drone's acceleration changes sign and until it reaches −2 m/s², beside the
   approximate physical bound of the sign change (rotors bang-bang, body at rest);
2. bang-bang velocity hold ``u = −4 sign(v − 1)`` at every ``sim.dt``: oscillation amplitude,
   drone vs exact double integrator;
3. open-loop random bang-bang (mean dwell 0.02 s and 0.25 s, 16 drones, 3 s, seed 0): planar RMS
   error to the exact double integrator.

Deterministic (no timing); the last line is JSON.
"""

from __future__ import annotations

import argparse
import copy
import json

import torch
import yaml

from madpinn.config import load_config
from madpinn.dynamics import DoubleIntegrator
from madpinn.simulation.mujoco import MujocoBackend, MujocoSettings
from madpinn.simulation.mujoco.response import bang_bang_tracking, reversal, sign_change_bound_ms, velocity_hold


def make_backend(cfg: dict, overrides=()) -> tuple[MujocoBackend, DoubleIntegrator]:
    section = copy.deepcopy(cfg["sim"].get("mujoco") or {})
    for item in overrides:
        key, _, value = item.partition("=")
        *parents, leaf = key.split(".")
        node = section
        for p in parents:
            node = node.setdefault(p, {})
        node[leaf] = yaml.safe_load(value)
    dyn = DoubleIntegrator(cfg["agents"]["u_max"], cfg["agents"]["v_max"])
    return MujocoBackend(dyn, float(cfg["sim"]["dt"]), MujocoSettings.from_config(section), dtype=torch.float64), dyn


def measure(cfg: dict, overrides=()) -> dict:
    backend, dyn = make_backend(cfg, overrides)
    res = {}
    for name, direction in (("x", (1.0, 0.0)), ("diagonal", (1.0, 1.0))):
        res[f"reversal_{name}"] = {**reversal(backend, direction, dyn.u_max),
                                   "sign_change_bound_ms": sign_change_bound_ms(backend, direction, dyn.u_max)}
    res["velocity_hold_amplitude"] = velocity_hold(backend, dyn)
    res["tracking"] = {f"dwell_{d}": bang_bang_tracking(backend, dyn, d) for d in (0.02, 0.25)}
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
        print(f"{k}: sign change {r['sign_change_ms']:.1f} ms (physical bound ≈ {r['sign_change_bound_ms']:.1f} ms), "
              f"−2 m/s² after {r['reach_minus2_ms']:.1f} ms")
    h = res["velocity_hold_amplitude"]
    print(f"bang-bang velocity hold: ±{h['mujoco']:.3f} m/s (loop closed on the setpoint: ±{h['mujoco_on_setpoint']:.3f}; "
          f"double integrator ±{h['double_integrator']:.3f} m/s)")
    t = res["tracking"]
    print(f"bang-bang tracking RMS: {100 * t['dwell_0.02']['rms']:.2f} cm (dwell 0.02 s), {100 * t['dwell_0.25']['rms']:.2f} cm (dwell 0.25 s)")
    print(json.dumps(res))


if __name__ == "__main__":
    main()
