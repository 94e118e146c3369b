"""MuJoCo backend protocol: shapes, determinism, world splitting, config, bad input."""

import math

import pytest
import torch

from madpinn.config import REPO_ROOT, load_config
from madpinn.settings import AgentSettings
from madpinn.simulation.settings import SimSettings
from madpinn.simulation import make_backend as make_registered_backend
from madpinn.simulation.mujoco import MujocoBackend, MujocoSettings, PhysicsDivergedError
from mujoco_helpers import DT, bang_bang, make_backend
from settings_helpers import mujoco_section


def _run(backend, accel):
    starts = torch.tensor([[[0.0, 0.0], [0.5, 0.5], [-0.5, 0.2]], [[0.1, -0.3], [0.7, 0.0], [0.0, 0.9]]], dtype=torch.float64)
    states = [backend.reset(starts, torch.zeros_like(starts))]
    for a in accel:
        backend.command(a, DT)
        states.append(backend.step())
    return torch.stack(states)


def test_registered_backend_returns_planar_state_on_requested_dtype():
    cfg = load_config([REPO_ROOT / "config.yaml"])
    cfg["sim"]["contacts"] = False   # random starts may overlap; contacts: tests/test_collision_conventions.py
    backend = make_registered_backend("mujoco", SimSettings.from_config(cfg), AgentSettings.from_config(cfg),
                                      torch.device("cpu"), torch.float32)
    assert isinstance(backend, MujocoBackend) and backend.dt == cfg["sim"]["dt"]
    starts = torch.rand(2, 5, 2)
    state = backend.reset(starts, torch.zeros_like(starts))
    assert state.shape == (2, 5, 4) and state.dtype == torch.float32
    torch.testing.assert_close(state[..., 0:2], starts)
    backend.command(torch.full((2, 5, 2), 4.0), backend.dt)
    state = backend.step()
    assert state.shape == (2, 5, 4) and state.dtype == torch.float32
    assert (state[..., 2:4] > 0).all()  # moving along the commanded acceleration


def test_same_inputs_give_identical_trajectories():
    accel = bang_bang(6, 200, 0.05, seed=3).reshape(200, 2, 3, 2)
    a = _run(make_backend(), accel)
    b = _run(make_backend(), accel)
    assert torch.equal(a, b)


def test_splitting_into_worlds_does_not_change_the_physics():
    accel = bang_bang(6, 200, 0.05, seed=4).reshape(200, 2, 3, 2)
    one_world = _run(make_backend(drones_per_world=64), accel)
    three_worlds = _run(make_backend(drones_per_world=2), accel)
    assert torch.equal(one_world, three_worlds)


def test_settings_are_the_config_section():
    cfg = load_config([REPO_ROOT / "config.yaml"])
    assert MujocoSettings.from_config(cfg["sim"]["mujoco"]).as_dict() == cfg["sim"]["mujoco"]


@pytest.mark.parametrize("section, match", [
    ({"substeps": 0}, "substeps"),
    ({"force_application": "magic"}, "force_application"),
    ({"gains": {"att_rp": -1.0}}, "att_rp"),
    ({"gains": {"max_tilt_deg": 95.0}}, "max_tilt_deg"),
    ({"thrust_to_weight": 0.8}, "thrust_to_weight"),
    ({"colour": "red"}, "unknown"),
    ({"gains": {"kp": 1.0}}, "unknown"),
])
def test_bad_settings_are_rejected(section, match):
    with pytest.raises(ValueError, match=match):
        MujocoSettings.from_config(mujoco_section(**section))


def test_bad_inputs_give_clear_errors():
    backend = make_backend(max_drones=8)
    with pytest.raises(RuntimeError, match="reset"):
        backend.command(torch.zeros(1, 2, 2, dtype=torch.float64), DT)
    with pytest.raises(RuntimeError, match="reset"):
        backend.step()
    with pytest.raises(ValueError, match=r"1\.\.8 drones"):
        backend.reset(torch.zeros(3, 3, 2), torch.zeros(3, 3, 2))
    with pytest.raises(ValueError, match=r"1\.\.8 drones"):
        backend.reset(torch.zeros(1, 0, 2), torch.zeros(1, 0, 2))
    with pytest.raises(ValueError, match=r"\[S, N, 2\]"):
        backend.reset(torch.zeros(2, 2), torch.zeros(2, 2))
    with pytest.raises(ValueError, match="non-finite"):
        backend.reset(torch.full((1, 2, 2), math.nan), torch.zeros(1, 2, 2))
    backend.reset(torch.zeros(1, 2, 2), torch.zeros(1, 2, 2))
    with pytest.raises(ValueError, match="NaN"):
        backend.command(torch.tensor([[[math.nan, 0.0], [0.0, 0.0]]]), DT)
    with pytest.raises(ValueError, match="accel must be"):
        backend.command(torch.zeros(1, 3, 2), DT)
    with pytest.raises(ValueError, match="duration"):
        backend.command(torch.zeros(1, 2, 2), 0.0)
    with pytest.raises(ValueError, match="non-finite position"):
        backend.hold(torch.full((1, 2, 2), math.inf))
    with pytest.raises(ValueError, match="sim.dt"):
        MujocoBackend(backend.dynamics, 0.0, backend.settings)


def test_unstable_physics_fails_with_a_clear_error(tmp_path, monkeypatch):
    # a rate loop far too fast for a 50 ms physics step diverges: the backend must stop, not
    # return MuJoCo's silently reset state
    monkeypatch.chdir(tmp_path)  # MuJoCo writes its warning to ./MUJOCO_LOG.TXT
    settings = MujocoSettings.from_config(mujoco_section(substeps=1, gains={"rate_rp": 400.0, "att_rp": 100.0}))
    unstable = MujocoBackend(make_backend().dynamics, 0.05, settings, dtype=torch.float64)
    starts = torch.zeros(1, 2, 2, dtype=torch.float64)
    unstable.reset(starts, starts)
    with pytest.raises(PhysicsDivergedError, match="unstable|non-finite"):
        for _ in range(400):
            unstable.command(torch.full((1, 2, 2), 4.0, dtype=torch.float64), 0.05)
            unstable.step()
