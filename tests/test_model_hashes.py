"""Identical weights, identical model files (issue 50 item 3): a trained model holds what its
weights are a function of, never the run's wall time, commit or date (those are in the training's
summary JSON beside it), so two trainings of one configuration and seed write byte-identical
files, wherever they write them; checkpoints written before still load."""

from __future__ import annotations

import copy
import hashlib
import json

import pytest

from madpinn.commands import main
from madpinn.config import REPO_ROOT, deep_merge, validate_config

CONFIGS = [str(REPO_ROOT / "config.yaml"), str(REPO_ROOT / "workflow" / "configs" / "smoke.yaml")]

pytestmark = pytest.mark.usefixtures("one_thread")


def _sha(path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def test_two_value_function_trainings_write_identical_files(tmp_path):
    """Two-stage V_s training (train, then fine-tune) twice, into directories of different names."""
    tiny = tmp_path / "tiny.yaml"
    tiny.write_text("value_functions:\n  vs:\n    iterations: 6\n    checkpoint_every: 3\n"
                    "    fine_tune: {iterations: 3, lr: 3.0e-5, lr_final: 1.0e-6}\n")
    outs = [tmp_path / d / "vs.pt" for d in ("first", "second run")]
    for out in outs:
        assert main(["train-value", "--config", *CONFIGS, str(tiny), "--kind", "vs", "--out", str(out),
                     "--no-track", "--no-progress"]) == 0
    assert _sha(outs[0]) == _sha(outs[1])
    assert _sha(outs[0].with_name("vs_stage1.pt")) == _sha(outs[1].with_name("vs_stage1.pt"))
    records = [json.loads(o.with_name("vs_train.json").read_text()) for o in outs]
    assert all(r["wall_s"] > 0 and r["git_commit"] for r in records)   # the run's record is kept, beside the model


def test_two_marl_trainings_write_identical_checkpoints(smoke_cfg, tmp_path):
    """SafeMARL's nominal policy and a validated DEF-MARL model (its deployed, best and last
    checkpoints), each trained twice."""
    from madpinn.commands.defmarl import train_defmarl
    from madpinn.commands.safemarl import train_safemarl_nominal

    cfg = deep_merge(copy.deepcopy(smoke_cfg), {"methods": {"defmarl": {
        "training": {"ppo": {"iterations": 2}}, "validation": {"every": 1, "scenarios": 1, "agent_counts": []}}}})
    validate_config(cfg)
    for d in ("a", "b"):
        train_safemarl_nominal(cfg, tmp_path / d / "nominal.pt", progress=False, track=False)
        train_defmarl(cfg, "n3", tmp_path / d / "defmarl.pt", progress=False, track=False)
    for name in ("nominal.pt", "defmarl.pt", "defmarl_best.pt", "defmarl_last.pt"):
        assert _sha(tmp_path / "a" / name) == _sha(tmp_path / "b" / name), name
    assert json.loads((tmp_path / "a" / "defmarl.json").read_text())["wall_s"] > 0


@pytest.mark.parametrize("name", ["vhat_cs", "vs", "safemarl_nominal", "defmarl_n3"])
def test_shipped_checkpoints_with_a_wall_time_still_load(name):
    """These shipped models were written with the wall time inside (vhat_cs: models/vhat.pt until issue
    61); they load as before."""
    import torch

    from madpinn.value_functions import load_vhat, load_vs

    path = REPO_ROOT / "models" / f"{name}.pt"
    assert "wall_s" in torch.load(path, map_location="cpu", weights_only=True)["meta"]
    if name in ("vhat_cs", "vs"):
        model = (load_vhat if name == "vhat_cs" else load_vs)(path)
        assert model.meta["iterations"] > 0
    else:
        from madpinn.marl.checkpoint import load_checkpoint

        assert load_checkpoint(path)["meta"]["iterations"] > 0


def test_a_training_seed_of_its_own_gives_other_weights_and_its_own_hash(tmp_path):
    """A V_s training with ``vs.seed: 5`` (issue 60's training-variance variants set it) starts from
    other weights and batches than one on ``value_functions.seed``; the seed is part of its training hash."""
    from madpinn.config import load_config
    from madpinn.value_functions.build import training_hash, training_seed

    tiny = tmp_path / "tiny.yaml"
    tiny.write_text("value_functions:\n  vs:\n    iterations: 3\n    checkpoint_every: 3\n    fine_tune: null\n")
    seeded = tmp_path / "seeded.yaml"
    seeded.write_text("value_functions:\n  vs: {seed: 5}\n")
    outs = {}
    for name, extra in (("base", []), ("seeded", [str(seeded)])):
        outs[name] = tmp_path / name / "vs.pt"
        assert main(["train-value", "--config", *CONFIGS, str(tiny), *extra, "--kind", "vs", "--out", str(outs[name]),
                     "--no-track", "--no-progress"]) == 0
    assert _sha(outs["base"]) != _sha(outs["seeded"])
    base, other = (load_config([*CONFIGS, str(tiny), *extra]) for extra in ([], [str(seeded)]))
    assert (training_seed(base, "vs"), training_seed(other, "vs")) == (base["value_functions"]["seed"], 5)
    assert training_hash(base, "vs") != training_hash(other, "vs")
