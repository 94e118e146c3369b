"""Candidate V̂ models side by side on validation cells (issue 33: a V̂ that sees fast encounters).

    python scripts/vhat_candidates.py --out results/vhat_candidates \
        --candidate shipped=models/vhat.pt h04=training/vhat_h04/vhat.pt \
        --cell scaling:64:10 scaling:128:5 main:16:20 conflict_circle:16:20 [--seed 100] [--run madpinn]

Each cell ``STUDY:N:SCENARIOS`` runs ``python -m madpinn evaluate`` (the workflow's evaluate job)
with ``config.yaml`` and an overlay that puts the study on the validation seed with that many
scenarios, once per candidate (``--model vhat=PATH vs=models/vs.pt``); a cell whose Parquet
exists is not rerun, so the script resumes. It then prints one Markdown table: safety, safe
scenarios, cost ÷T over collision-free agents (the paper's definition) and over all agents,
safety at d ≤ 2r, each with its 95 % bootstrap interval over scenarios. Validation seeds only.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
from pathlib import Path

import pandas as pd
import yaml

from madpinn.config import load_config
from madpinn.evaluation.metrics import scenario_intervals, seed_summary

REPO = Path(__file__).resolve().parents[1]


def parse(argv):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--out", type=Path, required=True, help="folder of the per-cell Parquet files")
    p.add_argument("--candidate", nargs="+", required=True, metavar="NAME=PATH")
    p.add_argument("--cell", nargs="+", required=True, metavar="STUDY:N:SCENARIOS")
    p.add_argument("--seed", type=int, default=100)
    p.add_argument("--run", default="madpinn", help="method or variant evaluated (reads vhat and vs)")
    p.add_argument("--table-only", action="store_true", help="only tabulate the cells already there")
    args = p.parse_args(argv)
    if args.seed < 100:
        p.error("validation seeds only (>= 100): the protocol seeds 0-4 are never used to choose a model")
    args.candidate = dict(c.split("=", 1) for c in args.candidate)
    for name, path in args.candidate.items():
        if not (REPO / path).is_file():
            p.error(f"candidate {name}: no model file {path}")
    cells = []
    for c in args.cell:
        study, n, k = c.split(":")
        cells.append((study, int(n), int(k)))
    args.cell = cells
    return args


def overlay(cells, seed: int, folder: Path) -> Path:
    """A config overlay adding ``seed`` to each study of ``cells`` with its scenario count (the
    study's own seeds stay listed, so settings that name them stay valid; only ``seed`` runs)."""
    base = load_config([REPO / "config.yaml"])["studies"]
    studies = {}
    for study, _, k in cells:
        seeds = sorted(set(base[study]["seeds"]) | {seed})
        studies[study] = {"seeds": seeds, "scenarios": max(k, studies.get(study, {}).get("scenarios", 0))}
    path = folder / "validation_cells.yaml"
    path.write_text(yaml.safe_dump({"studies": studies}))
    return path


def cell_path(out: Path, name: str, study: str, n: int, k: int, seed: int) -> Path:
    return out / name / f"{study}_n{n}_k{k}_seed{seed}.parquet"


def run_cells(args) -> None:
    with tempfile.TemporaryDirectory() as tmp:
        for study, n, k in args.cell:
            ov = overlay([(study, n, k)], args.seed, Path(tmp))
            for name, model in args.candidate.items():
                path = cell_path(args.out, name, study, n, k, args.seed)
                if path.is_file():
                    continue
                path.parent.mkdir(parents=True, exist_ok=True)
                cmd = [sys.executable, "-m", "madpinn", "evaluate", "--config", "config.yaml", str(ov),
                       "--study", study, "--run", args.run, "--n-agents", str(n), "--seed", str(args.seed),
                       "--out", str(path), "--model", f"vhat={model}", "vs=models/vs.pt",
                       "--no-track", "--no-progress", "--threads", "1"]
                print(f"[{name}] {study} N={n} ({k} scenarios, seed {args.seed})", flush=True)
                subprocess.run(cmd, cwd=REPO, check=True)


def table(args) -> str:
    head = ["cell", "V̂", "safety", "safe sc.", "cost ÷T", "cost ÷T all", "safety d ≤ 2r"]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for study, n, k in args.cell:
        for name in args.candidate:
            path = cell_path(args.out, name, study, n, k, args.seed)
            if not path.is_file():
                continue
            df = pd.read_parquet(path)
            s, ci = seed_summary(df), scenario_intervals(df)
            pct = lambda m: f"{100 * s[m]:.1f} [{100 * ci[m + '_ci_lo']:.1f}, {100 * ci[m + '_ci_hi']:.1f}]"
            lines.append(f"| {study} N={n} ({k} sc.) | {name} | {pct('safety_rate')} | {pct('safe_scenarios')} | "
                         f"{s['cost_time_avg']:.3f} [{ci['cost_time_avg_ci_lo']:.3f}, {ci['cost_time_avg_ci_hi']:.3f}] | "
                         f"{s['cost_all_time_avg']:.3f} | {pct('safety_rate_2r')} |")
    return "\n".join(lines)


def main(argv=None) -> None:
    args = parse(argv)
    if not args.table_only:
        run_cells(args)
    print(table(args))


if __name__ == "__main__":
    main()
