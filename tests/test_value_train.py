"""Trainer: resume after interruption reproduces the uninterrupted run, NaN guard, determinism,
learning, curriculum and learning-rate schedules."""

import math

import pytest
import torch

from madpinn.dynamics.pair import PairSystem
from madpinn.value_functions.model import CheckpointError
from madpinn.value_functions.problems import PairProblem
from madpinn.value_functions.train import (
    TrainingDiverged, TrainSettings, curriculum_alpha, learning_rate, train, train_step, training_batch,
)
from settings_helpers import pair_system

NET = {"hidden": 32, "layers": 2, "first_omega": 30.0, "hidden_omega": 30.0}


def settings(**kw):
    base = dict(iterations=24, batch_size=128, lr=1e-4, lr_final=1e-5, curriculum_fraction=0.5,
                checkpoint_every=5, output_scale=1.0, network=NET, seed=3, loss="l1", init_from=None,
                obstacle_weight=0.0, stop_at=None)
    base.update(kw)
    return TrainSettings(**base)


def test_resume_after_interruption_gives_the_uninterrupted_model(tmp_path):
    torch.set_num_threads(1)
    problem = PairProblem(pair_system())
    full, info_full = train(problem, settings(), tmp_path / "a.ckpt", "h", progress=False)
    part, info = train(problem, settings(), tmp_path / "b.ckpt", "h", progress=False, stop_after=13)
    assert not info["completed"] and info["iterations"] == 13
    resumed, info2 = train(problem, settings(), tmp_path / "b.ckpt", "h", progress=False)
    assert info2["completed"] and len(info2["history"]) == 24
    assert info2["history"] == pytest.approx(info_full["history"], rel=1e-6)
    for p, q in zip(full.parameters(), resumed.parameters()):
        assert torch.allclose(p, q, rtol=1e-6, atol=1e-7)
    # a checkpoint of another configuration is refused and kept (it used to be overwritten from iteration 0)
    before = (tmp_path / "b.ckpt").read_bytes()
    with pytest.raises(CheckpointError, match="another training configuration"):
        train(problem, settings(iterations=6), tmp_path / "b.ckpt", "other-hash", progress=False)
    assert (tmp_path / "b.ckpt").read_bytes() == before


def test_deterministic_and_learns():
    torch.set_num_threads(1)
    problem = PairProblem(pair_system())
    s = settings(iterations=150, checkpoint_every=1000, lr=1e-3, lr_final=1e-4, curriculum_fraction=0.0)
    a, ia = train(problem, s, "/nonexistent/dir/none.ckpt", "h", progress=False)
    b, ib = train(problem, s, "/nonexistent/dir/none.ckpt", "h", progress=False)
    assert ia["history"] == ib["history"]
    h = ia["history"]
    assert sum(h[-20:]) / 20 < 0.85 * sum(h[:20]) / 20


def test_nan_guard_fails_with_a_clear_message(tmp_path):
    problem = PairProblem(pair_system(collision_radius=float("nan")))  # NaN target -> NaN loss
    with pytest.raises(TrainingDiverged, match="diverged at iteration 0: loss=nan.*Lower value_functions.vs.lr"):
        train(problem, settings(), tmp_path / "c.ckpt", "h", progress=False)


def test_curriculum_and_schedule():
    s = settings(iterations=100, curriculum_fraction=0.5, lr=1e-3, lr_final=1e-5)
    assert curriculum_alpha(0, s) == pytest.approx(0.02) and curriculum_alpha(49, s) == 1.0
    assert learning_rate(0, s) == pytest.approx(1e-3) and learning_rate(99, s) == pytest.approx(1e-5)
    problem = PairProblem(pair_system())
    _, t = training_batch(problem, s, 9, "cpu", torch.float32)
    assert t.min() >= problem.horizon * (1 - 0.2) - 1e-6 and t.max() <= problem.horizon
    x1, _ = training_batch(problem, s, 9, "cpu", torch.float32)
    x2, _ = training_batch(problem, s, 9, "cpu", torch.float32)
    assert torch.equal(x1, x2)
    assert math.isclose(learning_rate(50, settings(lr=2e-5, lr_final=2e-5)), 2e-5)


