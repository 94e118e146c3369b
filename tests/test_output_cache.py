"""Snakemake's between-workflow output cache (`--cache`, profiles/shipped): a cell computed in one
working directory is restored, not recomputed, in another that shares the cache, and is an MLflow
run there too (restored=true, the computed run's params and metrics); a changed setting of the
cell computes it anew; nothing is stored onto an existing entry; a dry run with the profile writes
nothing; an entry is checked as one unit (madpinn/output_cache.py)."""

import json
import os
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


def _track_cells(workdir):
    """The rule track_cells' command for the one cell (the rule itself needs every cell of `all`)."""
    proc = subprocess.run([sys.executable, "-m", "madpinn", "track-cells", "--config", "results/smoke/config.resolved.yaml",
                           "--cells", CELL, "--out", "results/smoke/tracking/cells.json"], cwd=workdir, capture_output=True,
                          text=True, timeout=600, env=subprocess_env({"MADPINN_TRACKING_SOURCE": "workflow"}))
    assert proc.returncode == 0, proc.stderr[-3000:]
    return json.loads((workdir / "results/smoke/tracking/cells.json").read_text())


def _cell_run(workdir):
    from mlflow.tracking import MlflowClient

    client = MlflowClient(f"sqlite:///{workdir / 'mlflow' / 'mlflow.db'}")
    exp = client.get_experiment_by_name("madpinn-smoke")
    runs = client.search_runs([exp.experiment_id], "tags.`madpinn.job` = 'evaluate/mujoco/scaling/nominal/n64/seed0'")
    assert len(runs) == 1
    return runs[0], client


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

    # MLflow: the computed cell's run gets its provenance hash; the restored cell, which ran no job,
    # becomes a run with the same params, metrics and files, tagged restored=true
    provenance = entries[0].split("_")[0]
    assert _track_cells(first) == {"enabled": True, "cells": 1, "logged": 0, "tagged": 1}
    computed, _ = _cell_run(first)
    assert computed.data.tags["madpinn.restored"] == "false" and computed.data.tags["madpinn.provenance_hash"] == provenance
    assert _track_cells(second) == {"enabled": True, "cells": 1, "logged": 1, "tagged": 0}
    restored, client = _cell_run(second)
    assert restored.data.tags["madpinn.restored"] == "true" and restored.data.tags["madpinn.provenance_hash"] == provenance
    assert restored.data.params == computed.data.params
    figures = {"safety_rate", "safe_scenarios", "cost", "cost_time_avg", "cost_all", "cost_all_time_avg", "min_separation"}
    assert figures <= set(restored.data.metrics) and restored.data.metrics == computed.data.metrics
    assert 0 < restored.data.metrics["min_separation"] == pd.read_parquet(second / CELL)["min_separation"].min()
    from madpinn.tracking.mlflow_store import PAPER_METRICS, PAPER_PARAMS
    # the paper's view shows columns the cells have (infeasible_share: MAD-PINN cells only)
    assert set(PAPER_METRICS) - {"infeasible_share"} <= set(restored.data.metrics)
    assert set(PAPER_PARAMS) <= set(restored.data.params)
    files = {a.path for a in client.list_artifacts(restored.info.run_id)}
    assert files == {"n64_seed0.parquet", "n64_seed0.json", "n64_seed0_traj.npz"}
    assert _track_cells(second)["logged"] == 0 and _cell_run(second)[0].info.run_id == restored.info.run_id   # once

    overlay = tmp_path / "more_scenarios.yaml"                 # a setting the cell reads: a new entry
    overlay.write_text(yaml.safe_dump({"studies": {"scaling": {"scenarios": 3}}}))
    out = _run(third, cache, REPO / "workflow/configs/smoke.yaml", overlay).stderr
    assert f"Moving output file {CELL} to cache" in out
    assert len(pd.read_parquet(third / CELL)) == 3 and len(list(cache.iterdir())) == 6

    # issue 66: nothing is stored onto an existing entry. A cache holding one file of the cell's
    # entry (another run storing it, or a user's copy): the cell is computed into results/ and the
    # entry's file is left as it was (Snakemake's store replaced it and linked the cell to it)
    partial, fourth = tmp_path / "partial", tmp_path / "fourth"
    partial.mkdir()
    summary = cache / entries[1]
    assert summary.name.endswith("_summary.json")
    (partial / summary.name).write_bytes(summary.read_bytes())
    os.utime(partial / summary.name, (0, 0))
    out = run_snakemake(fourth, "-j1", CELL, *CACHED, env={"SNAKEMAKE_OUTPUT_CACHE": str(partial)}).stderr
    assert "nothing is stored onto an existing entry" in out and "Moving output file" not in out
    assert [p.name for p in partial.iterdir()] == [summary.name] and (partial / summary.name).stat().st_mtime == 0
    assert not (fourth / CELL).is_symlink() and (fourth / CELL).is_file()


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


