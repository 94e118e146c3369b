"""Evaluation cells on a GPU against the same cells on the CPU (issue 65 items 2-3): the prepared
measurement for a lent device.

Runs each named cell through the workflow's job function (:func:`madpinn.commands.evaluate.evaluate`,
shipped models, no tracking) on every device of ``--devices``, and prints one JSON line per run:
the device, wall time ``elapsed_s``, process CPU time ``cpu_s``, policy µs per agent-step, and the
cell's figures (safety, safe scenarios, cost ÷ T), then for each cell its figures' differences
between devices. GPU and CPU cells are keyed apart in the output cache (``madpinn.machine.planned_device``),
so the comparison states how far they differ; it decides nothing about which is kept.

    # on a lent GPU (one command, well under 10 minutes with --scenarios 2):
    PYTHONPATH=$PWD python benchmarks/gpu_cells.py --devices cuda cpu --scenarios 2 \\
        --cell scaling/madpinn/256/100 --cell large_arena_frontier/madpinn-carrot05vmaxh/256/100 --out $OUT/gpu_cells.jsonl
    # on the CPU (what CI can run): a small cell
    PYTHONPATH=$PWD python benchmarks/gpu_cells.py --devices cpu --scenarios 1 --cell main/madpinn/12/100

``--scenarios`` shortens each cell (the protocol's are 10 in the large arena); the seeds are
validation seeds (≥ 100). Cells of Table II's study ``scaling`` on seed 100 are not protocol cells.
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path

from madpinn.commands.evaluate import evaluate
from madpinn.config import REPO_ROOT, load_config

FIGURES = ("safety_rate", "safe_scenarios", "cost_time_avg", "encounter_speed_mean")
SHIPPED = {"vhat": "models/vhat.pt", "vs": "models/vs.pt"}


def cell_spec(text: str) -> tuple[str, str, int, int]:
    """``study/run/N/seed`` -> its parts."""
    try:
        study, run, n, seed = text.split("/")
        return study, run, int(n), int(seed)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(f"a cell is study/run/N/seed, got '{text}'") from exc


def require_validation_seeds(cells) -> None:
    """Stop, before any cell runs, when a ``cell_spec`` names a protocol seed (< 100)."""
    for _study, _run, _n, seed in cells:
        if seed < 100:
            raise SystemExit(f"validation seeds only (≥ 100), got {seed}")


def append_jsonl(path: Path, lines: list[dict]) -> None:
    """Append ``lines`` to ``path`` as JSON lines (its folder made if missing)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "a") as fh:
        fh.writelines(json.dumps(x) + "\n" for x in lines)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cell", type=cell_spec, action="append", required=True, help="study/run/N/seed (seed ≥ 100)")
    ap.add_argument("--devices", nargs="+", choices=("cpu", "cuda"), default=["cuda", "cpu"])
    ap.add_argument("--scenarios", type=int, default=None, help="scenarios per cell (default: the study's)")
    ap.add_argument("--out", type=Path, default=None, help="also append the JSON lines here")
    args = ap.parse_args()
    require_validation_seeds(args.cell)
    cfg = load_config([REPO_ROOT / "config.yaml"])
    models = {k: REPO_ROOT / v for k, v in SHIPPED.items()}
    lines = []
    for study, run, n, seed in args.cell:
        if args.scenarios:
            cfg["studies"][study]["scenarios"] = args.scenarios
        figures = {}
        for device in args.devices:
            with tempfile.TemporaryDirectory() as tmp:
                t0 = time.perf_counter()
                s = evaluate(cfg, study, run, n, seed, Path(tmp) / "cell.parquet", models=models, progress=False,
                             track=False, device=device)
                wall = time.perf_counter() - t0
            figures[device] = {k: s.get(k) for k in FIGURES}
            line = {"cell": f"{study}/{run}/{n}/{seed}", "scenarios": s["n_scenarios"], "device": s["device"],
                    "job_wall_s": round(wall, 2), "elapsed_s": round(s["elapsed_s"], 2), "cpu_s": round(s["cpu_s"], 2),
                    "policy_us_per_agent_step": round(s["policy_us_per_agent_step"], 2), **figures[device]}
            lines.append(line)
            print(json.dumps(line), flush=True)
        if len(figures) > 1:
            a, b = args.devices[:2]
            diff = {k: (figures[a][k] - figures[b][k]) if None not in (figures[a][k], figures[b][k]) else None for k in FIGURES}
            line = {"cell": f"{study}/{run}/{n}/{seed}", "difference": f"{a} - {b}", **diff}
            lines.append(line)
            print(json.dumps(line), flush=True)
    if args.out:
        append_jsonl(args.out, lines)


if __name__ == "__main__":
    main()
