"""DEF-MARL training in resumable, time-boxed pieces (``train-defmarl --checkpoint --time-limit``),
continuing a trained model without training state (``--init``), the validation curve and its
plateau rule: tiny configurations (the smoke overlay) through the command's own code path."""

import copy

import pandas as pd
import pytest
import torch

from madpinn.commands.defmarl import EXIT_PAUSED, resume_hash, train_defmarl
from madpinn.config import deep_merge, validate_config
from madpinn.marl.checkpoint import CheckpointError, load_checkpoint
from madpinn.marl.validation import ValidationSettings, plateau

pytestmark = pytest.mark.usefixtures("one_thread")


def _cfg(smoke_cfg, iterations=4, every=2, **training) -> dict:
    cfg = deep_merge(copy.deepcopy(smoke_cfg), {"methods": {"defmarl": {
        "training": {"ppo": {"iterations": iterations}, **training},
        "validation": {"every": every, "scenarios": 1, "agent_counts": [4]}}}})
    validate_config(cfg)
    return cfg


def _weights(path) -> dict:
    return load_checkpoint(path)["modules"]


def _same(a: dict, b: dict) -> None:
    assert a.keys() == b.keys()
    for k in a:
        for name in a[k]:
            assert torch.allclose(a[k][name], b[k][name], rtol=1e-6, atol=1e-7), (k, name)


def test_time_boxed_pieces_give_the_uninterrupted_model(smoke_cfg, tmp_path):
    """A time limit of 0 s stops every piece after one iteration (exit 75); calling again until
    done gives the uninterrupted run's weights and curves, validation rows included; a finished
    checkpoint is not trained again. Validating does not change the weights."""
    cfg = _cfg(smoke_cfg)
    full = train_defmarl(cfg, "n3", tmp_path / "full" / "m.pt", progress=False, track=False)
    assert full is not None and full["iterations"] == 4
    no_val = train_defmarl(_cfg(smoke_cfg, every=0), "n3", tmp_path / "noval" / "m.pt", progress=False, track=False)
    assert no_val["iterations"] == 4 and no_val["deployed_iteration"] == 4
    _same(_weights(tmp_path / "full" / "m_last.pt"), _weights(tmp_path / "noval" / "m.pt"))

    ckpt, out = tmp_path / "pieces" / "state.pt", tmp_path / "pieces" / "m.pt"
    calls, summary = 0, None
    while summary is None:
        summary = train_defmarl(cfg, "n3", out, progress=False, track=False, checkpoint=ckpt, time_limit=0.0)
        calls += 1
        assert load_checkpoint(ckpt)["train_state"]["iteration"] == min(calls, 4)
        if summary is None:
            assert not out.exists() and (tmp_path / "pieces" / "m_history.csv").is_file()
    assert calls == 4 and summary["iterations"] == 4
    _same(_weights(tmp_path / "full" / "m.pt"), _weights(out))
    a = pd.read_csv(tmp_path / "full" / "m_history.csv")
    b = pd.read_csv(tmp_path / "pieces" / "m_history.csv")
    keys = ["iteration", "episode_return", "violation_rate", "val_safety_n3", "val_safety_n4", "val_cost_n4", "val_best"]
    pd.testing.assert_frame_equal(a[keys], b[keys], rtol=1e-6)
    assert a["val_safety_n3"].notna().tolist() == [False, True, False, True]   # every 2 iterations
    # the best validation model so far is kept beside the model, the same in pieces
    assert a["val_best"].tolist()[1] == 1.0 and list(a["val_best"].fillna(-1)) == list(b["val_best"].fillna(-1))
    best = load_checkpoint(tmp_path / "full" / "m_best.pt")
    assert best["meta"]["validation"]["val_safety_n3"] == a["val_safety_n3"].max()
    _same(best["modules"], _weights(tmp_path / "pieces" / "m_best.pt"))
    # the deployed model (the job's output) is the best validation checkpoint, the last one beside it
    best_it = int(a["iteration"][a["val_best"] == 1.0].iloc[-1]) + 1
    assert full["deployed_iteration"] == summary["deployed_iteration"] == best_it
    _same(_weights(tmp_path / "full" / "m.pt"), _weights(tmp_path / "full" / ("m_last.pt" if best_it == 4 else "m_best.pt")))
    # a finished checkpoint is not trained again; a larger budget continues it
    again = train_defmarl(cfg, "n3", out, progress=False, track=False, checkpoint=ckpt, time_limit=0.0)
    assert again["iterations"] == 4
    _same(_weights(tmp_path / "full" / "m.pt"), _weights(out))
    more = train_defmarl(_cfg(smoke_cfg, iterations=5), "n3", out, progress=False, track=False, checkpoint=ckpt)
    assert more["iterations"] == 5 and load_checkpoint(tmp_path / "pieces" / "m_last.pt")["meta"]["iterations"] == 5
    assert more["deployed_iteration"] in (2, 4)   # validated every 2 iterations: the last (5) never is
    # another configuration does not resume that state
    with pytest.raises(CheckpointError, match="another configuration"):
        train_defmarl(_cfg(smoke_cfg, iterations=6, seed=1), "n3", out, progress=False, track=False, checkpoint=ckpt)
    assert resume_hash(cfg, "n3") == resume_hash(_cfg(smoke_cfg, iterations=9), "n3") != resume_hash(cfg, "n8")


