"""Issue 46's budget points along one run: ``value_functions.<kind>.stop_at`` ends a training inside
its schedule, its own training hash (a model of its own) but the schedule's resume hash, so it
finishes from the longer run's checkpoint at that iteration; a stop beyond the schedule is refused."""

from __future__ import annotations

import pytest
import torch

from conftest import REPO, SMOKE
from madpinn.commands import main
from madpinn.config import ConfigError, load_config
from madpinn.provenance import model_training_hash
from workflow_helpers import write_overlay

VARIANTS = {"value_functions": {"vhat_variants": {"long": {"fine_tune": None}, "early": {"fine_tune": None, "stop_at": 20}}}}


def test_an_early_stop_finishes_from_the_longer_runs_checkpoint(tmp_path, one_thread, capsys):
    overlay = write_overlay(tmp_path / "variants.yaml", VARIANTS)
    config = ["--config", str(REPO / "config.yaml"), str(SMOKE), str(overlay)]
    ckpt = tmp_path / "long.ckpt.pt"
    common = ["--no-track", "--no-progress", "--threads", "1", "--checkpoint", str(ckpt)]
    assert main(["train-value", *config, "--kind", "vhat", "--variant", "long", "--out", str(tmp_path / "long.pt"),
                 "--stop-after", "20", *common]) == 0
    state = torch.load(ckpt, map_location="cpu", weights_only=True)
    assert state["meta"]["train_state"]["iteration"] == 20
    capsys.readouterr()
    out = tmp_path / "vhat_early.pt"
    assert main(["train-value", *config, "--kind", "vhat", "--variant", "early", "--out", str(out), *common]) == 0
    assert "resuming from" in capsys.readouterr().out
    model = torch.load(out, map_location="cpu", weights_only=True)
    cfg = load_config([REPO / "config.yaml", SMOKE, overlay])
    assert model["meta"]["iterations"] == 20 and model["meta"]["settings"]["stop_at"] == 20
    assert model["meta"]["config_hash"] == model_training_hash(cfg, "vhat_early") != model_training_hash(cfg, "vhat_long")
    for name, w in model["state_dict"].items():
        assert torch.equal(w, state["state_dict"][name]), name


def test_a_stop_beyond_the_schedule_is_refused_at_load(tmp_path):
    overlay = write_overlay(tmp_path / "bad.yaml", {"value_functions": {"vhat_variants": {"late": {"stop_at": 10 ** 9}}}})
    with pytest.raises(ConfigError, match=r"value_functions.vhat_variants.late.stop_at': stop_at .1000000000. must lie in 1..iterations"):
        load_config([REPO / "config.yaml", SMOKE, overlay])
