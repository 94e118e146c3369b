"""One study's cells on either backend, from given model files, without the workflow: separates the
drones' tracking (MuJoCo) from the value functions (the double integrator V̂ was trained on).

    PYTHONPATH=$PWD python scripts/backend_probe.py --config config.yaml workflow/configs/shipped.yaml \
        workflow/configs/collision_readings.yaml workflow/configs/reading_2r.yaml \
        --model vhat=models/reading_2r/vhat.pt vs=models/reading_2r/vs.pt \
        --study main --runs madpinn madpinn-lookahead --agents 12 16 --seed 100 \
        --backends double_integrator mujoco [--contacts false]

Prints safety, safe scenarios, cost ÷T and, for collided agents, when they first collided (s).
Validation seeds only (≥ 100): this is a diagnostic, not a protocol cell.
"""
from __future__ import annotations

import argparse

import numpy as np

from madpinn.config import load_config
from madpinn.evaluation.cell import CellSettings, run_cell


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--config", nargs="+", required=True)
    p.add_argument("--model", nargs="+", default=[], metavar="NAME=PATH")
    p.add_argument("--study", required=True)
    p.add_argument("--runs", nargs="+", required=True)
    p.add_argument("--agents", nargs="+", type=int, required=True)
    p.add_argument("--seed", type=int, default=100)
    p.add_argument("--backends", nargs="+", default=["double_integrator", "mujoco"])
    p.add_argument("--contacts", choices=["true", "false"], help="override sim.contacts of the study")
    a = p.parse_args()
    if a.seed < 100:
        p.error("validation seeds only (≥ 100); the protocol seeds 0–4 are for the workflow's cells")
    cfg = load_config(a.config)
    if a.contacts is not None:
        cfg["sim"]["contacts"] = a.contacts == "true"
        cfg["studies"][a.study].get("sim", {}).pop("contacts", None)
    models = dict(m.split("=", 1) for m in a.model)
    print(f"collision radius {cfg['agents']['collision_radius']} m, study {a.study}, seed {a.seed}")
    for backend in a.backends:
        for run in a.runs:
            cs = CellSettings.from_config(cfg, a.study, run)
            for n in a.agents:
                c = run_cell(cs, n, a.seed, models=models, backend=backend, progress=False)
                t = c.trajectory
                times = np.sort(np.asarray(t.first_collision_step)[np.asarray(t.collided)] * cs.sim.dt)
                print(f"{backend:18s} {run:20s} N={n:3d} contacts={cs.sim.contacts!s:5s} "
                      f"safety {100 * c.summary['safety_rate']:5.1f} %  safe sc. {100 * c.summary['safe_scenarios']:5.1f} %  "
                      f"cost/T {c.summary['cost_time_avg']:.3f}  first collisions (first batch, s): "
                      f"{np.round(times, 2).tolist() if len(times) else '-'}", flush=True)


if __name__ == "__main__":
    main()
