"""Time one evaluation cell of the paper protocol (default: nominal, 16 agents x 100 scenarios,
small arena, 1200 steps of 2.5 ms) through the same code path as the workflow job.

    python benchmarks/bench_evaluation.py [--run nominal] [--n-agents 16] [--threads 1]
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

from madpinn.config import REPO_ROOT, load_config
from madpinn.commands.args import parse_models
from madpinn.commands.evaluate import evaluate


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--run", default="nominal")
    ap.add_argument("--study", default="main")
    ap.add_argument("--n-agents", type=int, default=16)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--model", action="append", default=[], metavar="NAME=PATH",
                    help="trained files of the run, e.g. --model vhat=results/models/vhat.pt --model vs=results/models/vs.pt")
    args = ap.parse_args()
    cfg = load_config([REPO_ROOT / "config.yaml"])
    best = float("inf")
    with tempfile.TemporaryDirectory() as tmp:
        for _ in range(args.repeats):
            t0 = time.perf_counter()
            s = evaluate(cfg, args.study, args.run, args.n_agents, args.seed, Path(tmp) / "x.parquet",
                         models=parse_models(args.model), threads=args.threads, progress=False, track=False)
            best = min(best, time.perf_counter() - t0)
    scen = cfg["studies"][args.study]["scenarios"]
    agent_steps = scen * args.n_agents * s["n_steps"]
    print(f"run={args.run} N={args.n_agents} scenarios={scen} steps={s['n_steps']} threads={args.threads}")
    print(f"safety_rate={s['safety_rate']:.4f} safe_scenarios={s['safe_scenarios']:.2f} cost={s['cost']:.3f}")
    print(f"us_per_agent_step: {1e6 * best / agent_steps:.3f}")
    print(f"wall_s_best_of_{args.repeats}: {best:.2f}")


if __name__ == "__main__":
    main()
