"""What a snakemake start costs: every dry run, every run and every Slurm job step (the plugin's
job step parses the whole workflow before it runs its job) plans the workflow, so planning
imports neither torch nor MuJoCo nor MLflow (≈ 2 s CPU per start otherwise:
docs/reference/performance.md)."""

from __future__ import annotations

import subprocess
import sys

from conftest import REPO, SMOKE, subprocess_env

HEAVY = ("torch", "mujoco", "mlflow", "cvxpy")
PROBE = ("import atexit, sys\n"
         f"atexit.register(lambda: print('heavy:', *(m for m in {HEAVY!r} if m in sys.modules)))\n"
         "from snakemake.cli import main\n"
         "main(sys.argv[1:])\n")


def test_planning_the_workflow_imports_no_heavy_library(tmp_path):
    cmd = [sys.executable, "-c", PROBE, "-s", str(REPO / "Snakefile"), "-d", str(tmp_path), "-n", "all",
           "--configfile", str(REPO / "config.yaml"), str(SMOKE)]
    proc = subprocess.run(cmd, capture_output=True, text=True, env=subprocess_env(), timeout=600)
    assert proc.returncode == 0 and "Job stats:" in proc.stdout + proc.stderr, proc.stderr[-4000:]
    heavy = [ln for ln in proc.stdout.splitlines() if ln.startswith("heavy:")]
    assert heavy == ["heavy:"], heavy
