"""The z search's distance to its floor measured paired: each cell run now, its floor rows timed just
before and just after it on the same host (issue 65).

    PYTHONPATH=$PWD:$PWD/benchmarks python benchmarks/zsearch_floor_paired.py \\
        --cell main/madpinn/8/100 --cell main/madpinn/16/100 --cell scaling/madpinn/64/100

:mod:`zsearch_floor` divides cells' CPU time, measured when they were computed (hours or days
earlier), by row costs measured now. On a shared cloud guest the same rows' cost moves by tens of
per cent between minutes and by more between days, so that ratio mixes the code's overhead with the
host's drift. Here both come from the same minutes: for each named cell (the workflow's job function,
:func:`madpinn.commands.evaluate.evaluate`, one thread, the shipped models, no tracking, validation
seeds ≥ 100) the V̂ row costs at the cell's batch are measured (best of ``--repeats``) right before
and right after the cell, and its floor (:func:`zsearch_floor.cell_floor_s` on the cell's
own ``policy_stats``) uses their mean. A cell that did not run the cold bisection is refused.

Prints one JSON line per cell (``cpu_s``, ``floor_s``, ``ratio``, ``drift``: the row cost after over
before, how far the host moved during the cell) and ``paired_cells_time_over_floor`` over all of them.
"""

from __future__ import annotations

import argparse
import json
import tempfile
from pathlib import Path

import torch

from gpu_cells import SHIPPED, append_jsonl, cell_spec, require_validation_seeds   # benchmarks/gpu_cells.py
from madpinn.commands.evaluate import evaluate
from madpinn.config import REPO_ROOT, load_config
from madpinn.value_functions import load_vhat
from madpinn.value_functions.z_search import bisection_steps
from zsearch_floor import cell_floor_s, ran_cold_bisection, row_costs_us   # benchmarks/zsearch_floor.py


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cell", type=cell_spec, action="append", required=True, help="study/run/N/seed (seed ≥ 100)")
    ap.add_argument("--scenarios", type=int, default=None, help="scenarios per cell (default: the study's, the protocol's batch)")
    ap.add_argument("--repeats", type=int, default=20)
    ap.add_argument("--z-tolerance", type=float, default=1e-3, help="methods.madpinn.z_tolerance (config.yaml: 1e-3)")
    ap.add_argument("--out", type=Path, default=None, help="also append the JSON lines here")
    args = ap.parse_args()
    require_validation_seeds(args.cell)
    torch.set_num_threads(1)
    cfg = load_config([REPO_ROOT / "config.yaml"])
    models = {k: REPO_ROOT / v for k, v in SHIPPED.items()}
    vhat = load_vhat(models["vhat"])
    steps = bisection_steps(args.z_tolerance)
    lines, cpu_total, floor_total = [], 0.0, 0.0
    for study, run, n, seed in args.cell:
        if args.scenarios:
            cfg["studies"][study]["scenarios"] = args.scenarios
        batch = n * int(cfg["studies"][study]["scenarios"])
        before = row_costs_us(vhat, batch, args.repeats)
        with tempfile.TemporaryDirectory() as tmp:
            s = evaluate(cfg, study, run, n, seed, Path(tmp) / "cell.parquet", models=models, progress=False,
                         track=False, device="cpu")
        after = row_costs_us(vhat, batch, args.repeats)
        stats = s.get("policy_stats") or {}
        if stats.get("vhat_evals_per_agent_step") is None or not ran_cold_bisection(stats, steps):
            raise SystemExit(f"{study}/{run}/{n}/{seed} did not run the cold bisection: no floor to compare with")
        floor_s = cell_floor_s(s, (before[0] + after[0]) / 2, (before[1] + after[1]) / 2, steps)
        cpu_total += s["cpu_s"]
        floor_total += floor_s
        line = {"cell": f"{study}/{run}/{n}/{seed}", "batch": batch, "cpu_s": round(s["cpu_s"], 2),
                "floor_s": round(floor_s, 2), "ratio": round(s["cpu_s"] / floor_s, 3),
                "value_row_us": [round(before[0], 3), round(after[0], 3)], "drift": round(after[0] / before[0], 3)}
        lines.append(line)
        print(json.dumps(line), flush=True)
    print(f"paired_cells_core_h: {cpu_total / 3600:.4f}")
    print(f"paired_cells_time_over_floor: {cpu_total / floor_total:.2f}")
    if args.out:
        append_jsonl(args.out, lines)


if __name__ == "__main__":
    main()
