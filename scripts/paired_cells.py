"""Paired comparison of evaluation cells that ran the same scenarios (same study, N and seed).

    python scripts/paired_cells.py A.parquet B.parquet [A2.parquet B2.parquet ...]

For each pair (A, B), prints one Markdown row: N, the scenario seed, safety and safe scenarios of A / B, the
time-averaged cost of A / B over collision-free agents (the paper's cost) and over all agents, the
paired per-scenario difference A − B (mean ± standard error over scenarios) of the safety rate
(points) and of both costs, the share of scenarios where A's all-agent cost is higher by more than
0.01, the mean final distance to goal of A / B (m), and the policy
time per agent-step of A / B (from each cell's JSON beside its Parquet, when present). It checks
that the pair's cells hold the same scenarios, agent count and seed, and refuses otherwise.
"""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path

import pandas as pd


COST_STEP = 0.01   # a scenario counts as costlier for A when its all-agent cost ÷T exceeds B's by more


def _cell(path: Path) -> tuple[pd.DataFrame, dict]:
    frame = pd.read_parquet(path).sort_values("scenario").reset_index(drop=True)
    summary = path.with_suffix(".json")
    return frame, (json.loads(summary.read_text()) if summary.is_file() else {})


def _diff(a: pd.Series, b: pd.Series, scale: float = 1.0) -> str:
    d = (a.to_numpy() - b.to_numpy()) * scale
    se = d.std(ddof=1) / math.sqrt(len(d)) if len(d) > 1 else float("nan")
    return f"{d.mean():+.3f} ± {se:.3f}"


def row(path_a: Path, path_b: Path) -> str:
    a, ja = _cell(path_a)
    b, jb = _cell(path_b)
    for key in ("scenario", "n_agents", "seed"):
        if not a[key].equals(b[key]):
            raise SystemExit(f"{path_a} and {path_b} differ in '{key}': not the same scenarios")
    n = int(a["n_agents"].iloc[0])
    policy = " / ".join(f"{j['policy_us_per_agent_step']:.0f}" if "policy_us_per_agent_step" in j else "–" for j in (ja, jb))
    return (f"| {n} | {int(a['seed'].iloc[0])} | {100 * a.safety_rate.mean():.1f} % / {100 * b.safety_rate.mean():.1f} % "
            f"({100 * a.safe.mean():.0f} / {100 * b.safe.mean():.0f} % safe sc.) "
            f"| {a.cost_safe_time_avg.mean():.3f} / {b.cost_safe_time_avg.mean():.3f} "
            f"| {a.cost_all_time_avg.mean():.3f} / {b.cost_all_time_avg.mean():.3f} "
            f"| {_diff(a.safety_rate, b.safety_rate, 100.0)} | {_diff(a.cost_safe_time_avg, b.cost_safe_time_avg)} "
            f"| {_diff(a.cost_all_time_avg, b.cost_all_time_avg)} "
            f"| {100 * (a.cost_all_time_avg.to_numpy() - b.cost_all_time_avg.to_numpy() > COST_STEP).mean():.0f} % "
            f"| {a.final_distance_mean.mean():.3f} / {b.final_distance_mean.mean():.3f} "
            f"| {policy} | {len(a)} |")


def main(argv: list[str]) -> None:
    if not argv or len(argv) % 2:
        raise SystemExit(__doc__)
    print("| N | seed | safety A / B (safe scenarios) | cost ÷T A / B | cost ÷T, all agents, A / B | safety A − B (points) "
          "| cost ÷T A − B | all agents A − B | A costlier (scenarios) | final distance A / B (m) "
          "| policy µs per agent-step A / B | scenarios |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|")
    for i in range(0, len(argv), 2):
        print(row(Path(argv[i]), Path(argv[i + 1])))


if __name__ == "__main__":
    main(sys.argv[1:])
