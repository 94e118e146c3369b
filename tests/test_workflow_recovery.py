"""Crash recovery with the README command alone: `kill -9` of the snakemake process group during a
job and during MLflow logging, then the plain `snakemake -j2 <targets>` (default profile) finishes
with every output, one finished MLflow run per job, nothing running and nothing left to do."""

import os
import signal
import sqlite3
import subprocess
import time
from collections import Counter

import pytest
from mlflow.tracking import MlflowClient

from workflow_helpers import TINY, copy_repo, env_for, planned_jobs, run_in, snakemake_cmd, write_overlay

FILES = ("smoke.yaml", "tiny.yaml")
TARGETS = ("table_update_ablation",)


def _start(copy):
    log = open(copy / "killed_runs.log", "a")   # both killed starts
    cmd = snakemake_cmd("-j2", *TARGETS, "--configfile", "config.yaml", *FILES)
    return subprocess.Popen(cmd, cwd=copy, env=env_for(copy), stdout=log, stderr=subprocess.STDOUT,
                            start_new_session=True)


def _kill_when(proc, condition, timeout=600):
    t0 = time.monotonic()
    while not condition():
        assert proc.poll() is None, "the run ended before the kill"
        assert time.monotonic() - t0 < timeout, "condition never met"
        time.sleep(0.02)
    os.killpg(proc.pid, signal.SIGKILL)
    proc.wait()


def _running_mlflow_runs(copy) -> int:
    db = copy / "mlflow" / "mlflow.db"
    if not db.is_file():
        return 0
    try:
        with sqlite3.connect(f"file:{db}?mode=ro", uri=True, timeout=0.01) as con:
            return con.execute("SELECT count(*) FROM runs WHERE status = 'RUNNING'").fetchone()[0]
    except sqlite3.Error:  # locked or schema not created yet
        return 0


def _check_recovered(copy, expected_jobs: int):
    run_in(copy, "-j2", *TARGETS, configfiles=FILES)          # the README command, nothing added
    assert planned_jobs(run_in(copy, "-n", *TARGETS, configfiles=FILES)) == {}
    client = MlflowClient(f"sqlite:///{copy / 'mlflow' / 'mlflow.db'}")
    exp = client.get_experiment_by_name("madpinn-smoke")
    runs = client.search_runs([exp.experiment_id], max_results=1000)
    assert all(r.info.status == "FINISHED" for r in runs), [r.info.status for r in runs]
    counts = Counter(r.data.tags["madpinn.job"] for r in runs)
    assert set(counts.values()) == {1} and len(counts) == expected_jobs, counts


@pytest.fixture
def clone(tmp_path):
    copy = copy_repo(tmp_path / "clone")
    write_overlay(copy / "tiny.yaml", TINY)
    jobs = planned_jobs(run_in(copy, "-n", *TARGETS, configfiles=FILES))
    return copy, sum(jobs.values()) - jobs["tracking_init"]  # every other job logs one run


def test_kills_during_mlflow_logging_and_during_a_job_then_readme_command_recovers(clone):
    """Two crashes in a row, each followed by the plain README command: the first kill lands while
    the first job's live MLflow run is open (a RUNNING run and a half-written output are left);
    the restarted command gets past it and is killed in turn while the first evaluation job runs
    (the trainings are done, their runs logged); the third start finishes everything."""
    copy, expected = clone
    proc = _start(copy)
    _kill_when(proc, lambda: _running_mlflow_runs(copy) > 0)
    proc = _start(copy)                     # "the run ended before the kill" if it cannot recover
    evals = copy / "results" / "smoke" / "logs" / "evaluate"
    _kill_when(proc, lambda: evals.is_dir() and any(evals.rglob("*.log")))
    assert (copy / ".snakemake" / "incomplete").is_dir()
    _check_recovered(copy, expected)
