"""Overhead of live MLflow logging in a training loop (embedded SQLite store in a temp directory).

    python benchmarks/bench_mlflow.py [--iterations 60000] [--every 60] [--flush-every-s 10]

Prints: the per-iteration cost of the V̂ training callback (``run.curve("loss", every)``, one
call per iteration, a window mean logged every ``every``), the per-iteration cost of the PPO
callback (9 curves logged every iteration), and the time to open and to close a run (closing
sends the buffered points, sets the status and purges the replaced run of the job).
"""

from __future__ import annotations

import argparse
import tempfile
import time
from dataclasses import replace
from pathlib import Path

from madpinn.config import REPO_ROOT, load_config
from madpinn.tracking import TrackingSettings, job_run


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--iterations", type=int, default=60000)
    ap.add_argument("--every", type=int, default=60)
    ap.add_argument("--ppo-iterations", type=int, default=550)
    ap.add_argument("--flush-every-s", type=float, default=10.0)
    args = ap.parse_args()
    cfg = load_config([REPO_ROOT / "config.yaml"])
    with tempfile.TemporaryDirectory() as tmp:
        settings = replace(TrackingSettings.from_config(cfg), uri=f"sqlite:///{Path(tmp) / 'mlflow.db'}",
                           experiment="bench-tracking", pending_dir=Path(tmp) / "pending", flush_every_s=args.flush_every_s)
        with job_run(settings, job_key="bench/warmup", rule="bench"):
            pass                                      # store creation (schema) outside the timings
        for key in ("bench/vhat", "bench/vhat"):      # second pass: also purges the first run
            t0 = time.perf_counter()
            run = job_run(settings, job_key=key, rule="bench").__enter__()
            t_open = time.perf_counter() - t0
            curve = run.curve("loss", args.every)
            t0 = time.perf_counter()
            for it in range(1, args.iterations + 1):
                curve(it, 1.0 / it)
            t_loop = time.perf_counter() - t0
            t0 = time.perf_counter()
            run.__exit__(None, None, None)
            t_close = time.perf_counter() - t0
        print(f"V̂-style curve: {1e6 * t_loop / args.iterations:.2f} µs/iteration over {args.iterations} iterations "
              f"({args.iterations // args.every} points, flush every {args.flush_every_s} s); "
              f"open {1e3 * t_open:.0f} ms, close+purge {1e3 * t_close:.0f} ms")
        keys = [f"curve_{i}" for i in range(9)]
        with job_run(settings, job_key="bench/ppo", rule="bench") as run:
            t0 = time.perf_counter()
            for it in range(args.ppo_iterations):
                run.log_metrics({k: float(it) for k in keys}, step=it)
            t_ppo = time.perf_counter() - t0
        print(f"PPO-style curves: {1e6 * t_ppo / args.ppo_iterations:.1f} µs/iteration (9 metrics, "
              f"{args.ppo_iterations} iterations)")


if __name__ == "__main__":
    main()
