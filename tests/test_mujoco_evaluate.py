"""The smoke DAG's evaluation path with ``sim.backend: mujoco`` (and the same cell on the double
integrator for comparison)."""

import json

import numpy as np
import pandas as pd
import pytest

from madpinn.config import REPO_ROOT, deep_merge, load_yaml, validate_config
from madpinn.commands.evaluate import evaluate


@pytest.fixture
def smoke_cfg(tmp_path):
    cfg = deep_merge(load_yaml(REPO_ROOT / "config.yaml"), load_yaml(REPO_ROOT / "workflow/configs/smoke.yaml"))
    cfg = deep_merge(cfg, {"paths": {"results": str(tmp_path / "results"), "figures": str(tmp_path / "figs")},
                           "tracking": {"enabled": False}, "sim": {"backend": "mujoco"}})
    validate_config(cfg)
    return cfg


def test_evaluation_cell_runs_on_mujoco(smoke_cfg, tmp_path):
    out = tmp_path / "mujoco.parquet"
    summary = evaluate(smoke_cfg, "main", "nominal", 3, 0, out, progress=False, track=False)
    assert summary["backend"] == "mujoco"
    df = pd.read_parquet(out)
    assert len(df) == smoke_cfg["studies"]["main"]["scenarios"] and (df["backend"] == "mujoco").all()
    assert json.loads(out.with_suffix(".json").read_text())["backend"] == "mujoco"
    traj = np.load(tmp_path / "mujoco_traj.npz")
    assert traj["positions"].shape[1:] == (3, 2) and np.isfinite(traj["positions"]).all()

    di = evaluate(smoke_cfg, "main", "nominal", 3, 0, tmp_path / "di.parquet", backend="double_integrator",
                  progress=False, track=False)
    di_traj = np.load(tmp_path / "di_traj.npz")
    # same scenarios, same policy: the drones stay close to the ideal double integrator
    assert np.abs(traj["positions"] - di_traj["positions"]).max() < 0.05
    assert summary["cost"] == pytest.approx(di["cost"], rel=0.05)