def test_fine_tuning_starts_from_the_model_and_continues_its_batch_stream(tmp_path):
    from madpinn.value_functions.model import CheckpointError, model_payload, save_atomic

    torch.set_num_threads(1)
    problem = PairProblem(pair_system())
    base, info = train(problem, settings(iterations=10), tmp_path / "base.ckpt", "h", progress=False)
    save_atomic(model_payload(problem, base, 1.0, {"iterations": info["iterations"]}), tmp_path / "base.pt")
    frozen = settings(iterations=1, lr=0.0, lr_final=0.0, init_from=str(tmp_path / "base.pt"))
    tuned, ft = train(problem, frozen, tmp_path / "ft.ckpt", "ft", progress=False)
    assert ft["batch_offset"] == 10
    for p, q in zip(base.parameters(), tuned.parameters()):  # lr 0: the loaded weights, unchanged
        assert torch.equal(p, q)
    # its first batch is the base run's 11th, not a replay of the base run's first
    s0, _ = training_batch(problem, settings(), 0, "cpu", torch.float32)
    s10, _ = training_batch(problem, settings(), 10, "cpu", torch.float32)
    s_ft, _ = training_batch(problem, frozen, 0, "cpu", torch.float32, ft["batch_offset"])
    assert torch.equal(s_ft, s10) and not torch.equal(s_ft, s0)
    # ... and train() used it: the first fine-tuning loss is the loaded model's loss on that batch
    opt = torch.optim.Adam(tuned.parameters())
    on = {k: train_step(problem, tuned, opt, frozen, 0, "cpu", torch.float32, k) for k in (0, 10)}
    assert ft["history"][0] == pytest.approx(on[10], rel=1e-6) and ft["history"][0] != pytest.approx(on[0], rel=1e-6)
    with pytest.raises(CheckpointError, match="network"):
        train(problem, settings(iterations=1, init_from=str(tmp_path / "base.pt"), network={**NET, "hidden": 16}),
              tmp_path / "bad.ckpt", "bad", progress=False)
    with pytest.raises(CheckpointError, match="not found"):
        train(problem, settings(iterations=1, init_from=str(tmp_path / "missing.pt")), tmp_path / "m.ckpt", "m",
              progress=False)


def test_time_boxed_pieces_give_the_uninterrupted_model(tmp_path):
    """A deadline already passed stops every call after one iteration; calling again until done
    reproduces the uninterrupted run, and a finished run is not trained again."""
    import time

    torch.set_num_threads(1)
    problem = PairProblem(pair_system())
    full, info_full = train(problem, settings(), tmp_path / "a.ckpt", "h", progress=False)
    calls, info = 0, {"completed": False}
    while not info["completed"]:
        piece, info = train(problem, settings(), tmp_path / "b.ckpt", "h", progress=False, deadline=time.monotonic() - 1)
        calls += 1
        assert info["iterations"] == calls
    assert calls == 24 and info["history"] == pytest.approx(info_full["history"], rel=1e-6)
    for p, q in zip(full.parameters(), piece.parameters()):
        assert torch.allclose(p, q, rtol=1e-6, atol=1e-7)
    again, info_again = train(problem, settings(), tmp_path / "b.ckpt", "h", progress=False, deadline=time.monotonic() - 1)
    assert info_again["completed"] and len(info_again["history"]) == 24
    for p, q in zip(piece.parameters(), again.parameters()):
        assert torch.equal(p, q)


def test_stop_at_ends_inside_the_schedule_and_resumes_from_the_longer_runs_checkpoint(tmp_path):
    """A run with ``stop_at`` is the longer schedule's run up to that iteration (curriculum and learning
    rate follow ``iterations``), so it ends with the longer run's weights there and resumes from its checkpoint."""
    torch.set_num_threads(1)
    problem = PairProblem(pair_system())
    short, info = train(problem, settings(stop_at=10), tmp_path / "short.ckpt", "h", progress=False)
    assert info["completed"] and info["iterations"] == 10 and len(info["history"]) == 10
    longer, info_long = train(problem, settings(), tmp_path / "long.ckpt", "h", progress=False, stop_after=10)
    assert not info_long["completed"]
    assert info["history"] == info_long["history"]
    for p, q in zip(short.parameters(), longer.parameters()):
        assert torch.equal(p, q)
    # an early-ending schedule differs from a shorter schedule (its curriculum and rate span 10 iterations)
    _, info_10 = train(problem, settings(iterations=10), tmp_path / "ten.ckpt", "h", progress=False)
    assert info_10["history"] != info["history"]
    # the stop_at run resumes from the longer run's checkpoint at its end: nothing left to train
    resumed, info_r = train(problem, settings(stop_at=10), tmp_path / "long.ckpt", "h", progress=False)
    assert info_r["completed"] and info_r["history"] == info_long["history"]
    for p, q in zip(resumed.parameters(), longer.parameters()):
        assert torch.equal(p, q)
    with pytest.raises(ValueError, match="stop_at .25. must lie in 1..iterations .24."):
        settings(stop_at=25)
