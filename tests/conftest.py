"""Shared fixtures: repository paths, configs, and a real-snakemake runner."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest
import torch

from madpinn.config import load_config

REPO = Path(__file__).resolve().parents[1]
SMOKE = REPO / "workflow" / "configs" / "smoke.yaml"


@pytest.fixture(autouse=True)
def isolated_tracking_uri():
    """A test that points MLflow at a store (``mlflow.set_tracking_uri`` exports
    ``MLFLOW_TRACKING_URI``) must not send later tests' subprocesses there."""
    import mlflow

    env = os.environ.get("MLFLOW_TRACKING_URI")
    yield
    mlflow.set_tracking_uri(env)
    if env is None:
        os.environ.pop("MLFLOW_TRACKING_URI", None)
    else:
        os.environ["MLFLOW_TRACKING_URI"] = env


@pytest.fixture
def one_thread():
    """Tiny tensors: one intra-op thread is fastest and keeps float reductions reproducible."""
    n = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(n)


@pytest.fixture(scope="session")
def paper_cfg() -> dict:
    return load_config([REPO / "config.yaml"])


@pytest.fixture(scope="session")
def smoke_cfg() -> dict:
    return load_config([REPO / "config.yaml", SMOKE])


def subprocess_env(extra: dict | None = None) -> dict:
    env = dict(os.environ)
    env["PYTHONPATH"] = str(REPO) + os.pathsep + env.get("PYTHONPATH", "")
    env.pop("MLFLOW_TRACKING_URI", None)
    env["MADPINN_LOG"] = "full"   # the workflow tests read Snakemake's per-job lines (madpinn/run_log.py)
    env.update(extra or {})
    return env


def run_snakemake(workdir: Path, *args: str, configfiles=(SMOKE,), env: dict | None = None, check=True):
    """Run the real workflow in ``workdir`` with the smoke overlay; returns CompletedProcess."""
    cmd = [
        sys.executable, "-m", "snakemake", "-s", str(REPO / "Snakefile"), "-d", str(workdir),
        "--configfile", str(REPO / "config.yaml"), *map(str, configfiles), *args,
    ]
    proc = subprocess.run(cmd, capture_output=True, text=True, env=subprocess_env(env), timeout=1800)
    if check and proc.returncode != 0:
        raise AssertionError(f"snakemake failed ({proc.returncode}):\n{proc.stdout[-4000:]}\n{proc.stderr[-6000:]}")
    return proc


# Longest files first, so that `pytest -n 3 --dist loadfile --no-loadscope-reorder` (README) starts
# them at once instead of leaving one to run alone at the end (xdist's default reorder would sort the
# files by their number of tests); order within a file is kept.
# test_shipped_faults.py takes 76 s since V̂'s calibration is restored too (1 009 s before, 2026-12-05).
LONG_FIRST = ("test_workflow.py", "test_workflow_recovery.py", "test_workflow_reruns.py", "test_mlflow_server.py",
              "test_workflow_profiles.py", "test_shipped_faults.py")


def pytest_collection_modifyitems(items):
    rank = {name: i for i, name in enumerate(LONG_FIRST)}
    items.sort(key=lambda item: rank.get(item.path.name, len(LONG_FIRST)))
