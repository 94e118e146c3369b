"""The scenario-law study's readings (issue 60 item 1): per cell, safety, load (straight-line
encounters per agent), the failure hazard per encounter with its 95 % scenario-bootstrap interval,
and the mean encounter speed; then the agents of all cells by encounter speed (collided share per
bin); last, per (study, N), the scenarios pooled over the seeds present: safety, the share of
collision-free scenarios and the paper's cost (collision-free agents) over the episode and ÷T. The
rule that reads them: docs/findings/2026-11-28-table-ii-readings-preregistered.md.

    PYTHONPATH=$PWD python scripts/scenario_law_readings.py results/scenario_laws/eval [--edges 0 1 2 3 4 6]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import pandas as pd

from madpinn.evaluation.encounter_hazard import cell_hazard, hazard_by_speed

R = 0.1   # agents.collision_radius (config.yaml), m


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("cells", type=Path, help="directory holding the cells' Parquet files (searched recursively)")
    ap.add_argument("--edges", type=float, nargs="+", default=[0, 1, 2, 3, 4, 6])
    args = ap.parse_args()
    files = sorted(args.cells.rglob("n*_seed*.parquet"))
    if not files:
        raise SystemExit(f"no cells under {args.cells}")
    rows, frames = [], []
    for f in files:
        df = pd.read_parquet(f)
        h = cell_hazard(df)
        rows.append({"study": f.parts[-3], "run": f.parts[-2], "cell": f.stem, **h,
                     "encounter_speed": float(np.nanmean(df["encounter_speed_mean"]))})
        frames.append(df)
    print(pd.DataFrame(rows).to_string(index=False, float_format=lambda v: f"{v:.4f}"))
    print()
    print(hazard_by_speed(pd.concat(frames, ignore_index=True), args.edges, R).to_string(index=False, float_format=lambda v: f"{v:.4f}"))
    print()
    cells = pd.concat([df.assign(study=f.parts[-3], run=f.parts[-2]) for f, df in zip(files, frames)], ignore_index=True)
    pooled = cells.groupby(["study", "run", "n_agents"]).agg(
        seeds=("seed", "nunique"), scenarios=("scenario", "size"), safety=("safety_rate", "mean"),
        safe_scenarios=("safe", "mean"), cost=("cost_safe_mean", "mean"), cost_per_s=("cost_safe_time_avg", "mean"))
    print(pooled.reset_index().to_string(index=False, float_format=lambda v: f"{v:.4f}"))


if __name__ == "__main__":
    main()
