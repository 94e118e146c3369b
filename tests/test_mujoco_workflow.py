"""Workflow wiring of the MuJoCo backend: the DAG on `sim.backend: mujoco` with clips, and the
``render-clip`` command (renders where offscreen GL exists, records why not elsewhere)."""

import json
import subprocess
import sys

import numpy as np
import yaml

from conftest import subprocess_env
from madpinn.commands import main
from madpinn.config import REPO_ROOT, load_config
from madpinn.simulation.mujoco.render import gl_context_available
from madpinn.simulation.mujoco.settings import MujocoSettings


def test_dag_on_mujoco_with_clips(tmp_path):
    overlay = tmp_path / "mujoco.yaml"
    overlay.write_text(yaml.safe_dump({
        "paths": {"results": str(tmp_path / "results"), "figures": str(tmp_path / "figs")},
        "sim": {"backend": "mujoco", "mujoco": {"render_clips": True}},
    }))
    proc = subprocess.run(
        [sys.executable, "-m", "snakemake", "-n", "-j1", "all", "--snakefile", str(REPO_ROOT / "Snakefile"),
         "--directory", str(tmp_path), "--configfile", str(REPO_ROOT / "workflow/configs/smoke.yaml"), str(overlay)],
        capture_output=True, text=True, env=subprocess_env(), timeout=300,
    )
    assert proc.returncode == 0, proc.stderr[-3000:] + proc.stdout[-3000:]
    out = proc.stdout + proc.stderr
    assert "/eval/mujoco/main/nominal/n3_seed0.parquet" in out
    assert "/clips/mujoco/main/nominal/n3_seed0.json" in out
    assert "/clips/mujoco/scaling/nominal/n64_seed0.json" in out


def test_render_clip_command(tmp_path):
    traj = tmp_path / "cell_traj.npz"
    t = np.arange(4) * 0.02
    np.savez(traj, times=t, positions=np.stack([np.stack([t, t], 1), np.stack([-t, t], 1)], 1),
             goals=np.array([[0.5, 0.5], [-0.5, 0.5]]), first_collision_step=np.array([-1, -1]), dt=0.0025,
             half_width=1.0)
    status_path = tmp_path / "clip.json"
    assert main(["render-clip", "--config", str(REPO_ROOT / "config.yaml"), "--traj", str(traj),
                 "--out", str(status_path), "--no-track"]) == 0
    status = json.loads(status_path.read_text())
    ok, _ = gl_context_available(MujocoSettings.from_config(load_config([REPO_ROOT / "config.yaml"])["sim"]["mujoco"]).spec)
    assert status["rendered"] is ok
    assert (tmp_path / "clip.gif").is_file() is ok
