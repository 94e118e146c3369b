"""Start-up cost of a workflow job: what each ``python -m madpinn <command>`` pays before its work.

    python benchmarks/bench_job_startup.py [--repeats 5]

Every workflow job is a fresh Python process, so per-job imports multiply by the number of jobs
(42 in the smoke DAG, 264 in the paper protocol). Each probe runs in a fresh subprocess and times
its statement inside the process (interpreter start-up excluded; ``python -c pass`` is printed for
that); best of ``--repeats``. "MLflow client on a store" opens a client on an existing SQLite store
as a job's live run does (MLflow import + SQLAlchemy store set-up).
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
OPEN_STORE = "from mlflow.tracking import MlflowClient; MlflowClient(tracking_uri=URI).search_experiments()"

PROBES = {
    "interpreter (python -c pass), whole process": None,
    "command line parser (every job)": "from madpinn.commands import build_parser; build_parser()",
    "config load + validation (every job)":
        f"from madpinn.config import load_config; load_config([{str(REPO / 'config.yaml')!r}])",
    "import torch (evaluation, training jobs)": "import torch",
    "import mujoco (MuJoCo evaluation jobs)": "import mujoco",
    "import cvxpy (oracle jobs)": "import cvxpy",
    "import mlflow": "import mlflow",
    "MLflow client on a store (every tracked job)": OPEN_STORE,
}


def _time_in_process(stmt: str, uri: str) -> float:
    code = (f"import time; URI = {uri!r}; t0 = time.perf_counter()\n{stmt}\n"
            "print(time.perf_counter() - t0)")
    out = subprocess.run([sys.executable, "-c", code], cwd=REPO, capture_output=True, text=True, check=True)
    return float(out.stdout.strip().splitlines()[-1])


def _time_process() -> float:
    t0 = time.perf_counter()
    subprocess.run([sys.executable, "-c", "pass"], check=True)
    return time.perf_counter() - t0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=5)
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        uri = f"sqlite:///{Path(tmp) / 'mlflow.db'}"
        _time_in_process(OPEN_STORE, uri)   # creates the store's schema once
        print(f"{'probe':48s} best of {args.repeats} (s)")
        for name, stmt in PROBES.items():
            times = [(_time_process() if stmt is None else _time_in_process(stmt, uri)) for _ in range(args.repeats)]
            print(f"{name:48s} {min(times):.3f}")


if __name__ == "__main__":
    main()