def test_continue_a_model_without_training_state(smoke_cfg, tmp_path):
    """``--init``: a finished model's weights and normalisers, fresh optimizers, iterations
    counted on from the model's; refused when the budget is not larger."""
    base = tmp_path / "base.pt"
    train_defmarl(_cfg(smoke_cfg, iterations=2, every=0), "n3", base, progress=False, track=False)
    assert "train_state" not in load_checkpoint(base)
    out = tmp_path / "cont.pt"
    s = train_defmarl(_cfg(smoke_cfg, iterations=3, every=0), "n3", out, progress=False, track=False, init=base)
    assert s["iterations"] == 1 and load_checkpoint(out)["meta"]["iterations"] == 3
    assert pd.read_csv(tmp_path / "cont_history.csv")["iteration"].tolist() == [2]
    with pytest.raises(CheckpointError, match="raise the iterations"):
        train_defmarl(_cfg(smoke_cfg, iterations=2, every=0), "n3", tmp_path / "x.pt", progress=False, track=False, init=base)
    other = copy.deepcopy(_cfg(smoke_cfg, iterations=3, every=0))
    other["methods"]["defmarl"]["epigraph"]["z_max"] = 4.0
    with pytest.raises(CheckpointError, match="epigraph settings"):
        train_defmarl(other, "n3", tmp_path / "z.pt", progress=False, track=False, init=base)
    with pytest.raises(CheckpointError, match="does not fit"):
        train_defmarl(_cfg(smoke_cfg, iterations=3, every=0, network={"hidden": 8}), "n3", tmp_path / "y.pt",
                      progress=False, track=False, init=base)


def test_time_limit_needs_a_checkpoint_and_cli_exit_code(smoke_cfg, tmp_path):
    from madpinn.config import ConfigError

    with pytest.raises(ConfigError, match="--checkpoint"):
        train_defmarl(_cfg(smoke_cfg), "n3", tmp_path / "m.pt", track=False, time_limit=1.0)
    assert EXIT_PAUSED == 75


def test_plateau_rule():
    assert not plateau([80, 85, 90, 91, 92], 3, 1.0)           # fewer than two windows
    assert not plateau([80, 85, 90, 91, 92, 93], 3, 1.0)       # +7 points
    assert plateau([90, 91, 92, 91, 92, 92.5], 3, 1.0)         # +0.83 points
    assert plateau([90, 91, 92, 88, 89, 90], 3, 1.0)           # worse
    with pytest.raises(ValueError, match="validation seed"):
        ValidationSettings.from_config({"every": 1, "seed": 0, "scenarios": 1, "agent_counts": [], "backend": "mujoco",
                                        "study": "main", "plateau": {"window": 3, "min_gain": 1.0, "stop": False}})


def test_best_model_rule_ties_exactly_and_breaks_ties_on_the_other_counts():
    """Equal outcome counts tie whatever their float rounding (146 of 150 agents safe gives
    97.33333333333333 or 97.33333333333334 depending on how it was computed), the tie goes to the
    higher safety at the other validation counts, and a row must beat every earlier one strictly;
    rows without validation are skipped."""
    from madpinn.evaluation.marl_validation import CellValidation
    from madpinn.marl.best_model import mark_best

    v = CellValidation.__new__(CellValidation)
    v.train_n, v.counts = 3, [3, 16]
    rows = [{"iteration": 49, "val_safety_n3": 90.0, "val_safety_n16": 70.0},
            {"iteration": 99},                                                       # no validation
            {"iteration": 149, "val_safety_n3": 97.33333333333333, "val_safety_n16": 49.1},
            {"iteration": 199, "val_safety_n3": 97.33333333333333, "val_safety_n16": 62.6},
            {"iteration": 249, "val_safety_n3": 96.0, "val_safety_n16": 80.0},
            {"iteration": 299, "val_safety_n3": 97.33333333333334, "val_safety_n16": 50.0}]   # one rounding step up
    assert v.score(rows[3])[0] == v.score(rows[5])[0]
    best = mark_best(rows, v.score)
    assert best["iteration"] == 199 and [r.get("val_best") for r in rows] == [1.0, None, 1.0, 1.0, 0.0, 0.0]
    assert v.score({"iteration": 1, "val_safety_n3": float("nan")}) is None
