"""Physics + controller time per drone-step of the MuJoCo Crazyflie backend.

    PYTHONPATH=$PWD python benchmarks/bench_mujoco.py [--config config.yaml] [--steps 200] [--repeats 3]
    PYTHONPATH=$PWD python benchmarks/bench_mujoco.py --compare-forces   # qfrc vs xfrc vs site actuators

For N ∈ {16, 256, 1024, 5120} drones in one backend (one job's S × N), times ``command`` +
``step`` (one ``sim.dt`` with ``sim.mujoco.substeps`` physics + controller substeps) under
bang-bang policy accelerations; prints best-of-``repeats`` µs per drone-step, then MuJoCo's bare
free-body step for reference. The last line is ``us_per_drone_step_at_5120: X``.
"""

from __future__ import annotations

import argparse
import time

import mujoco
import numpy as np
import torch

from madpinn.config import deep_merge, load_config
from madpinn.dynamics import DoubleIntegrator
from madpinn.simulation.mujoco import MujocoBackend, MujocoSettings, compile_world

COUNTS = (16, 256, 1024, 5120)


def time_backend(cfg: dict, count: int, steps: int, repeats: int, overrides: dict | None = None) -> float:
    """Best-of-``repeats`` µs per drone-step (command + step) for ``count`` drones."""
    settings = MujocoSettings.from_config(deep_merge(cfg["sim"].get("mujoco") or {}, overrides or {}))
    dyn = DoubleIntegrator(cfg["agents"]["u_max"], cfg["agents"]["v_max"])
    backend = MujocoBackend(dyn, cfg["sim"]["dt"], settings)
    gen = torch.Generator().manual_seed(0)
    starts = torch.rand(1, count, 2, generator=gen) * 2 - 1
    accel = (torch.randint(0, 2, (steps, 1, count, 2), generator=gen) * 2 - 1) * cfg["agents"]["u_max"]
    best = float("inf")
    for _ in range(repeats + 1):  # first round: warm-up (model compile, caches)
        backend.reset(starts, torch.zeros_like(starts))
        t0 = time.perf_counter()
        for k in range(steps):
            backend.command(accel[k].float(), backend.dt)
            backend.step()
        best = min(best, time.perf_counter() - t0)
    return 1e6 * best / (steps * count)


def time_bare_mujoco(cfg: dict, count: int, steps: int, repeats: int) -> float:
    """Best-of µs per drone per ``sim.dt`` of MuJoCo alone (same worlds and substeps, constant
    hover forces, no controller)."""
    settings = MujocoSettings.from_config(cfg["sim"].get("mujoco"))
    h = cfg["sim"]["dt"] / settings.substeps
    worlds = []
    for start in range(0, count, settings.drones_per_world):
        model = compile_world(min(settings.drones_per_world, count - start), h, settings.spec)
        data = mujoco.MjData(model)
        data.qfrc_applied.reshape(-1, 6)[:, 2] = settings.spec.mass * 9.81
        worlds.append((model, data))
    best = float("inf")
    for _ in range(repeats):
        t0 = time.perf_counter()
        for _ in range(steps * settings.substeps):
            for model, data in worlds:
                mujoco.mj_step(model, data)
        best = min(best, time.perf_counter() - t0)
    return 1e6 * best / (steps * count)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--config", nargs="+", default=["config.yaml"])
    ap.add_argument("--steps", type=int, default=200, help="sim steps timed per repeat")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--compare-forces", action="store_true", help="also time xfrc and site actuators")
    args = ap.parse_args()
    torch.set_num_threads(1)
    cfg = load_config(args.config)
    m = cfg["sim"].get("mujoco") or {}
    print(f"MuJoCo {mujoco.__version__}, dt = {cfg['sim']['dt']} s, substeps = {m.get('substeps')}, "
          f"force_application = {m.get('force_application')}, drones_per_world = {m.get('drones_per_world')}")
    if args.compare_forces:
        for count in (16, 64, 256, 1024):
            row = []
            for mode in ("qfrc", "xfrc", "site"):
                if mode == "site" and count > 1024:
                    continue
                us = time_backend(cfg, count, max(20, args.steps // 4), args.repeats,
                                  {"force_application": mode, "drones_per_world": count})
                row.append(f"{mode} {us:.3f}")
            print(f"forces N={count:5d} (one world): " + ", ".join(row) + "  us/drone-step")
    result = {}
    for count in COUNTS:
        result[count] = time_backend(cfg, count, args.steps, args.repeats)
        bare = time_bare_mujoco(cfg, count, args.steps, args.repeats)
        print(f"N={count:5d}: backend {result[count]:.3f} us/drone-step (MuJoCo alone {bare:.3f})", flush=True)
    print(f"us_per_drone_step_at_5120: {result[5120]:.3f}")


if __name__ == "__main__":
    main()