def test_every_kind_of_damaged_cache_entry_is_named(tmp_path):
    """Issue 50 item 1: Snakemake restores an entry without reading it. check_entries reads each
    one whole: a truncated Parquet, a JSON cut short and an NPZ with one flipped byte are each
    named; the committed entries and the cache's README pass."""
    import shutil

    import pytest

    from madpinn.output_cache import CacheEntryError, check_entries

    src = sorted((REPO / "output_cache").glob("*_traj.npz"))[0]
    stem = src.name.removesuffix("_traj.npz")
    for suffix in ("_parquet.parquet", "_summary.json", "_traj.npz"):
        shutil.copy2(REPO / "output_cache" / f"{stem}{suffix}", tmp_path / f"{stem}{suffix}")
    (tmp_path / "README.md").write_text("not an entry")
    assert check_entries(tmp_path) == 3
    npz = tmp_path / f"{stem}_traj.npz"
    good = npz.read_bytes()
    offset = _npz_data_byte(npz)
    npz.write_bytes(good[:offset] + bytes([good[offset] ^ 0xFF]) + good[offset + 1:])
    for name, damage in ((f"{stem}_traj.npz", None),
                         (f"{stem}_summary.json", lambda b: b[: len(b) // 2]),
                         (f"{stem}_parquet.parquet", lambda b: b[:500])):
        path = tmp_path / name
        if damage is not None:
            path.write_bytes(damage(path.read_bytes()))
        with pytest.raises(CacheEntryError, match=name):
            check_entries(tmp_path)
        path.unlink()


def _npz_data_byte(path):
    """The offset of a data byte in the middle of an NPZ's first member (a byte only its CRC guards)."""
    import zipfile

    with zipfile.ZipFile(path) as z:
        info = z.infolist()[0]
    raw = path.read_bytes()
    name_len = int.from_bytes(raw[info.header_offset + 26: info.header_offset + 28], "little")
    extra_len = int.from_bytes(raw[info.header_offset + 28: info.header_offset + 30], "little")
    return info.header_offset + 30 + name_len + extra_len + info.compress_size // 2


def _one_entry(tmp_path):
    """A copy of one committed evaluation-cell entry (its three files) in a fresh directory."""
    import shutil

    src = sorted((REPO / "output_cache").glob("*_traj.npz"))[0]
    stem = src.name.removesuffix("_traj.npz")
    d = tmp_path / "oc"
    d.mkdir(parents=True)
    for suffix in ("_parquet.parquet", "_summary.json", "_traj.npz"):
        shutil.copy2(REPO / "output_cache" / f"{stem}{suffix}", d / f"{stem}{suffix}")
    return d, stem


def test_an_entry_is_checked_as_one_unit_and_named_with_its_fix(tmp_path):
    """Issue 66 item 1: a member missing, a symlink (to itself: what Snakemake's store onto an
    existing entry left) or, in a git work tree, changed from its committed version is refused
    naming the entry; the fix restores from git what git tracks, else deletes the entry. The run's
    own layer (complete=False) may hold a partial entry: another run stores one file at a time."""
    import subprocess

    import pytest

    from madpinn.output_cache import KINDS, CacheEntryError, check_entries

    d, stem = _one_entry(tmp_path)
    assert check_entries(d, KINDS) == 3
    (d / f"{stem}_summary.json").unlink()
    with pytest.raises(CacheEntryError, match=r"incomplete: its _summary\.json missing") as err:
        check_entries(d, KINDS)
    assert err.value.fix.startswith(f"delete the entry's files (rm ") and stem in err.value.fix   # git tracks none
    assert check_entries(d, KINDS, complete=False, git=False) == 2
    assert check_entries(d, ()) == 2                           # an entry of no known kind is not completed

    d, stem = _one_entry(tmp_path / "git")
    git = ["git", "-C", str(d), "-c", "user.email=t@t", "-c", "user.name=t"]
    subprocess.run([*git, "init", "-q"], check=True)
    subprocess.run([*git, "add", "-A"], check=True)
    subprocess.run([*git, "commit", "-qm", "x"], check=True)
    parquet = d / f"{stem}_parquet.parquet"
    parquet.unlink()
    parquet.symlink_to(parquet.absolute())
    for complete in (True, False):
        with pytest.raises(CacheEntryError, match="is a symlink to itself") as err:
            check_entries(d, KINDS, complete=complete)
        assert err.value.fix == f"restore the entry from git: git checkout -- {parquet}"
    subprocess.run([*git, "checkout", "--", "."], check=True)
    summary = d / f"{stem}_summary.json"
    summary.write_text(summary.read_text().replace('"seed"', '"seed" ', 1))   # readable, not the committed bytes
    with pytest.raises(CacheEntryError, match="not its committed version"):
        check_entries(d, KINDS)
    assert check_entries(d, KINDS, git=False) == 3


def test_publish_adds_whole_new_entries_and_never_writes_onto_one(tmp_path):
    """`python -m madpinn publish`: a run's whole new entries (results/output_cache) are copied into
    the committed cache, an entry the committed cache has is left as it is, a partial one is not
    copied; the run's tables go to paper_figures/."""
    import shutil

    own, stem = _one_entry(tmp_path / "r")
    results = tmp_path / "results"
    results.mkdir()
    own = shutil.move(own, results / "output_cache")
    committed = tmp_path / "committed"
    committed.mkdir()
    other = sorted((REPO / "output_cache").glob("*_traj.npz"))[1].name.removesuffix("_traj.npz")
    for suffix in ("_parquet.parquet", "_summary.json"):          # a partial entry: not published
        shutil.copy2(REPO / "output_cache" / f"{other}{suffix}", own / f"{other}{suffix}")
    kept = committed / f"{stem}_summary.json"                    # here already: never written onto
    figures = results / "paper_figures"
    figures.mkdir()
    (figures / "table_x.md").write_text("new table\n")
    cfg = tmp_path / "c.yaml"
    cfg.write_text(yaml.safe_dump({"paths": {"results": str(results), "figures": str(figures),
                                             "output_cache": str(committed)}, "tracking": {"enabled": False}}))

    def publish(*extra):
        proc = subprocess.run([sys.executable, "-m", "madpinn", "publish", "--config", str(REPO / "config.yaml"), str(cfg),
                               "--figures-to", str(tmp_path / "paper_figures"), *extra], cwd=tmp_path,
                              capture_output=True, text=True, timeout=600, env=subprocess_env())
        assert proc.returncode == 0, proc.stderr[-3000:]
        return proc.stdout

    assert "would copy 1 files" in publish("-n") and not list(committed.iterdir())
    out = publish()
    assert "copied 1 new cache entries" in out and "copied 1 files" in out
    assert sorted(p.name for p in committed.iterdir()) == sorted(f"{stem}{s}" for s in
                                                                 ("_parquet.parquet", "_summary.json", "_traj.npz"))
    assert (tmp_path / "paper_figures" / "table_x.md").read_text() == "new table\n"
    for p in committed.iterdir():
        p.unlink()
    kept.write_text("{}")
    out = publish()
    assert "copied 0 new cache entries" in out and "(1 there already)" in out and kept.read_text() == "{}"
    assert sorted(p.name for p in committed.iterdir()) == [kept.name]
