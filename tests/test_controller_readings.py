"""table_controller_readings (issue 46): the same cells under each controller reading, side by
side, from committed cell files (output_cache/) relabelled as the ctl_* studies of the config."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pandas as pd
import pytest

from conftest import REPO
from madpinn.config import load_config
from madpinn.evaluation.controller_readings import readings_table, recorded_speeds, study_reading, write_controller_readings


def _committed_cell(study: str, run: str, n: int) -> Path:
    """The committed output_cache Parquet of one (study, run, N) cell."""
    for summary in sorted((REPO / "output_cache").glob("*_summary.json")):
        d = json.loads(summary.read_text())
        if d.get("study") == study and d.get("run") == run and d.get("n_agents") == n:
            return summary.with_name(summary.name.replace("_summary.json", "_parquet.parquet"))
    pytest.skip(f"no committed cell of {study} {run} N={n}")


def _as_cell(src: Path, dest_dir: Path, study: str, safety_shift: float = 0.0) -> Path:
    """Copy a cached cell (Parquet, summary, trajectory) into a results layout as ``study``'s."""
    dest_dir.mkdir(parents=True, exist_ok=True)
    frame = pd.read_parquet(src)
    frame["study"] = study
    frame["safety_rate"] = (frame["safety_rate"] + safety_shift).clip(0.0, 1.0)
    out = dest_dir / "n64_seed100.parquet"
    frame.to_parquet(out)
    stem = src.name.replace("_parquet.parquet", "")
    shutil.copy(src.with_name(stem + "_summary.json"), out.with_suffix(".json"))
    shutil.copy(src.with_name(stem + "_traj.npz"), out.with_name(out.stem + "_traj.npz"))
    return out


def test_readings_side_by_side_from_cells(tmp_path):
    cfg = load_config([REPO / "config.yaml"])
    assert study_reading(cfg, "ctl_large_mellinger") == "mellinger" and study_reading(cfg, "main") == "cascaded"
    src = _committed_cell("large_arena_frontier", "madpinn", 64)
    a = _as_cell(src, tmp_path / "ctl_large_cascaded" / "madpinn", "ctl_large_cascaded")
    b = _as_cell(src, tmp_path / "ctl_large_mellinger" / "madpinn", "ctl_large_mellinger", safety_shift=-0.1)
    table = readings_table([a, b], cfg)
    assert len(table) == 1 and table["arena"].iloc[0] == "large"
    row = table.iloc[0]
    assert row["cascaded: safety"] - row["mellinger: safety"] == pytest.approx(0.1, abs=0.02)   # the shift, clipped at 0
    assert 0.0 < row["cascaded: speed p50"] <= row["cascaded: speed p90"] < 10.0
    assert 0.0 <= row["cascaded: infeasible"] <= 1.0
    assert "firmware_pid: safety" not in table.columns      # no cell of that reading: no column
    files = write_controller_readings([a, b], cfg, tmp_path / "out")
    assert [f.suffix for f in files] == [".csv", ".md", ".html"] and "mellinger: safety" in files[1].read_text()


def test_recorded_speeds_are_the_finite_differences(tmp_path):
    import numpy as np

    traj = tmp_path / "t_traj.npz"
    times = np.array([0.0, 0.5, 1.0])
    positions = np.array([[[0.0, 0.0]], [[0.3, 0.4]], [[0.3, 0.4]]])
    np.savez(traj, times=times, positions=positions)
    np.testing.assert_allclose(recorded_speeds(traj), [1.0, 0.0])
