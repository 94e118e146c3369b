"""training/snapshot_checkpoint.py (issue 46): copies of a running training's checkpoint at chosen
iterations, checked against a real resume checkpoint of the smoke V̂ training."""

from __future__ import annotations

import subprocess
import sys

import torch

from conftest import REPO, SMOKE
from madpinn.commands import main

SCRIPT = REPO / "training" / "snapshot_checkpoint.py"


def test_keeps_the_checkpoint_at_its_iteration_and_stops_when_one_was_missed(tmp_path, one_thread):
    ckpt = tmp_path / "vhat.ckpt.pt"
    assert main(["train-value", "--config", str(REPO / "config.yaml"), str(SMOKE), "--kind", "vhat", "--out",
                 str(tmp_path / "vhat.pt"), "--checkpoint", str(ckpt), "--stop-after", "10", "--no-track", "--no-progress",
                 "--threads", "1"]) in (0, 75)
    run = lambda *at: subprocess.run([sys.executable, str(SCRIPT), "--checkpoint", str(ckpt), "--at", *map(str, at),
                                      "--out-dir", str(tmp_path / "snap"), "--poll-s", "0.05"], capture_output=True, text=True,
                                     timeout=120)
    done = run(10)
    assert done.returncode == 0, done.stderr
    kept = tmp_path / "snap" / "vhat_it000010.ckpt.pt"
    assert kept.read_bytes() == ckpt.read_bytes()
    assert torch.load(kept, weights_only=True)["meta"]["train_state"]["iteration"] == 10
    # the training is past iteration 5 and that copy was never made: say so instead of waiting forever
    missed = run(5)
    assert missed.returncode == 1 and "[5]" in missed.stdout
