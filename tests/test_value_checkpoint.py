"""Checkpoint files: round trip through the public API, clear errors for bad files."""

import pytest
import torch

from madpinn.value_functions.epigraph import EpigraphSystem
from madpinn.dynamics.pair import PairSystem
from madpinn.value_functions import CheckpointError, load_vhat, load_vs
from madpinn.value_functions.model import build_network, model_payload, save_atomic
from madpinn.value_functions.problems import EpigraphProblem, PairProblem
from settings_helpers import epigraph_system, observation_settings, pair_system

NET = {"hidden": 16, "layers": 2, "first_omega": 30.0, "hidden_omega": 30.0}


@pytest.fixture()
def files(tmp_path):
    torch.manual_seed(0)
    spec = observation_settings()
    pv = EpigraphProblem(epigraph_system(spec=spec, z_max=21.45))
    ps = PairProblem(pair_system())
    vh = save_atomic(model_payload(pv, build_network(pv, NET), 1.5, {"iterations": 7}), tmp_path / "vhat.pt")
    vs = save_atomic(model_payload(ps, build_network(ps, NET), 1.0, {"iterations": 9}), tmp_path / "vs.pt")
    return vh, vs


def test_public_api(files):
    vh_path, vs_path = files
    vhat = load_vhat(vh_path)
    assert vhat.horizon == 0.2 and vhat.z_max == 21.45 and vhat.obs_spec == observation_settings()
    obs = torch.randn(10, 16)
    z = torch.rand(10) * 5
    v = vhat.value(obs, z, 0.0)
    with torch.no_grad():
        v2, go, gz = vhat.value_and_grad(obs, z, torch.zeros(10))
    assert v.shape == (10,) and go.shape == (10, 16) and gz.shape == (10,)
    assert torch.allclose(v, v2, atol=1e-5)
    vs = load_vs(vs_path, dtype=torch.float64)
    assert vs.horizon == 1.0 and vs.collision_radius == 0.1
    x = torch.randn(5, 4, dtype=torch.float64)
    val, grad = vs.value_and_grad(x)
    assert val.shape == (5,) and grad.shape == (5, 4) and val.dtype == torch.float64
    assert torch.allclose(vs.value(x, 0.0), val)
    assert vs.meta["iterations"] == 9


def test_missing_truncated_garbage_and_mismatched_files(files, tmp_path):
    vh_path, vs_path = files
    with pytest.raises(CheckpointError, match="not found"):
        load_vhat(tmp_path / "nope.pt")
    data = vh_path.read_bytes()
    (tmp_path / "trunc.pt").write_bytes(data[: len(data) // 2])
    with pytest.raises(CheckpointError, match="corrupted or truncated"):
        load_vhat(tmp_path / "trunc.pt")
    (tmp_path / "garbage.pt").write_bytes(b"not a checkpoint at all")
    with pytest.raises(CheckpointError, match="not a torch checkpoint"):
        load_vs(tmp_path / "garbage.pt")
    with pytest.raises(CheckpointError, match="'vs' value function, expected 'vhat'"):
        load_vhat(vs_path)
    torch.save({"weights": torch.zeros(3)}, tmp_path / "other.pt")
    with pytest.raises(CheckpointError, match="not a madpinn value-function checkpoint"):
        load_vs(tmp_path / "other.pt")
    payload = torch.load(vs_path, weights_only=True)
    payload["network"]["hidden"] = 32
    torch.save(payload, tmp_path / "shape.pt")
    with pytest.raises(CheckpointError, match="do not match"):
        load_vs(tmp_path / "shape.pt")


def test_bad_shapes_are_clear_errors(files):
    vhat = load_vhat(files[0])
    with pytest.raises(ValueError, match="disagree"):
        vhat.value(torch.zeros(4, 16), torch.zeros(3))
    with pytest.raises(ValueError, match="expected state"):
        load_vs(files[1]).value(torch.zeros(4, 3))


class _Runs:   # a pickle that would run a shell command if it were ever unpickled unsafely
    def __init__(self, marker):
        self.marker = str(marker)

    def __reduce__(self):
        import os

        return (os.system, (f"touch {self.marker}",))


def test_refused_checkpoints_say_what_happened_without_torchs_unsafe_advice(files, tmp_path):
    """Issue 35 item 5: a blocked pickle is not "corrupted or truncated"; no message repeats torch's
    advice that weights_only=False "will likely succeed", nor names a snakemake command on the
    user's own file; nothing in the file runs."""
    from madpinn.marl.checkpoint import CheckpointError as MarlCheckpointError, load_actor

    marker = tmp_path / "ran"
    torch.save({"x": _Runs(marker)}, tmp_path / "evil.pt")
    data = files[0].read_bytes()
    (tmp_path / "trunc.pt").write_bytes(data[: len(data) // 2])
    cases = {"evil.pt": "pickled Python objects (posix.system)", "trunc.pt": "corrupted or truncated"}
    for name, words in cases.items():
        for load, error in ((load_vhat, CheckpointError), (load_actor, MarlCheckpointError)):
            with pytest.raises(error) as exc:
                load(tmp_path / name)
            msg = str(exc.value)
            assert words in msg and "\n" not in msg, msg
            for advice in ("weights_only=False", "likely succeed", "snakemake", "trusted source"):
                assert advice not in msg, msg
    assert not marker.exists()


def test_resume_from_a_file_that_is_not_a_resume_checkpoint_refuses_and_keeps_it(files, tmp_path):
    """Issue 35 item 5: ``train-value --checkpoint BAD`` used to overwrite the user's file (an
    unreadable file, another kind's model, a finished model); now it stops and leaves it as it was."""
    from madpinn.value_functions.train import TrainSettings, train

    vh_path, vs_path = files
    bad = tmp_path / "mine.pt"
    bad.write_bytes(b"not a checkpoint at all")
    problem = EpigraphProblem(epigraph_system(z_max=21.45))
    s = TrainSettings(iterations=2, batch_size=16, lr=1e-4, lr_final=1e-5, curriculum_fraction=0.0, checkpoint_every=1,
                      output_scale=1.5, network=NET, seed=0, loss="l1", init_from=None, obstacle_weight=0.0, stop_at=None)
    for path, words in ((bad, "not a torch checkpoint"), (vs_path, "'vs' value function"), (vh_path, "finished vhat model")):
        before = path.read_bytes()
        with pytest.raises(CheckpointError, match=words) as exc:
            train(problem, s, path, "h", progress=False, stop_after=1)
        assert "left untouched" in str(exc.value) and path.read_bytes() == before


def test_resume_checkpoint_of_another_configuration_is_refused_and_kept(tmp_path):
    """A resume checkpoint written under another training hash (another configuration, or hours of
    another run) used to be ignored and overwritten from iteration 0; now it is refused, untouched."""
    from madpinn.value_functions.train import TrainSettings, train

    problem = EpigraphProblem(epigraph_system(z_max=21.45))
    s = TrainSettings(iterations=4, batch_size=16, lr=1e-4, lr_final=1e-5, curriculum_fraction=0.0, checkpoint_every=1,
                      output_scale=1.5, network=NET, seed=0, loss="l1", init_from=None, obstacle_weight=0.0, stop_at=None)
    ckpt = tmp_path / "run.ckpt.pt"
    train(problem, s, ckpt, "first", progress=False, stop_after=2)
    before = ckpt.read_bytes()
    with pytest.raises(CheckpointError, match="another training configuration") as exc:
        train(problem, s, ckpt, "second", progress=False, stop_after=1)
    assert "left untouched" in str(exc.value) and "\n" not in str(exc.value) and ckpt.read_bytes() == before
