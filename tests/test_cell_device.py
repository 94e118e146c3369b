"""Evaluation cells on a GPU (issue 65 item 2): a cell is keyed under the device it runs on, so GPU
cells and CPU cells are separate output-cache entries (their floating-point results differ), and a
cell asked to run on CUDA where there is none stops with one line before writing anything."""

import subprocess
import sys

import pytest
import torch
import yaml

from conftest import REPO, SMOKE, run_snakemake, subprocess_env
from madpinn.config import load_config
from madpinn.commands.evaluate import evaluate
from madpinn.machine import planned_device


def test_the_planned_device_follows_the_setting_and_the_machine():
    assert planned_device("cpu") == "cpu"
    assert planned_device("cuda") == "cuda" and planned_device("cuda:0") == "cuda"
    assert planned_device("auto") == ("cuda" if torch.cuda.is_available() else "cpu")


def test_a_cell_records_the_device_it_ran_on(tmp_path):
    cfg = load_config(["config.yaml"])
    cfg["sim"]["backend"], cfg["studies"]["main"]["scenarios"] = "double_integrator", 1
    s = evaluate(cfg, "main", "nominal", 3, 100, tmp_path / "n3.parquet", track=False, device="cpu", progress=False)
    assert s["device"] == "cpu"


@pytest.mark.skipif(torch.cuda.is_available(), reason="this machine has CUDA")
def test_cuda_where_there_is_none_is_one_line_and_writes_nothing(tmp_path):
    out = tmp_path / "cell" / "n3.parquet"
    proc = subprocess.run([sys.executable, "-m", "madpinn", "evaluate", "--config", str(REPO / "config.yaml"), "--study", "main",
                           "--run", "nominal", "--n-agents", "3", "--seed", "100", "--out", str(out), "--device", "cuda",
                           "--no-track"], capture_output=True, text=True, env=subprocess_env(), cwd=tmp_path)
    assert proc.returncode == 2
    assert proc.stderr.strip().count("\n") == 0 and "CUDA is not available" in proc.stderr, proc.stderr
    assert not out.parent.exists()


def test_a_cuda_config_plans_gpu_cells_on_a_machine_without_one(tmp_path):
    """A cluster's planning machine may have no GPU: ``device: cuda`` still plans every cell with
    ``--device cuda`` (a param of the cell's job, so its cache key), and writes nothing."""
    overlay = tmp_path / "cuda.yaml"
    overlay.write_text(yaml.safe_dump({"device": "cuda"}))
    out = run_snakemake(tmp_path / "run", "-n", "all", configfiles=(SMOKE, overlay))
    text = out.stdout + out.stderr
    assert "--device cuda" in text and "--device cpu" not in text
    assert not (tmp_path / "run" / "results").exists()
