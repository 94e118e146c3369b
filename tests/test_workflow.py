"""The whole smoke DAG through real snakemake into a real MLflow store."""

import json
import re
from collections import Counter
from pathlib import Path

import pandas as pd
import pytest
from mlflow.tracking import MlflowClient

from conftest import REPO, SMOKE, run_snakemake


def _job_counts(workdir: Path) -> Counter:
    client = MlflowClient(f"sqlite:///{workdir / 'mlflow' / 'mlflow.db'}")
    exp = client.get_experiment_by_name("madpinn-smoke")
    runs = client.search_runs([exp.experiment_id], max_results=5000)
    assert all(r.info.status == "FINISHED" for r in runs)
    return Counter(r.data.tags["madpinn.job"] for r in runs)


@pytest.fixture(scope="module")
def smoke_run(tmp_path_factory):
    workdir = tmp_path_factory.mktemp("smoke")
    run_snakemake(workdir, "-j2", "all")
    return workdir


def _evaluation_cells(configfiles) -> int:
    """Evaluation jobs the config fans out to: runs × agent counts × seeds, summed over studies."""
    from madpinn.config import load_config

    cfg = load_config([REPO / "config.yaml", *configfiles])
    return sum(len(st["runs"]) * len(st["agent_counts"]) * len(st["seeds"]) for st in cfg["studies"].values())


def test_smoke_dag_produces_tables_and_one_run_per_job(smoke_run):
    figs = smoke_run / "results" / "smoke" / "paper_figures"
    for name in ("table_safety_scaling", "table_ours_scaling"):
        for ext in ("csv", "md", "tex"):
            assert (figs / f"{name}.{ext}").stat().st_size > 0
    for name in ("fig_cost_safety", "fig_trajectories"):
        for ext in ("pdf", "png"):
            assert (figs / f"{name}.{ext}").stat().st_size > 1000
    table = pd.read_csv(figs / "table_safety_scaling.csv")
    assert set(table["n_agents"]) == {3, 16}
    assert (table["n_seeds"] == 2).all()
    counts = _job_counts(smoke_run)
    evals = [k for k in counts if k.startswith("evaluate/")]
    assert len(evals) == _evaluation_cells([SMOKE]) and set(counts.values()) == {1}
    assert {"table/table_safety_scaling", "figure/fig_cost_safety", "figure/fig_trajectories"} <= set(counts)


def test_rerun_replaces_runs_without_duplicates(smoke_run):
    before = _job_counts(smoke_run)
    run_snakemake(smoke_run, "-j2", "all", "--forceall")
    after = _job_counts(smoke_run)
    assert after == before and set(after.values()) == {1}


def test_results_are_deterministic_across_reruns(smoke_run, tmp_path):
    """A fresh run with 4 parallel writers into a new store gives identical numbers."""
    run_snakemake(tmp_path, "-j4", "all")
    for f in sorted((smoke_run / "results" / "smoke" / "eval").rglob("*.parquet")):
        other = tmp_path / f.relative_to(smoke_run)
        pd.testing.assert_frame_equal(pd.read_parquet(f), pd.read_parquet(other))
    assert set(_job_counts(tmp_path).values()) == {1}


def test_single_table_target_rebuilds_alone(smoke_run):
    target = smoke_run / "results" / "smoke" / "paper_figures" / "table_ours_scaling.md"
    target.unlink()
    proc = run_snakemake(smoke_run, "-j1", "table_ours_scaling")
    assert target.is_file()
    assert "rule evaluate" not in proc.stdout + proc.stderr


def test_dry_run_of_paper_config_lists_the_full_fan_out(tmp_path):
    proc = run_snakemake(tmp_path, "-n", "-j2", "all", configfiles=())
    out = proc.stdout + proc.stderr
    m = re.search(r"^evaluate\s+(\d+)$", out, re.M)
    assert m and int(m.group(1)) == _evaluation_cells([])
    assert not (tmp_path / "mlflow").exists()


def test_invalid_config_fails_before_any_job(tmp_path):
    bad = tmp_path / "bad.yaml"
    bad.write_text("studies:\n  main:\n    scenarios: -3\n")
    proc = run_snakemake(tmp_path, "-j2", "all", configfiles=(SMOKE, bad), check=False)
    assert proc.returncode != 0
    assert "'studies.main.scenarios'" in proc.stderr
    assert not (tmp_path / "results" / "smoke" / "eval").exists()


def test_unreachable_tracking_server_stops_before_the_fan_out(tmp_path):
    proc = run_snakemake(tmp_path, "-j2", "all", env={"MLFLOW_TRACKING_URI": "http://127.0.0.1:9"}, check=False)
    assert proc.returncode != 0
    assert "unreachable" in proc.stdout + proc.stderr
    assert not list((tmp_path / "results" / "smoke").rglob("*.parquet"))
