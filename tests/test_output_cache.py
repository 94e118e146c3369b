"""Snakemake's between-workflow output cache (`--cache`, profiles/shipped): a cell computed in one
working directory is restored, not recomputed, in another that shares the cache; a changed setting
of the cell computes it anew; a dry run with the profile writes nothing."""

import re
import subprocess
import sys

import pandas as pd
import yaml

from conftest import REPO, run_snakemake, subprocess_env

CELL = "results/smoke/eval/mujoco/scaling/nominal/n64_seed0.parquet"
CACHED = ("--cache", "evaluate", "oracle", "oracle_pattern")


def _run(workdir, cache, *extra):
    return run_snakemake(workdir, "-j1", CELL, *CACHED, env={"SNAKEMAKE_OUTPUT_CACHE": str(cache)}, **({"configfiles": extra} if extra else {}))


def test_cell_is_restored_from_the_cache_in_another_directory_and_recomputed_when_its_settings_change(tmp_path):
    cache = tmp_path / "cache"
    cache.mkdir()
    first, second, third = (tmp_path / d for d in ("first", "second", "third"))
    out = _run(first, cache).stderr
    assert f"Moving output file {CELL} to cache" in out
    entries = sorted(p.name for p in cache.iterdir())
    assert [e.rsplit("_", 1)[-1] for e in entries] == ["parquet.parquet", "summary.json", "traj.npz"]

    out = _run(second, cache).stderr                      # same code, config and wildcards: restored
    assert f"Symlinking output file {CELL} from cache" in out and "Moving output file" not in out
    log = second / "results/smoke/logs/evaluate/mujoco/scaling/nominal/n64_seed0.log"
    assert not log.exists() or log.stat().st_size == 0       # the cell's command (it tees its output) never ran
    pd.testing.assert_frame_equal(pd.read_parquet(first / CELL), pd.read_parquet(second / CELL))

    overlay = tmp_path / "more_scenarios.yaml"                 # a setting the cell reads: a new entry
    overlay.write_text(yaml.safe_dump({"studies": {"scaling": {"scenarios": 3}}}))
    out = _run(third, cache, REPO / "workflow/configs/smoke.yaml", overlay).stderr
    assert f"Moving output file {CELL} to cache" in out
    assert len(pd.read_parquet(third / CELL)) == 3 and len(list(cache.iterdir())) == 6


def test_shipped_profile_dry_run_caches_cells_and_writes_nothing(tmp_path):
    """From the repository root, as README says (the profile's config files are relative to it);
    ``--forceall`` lists the whole DAG also in a checkout whose results/ already hold it."""
    oc = tmp_path / "oc"
    proc = subprocess.run([sys.executable, "-m", "snakemake", "-n", "-j2", "all", "--forceall", "--profile", "profiles/shipped"],
                          cwd=REPO, capture_output=True, text=True, timeout=600,
                          env={**subprocess_env(), "SNAKEMAKE_OUTPUT_CACHE": str(oc)})
    assert proc.returncode == 0, proc.stderr[-3000:]
    jobs = dict(re.findall(r"^(\w+)\s+(\d+)$", proc.stdout, re.M))
    assert "train_vhat" not in jobs and "train_vs" not in jobs and int(jobs["evaluate"]) > 200   # models from models/
    assert not oc.exists()
