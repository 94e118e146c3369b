"""The 3-D double integrator through the seam (issue 63 item 2): one module
(``madpinn/dynamics/double_integrator_3d.py``) and one schema entry (``agents.model`` with its
``altitude_band``). Its dynamics, its configuration (and that the planar default leaves every hash
as it was), V̂ and V_s trained for it on the smoke budget, a tiny evaluation cell under MAD-PINN
and MAD-PINN + CBVF filter, two kinds of agents in one 3-D scenario, and the policies that stay
planar refusing it with one clear line."""

from __future__ import annotations

import copy

import pytest
import torch

from conftest import REPO, SMOKE
from madpinn.config import hashed_agents, load_config, subtree_hash
from madpinn.config.hashing import PAPER_AGENT_MODEL
from madpinn.config.schema import node_at
from madpinn.dynamics import PAPER_MODEL, DoubleIntegrator
from madpinn.dynamics.double_integrator_3d import DoubleIntegrator3D
from madpinn.evaluation.cell import CellSettings, run_cell
from madpinn.observation import ObservationSettings, split_observation
from madpinn.policies.nominal import NominalPD
from madpinn.settings import AgentSettings
from madpinn.simulation import DoubleIntegratorBackend, run_episode
from madpinn.value_functions.build import problem_from_config, training_hash
from policy_models import smoke_config_3d, tiny_model_dir, tiny_models

BAND = (0.5, 1.5)
DT = 0.0025


def test_the_3d_step_is_the_planar_step_per_axis_inside_the_band():
    g = torch.Generator().manual_seed(0)
    p = torch.cat([torch.rand(64, 2, generator=g) * 2 - 1, 0.75 + 0.5 * torch.rand(64, 1, generator=g)], -1).double()
    v = (torch.rand(64, 3, generator=g) - 0.5).double()
    u = (torch.rand(64, 3, generator=g) * 8 - 4).double()
    three, flat = DoubleIntegrator3D(4.0, 4.0, BAND), DoubleIntegrator(4.0, 4.0)
    s = three.step(torch.cat([p, v], -1), u, 0.05)
    for axes in ([0, 1], [1, 2]):   # any two axes of the 3-D step are the planar model's step
        planar = flat.step(torch.cat([p[:, axes], v[:, axes]], -1), u[:, axes], 0.05)
        assert torch.equal(s[:, axes], planar[:, :2]) and torch.equal(s[:, [a + 3 for a in axes]], planar[:, 2:])


def test_the_altitude_stays_in_the_band_and_outward_vertical_speed_stops():
    model = DoubleIntegrator3D(4.0, 4.0, BAND)
    state = torch.tensor([[0.0, 0.0, 1.45, 0.0, 0.0, 3.0], [0.0, 0.0, 0.55, 0.0, 0.0, -3.0]], dtype=torch.float64)
    out = model.step(state, torch.tensor([[0.0, 0.0, 4.0], [0.0, 0.0, -4.0]], dtype=torch.float64), 0.1)
    assert out[:, 2].tolist() == [1.5, 0.5] and out[:, 5].tolist() == [0.0, 0.0]
    down = model.step(out, torch.tensor([[0.0, 0.0, -4.0], [0.0, 0.0, 4.0]], dtype=torch.float64), 0.1)
    assert down[0, 2] < 1.5 and down[1, 2] > 0.5   # the band is a floor and a ceiling, not a trap
    assert model.place(torch.zeros(2, 2)).tolist() == [[0.0, 0.0, 1.0], [0.0, 0.0, 1.0]]
    with pytest.raises(ValueError, match="z_lo < z_hi"):
        DoubleIntegrator3D(4.0, 4.0, (1.0, 1.0))
    with pytest.raises(ValueError, match=r"expected state \[\.\.\.,6\]"):
        model.step(torch.zeros(1, 4), torch.zeros(1, 3), 0.1)


def test_one_schema_entry_chooses_the_model_and_the_planar_default_keeps_every_hash():
    paper = load_config([REPO / "config.yaml"])
    three = smoke_config_3d()
    assert node_at("agents.model")["default"] == PAPER_AGENT_MODEL == PAPER_MODEL == DoubleIntegrator.name
    assert isinstance(AgentSettings.from_config(paper).dynamics(), DoubleIntegrator)
    model = AgentSettings.from_config(three).dynamics()
    assert isinstance(model, DoubleIntegrator3D) and model.altitude_band == tuple(node_at("agents.altitude_band")["default"])
    # the planar model hashes `agents` as before the keys existed; the 3-D one hashes them
    bare = {k: v for k, v in paper["agents"].items() if k not in ("model", "altitude_band")}
    assert hashed_agents(paper["agents"]) == bare
    assert subtree_hash(paper, ("agents",)) == subtree_hash({"agents": bare}, ("agents",))
    smoke = load_config([REPO / "config.yaml", SMOKE])
    assert training_hash(three, "vhat") != training_hash(smoke, "vhat") and training_hash(three, "vs") != training_hash(smoke, "vs")
    other_band = copy.deepcopy(three)
    other_band["agents"]["altitude_band"] = [0.2, 2.0]
    assert training_hash(other_band, "vs") != training_hash(three, "vs")
    with pytest.raises(ValueError, match="unknown agent model"):
        AgentSettings(0.1, 4.0, 4.0, "unicycle", BAND)


def test_the_value_problems_take_the_3d_layout():
    cfg = smoke_config_3d()
    vhat, vs = problem_from_config(cfg, "vhat"), problem_from_config(cfg, "vs")
    n = cfg["observation"]["n_neighbours"]
    assert vs.state_dim == 6 and vhat.state_dim == 6 + 9 * n + 1   # [o (2d + 3d·n), z]
    assert vhat.system.velocity_index().tolist() == [[0, 1, 2]] + [[6 + 9 * j + 3 + k for k in range(3)] for j in range(n)]
    g = torch.Generator().manual_seed(1)
    s = vs.sample_training_states(512, g, torch.float64)
    assert s.shape == (512, 6) and (s[:, :3].abs() <= vs.system.p_range).all()
    assert vs.describe()["model"] == "double_integrator_3d"
    assert type(vs).from_description(vs.describe()).system == vs.system
    assert type(vhat).from_description(vhat.describe()).system == vhat.system
    # the planar descriptions are those of every checkpoint so far: no model key
    planar = problem_from_config(load_config([REPO / "config.yaml", SMOKE]), "vs")
    assert "model" not in planar.describe() and "model" not in problem_from_config(load_config([REPO / "config.yaml", SMOKE]), "vhat").describe()["spec"]


def test_vhat_and_vs_train_for_the_3d_model_on_the_smoke_budget():
    vhat, vs = tiny_models(torch.float64, three_d=True)
    assert vhat.obs_spec.model == vs.system.model == "double_integrator_3d"
    g = torch.Generator().manual_seed(2)
    x = vs.system.sample(64, g, dtype=torch.float64)
    v, grad = vs.value_and_grad(x, 0.0)
    assert grad.shape == (64, 6) and torch.isfinite(v).all()
    # V_s never exceeds the current margin ψ (the exact terminal parameterisation at t = T)
    assert torch.allclose(vs.value(x, vs.horizon), vs.system.target(x), atol=1e-9)


@pytest.mark.parametrize("run,backend", [("madpinn", "double_integrator"), ("madpinn-filtered", "double_integrator"),
                                         ("madpinn", "mujoco")])
def test_a_tiny_3d_evaluation_cell(run, backend):
    """One cell of the 3-D model on each backend (MuJoCo: the drones fly the policy's altitude setpoint)."""
    if backend == "mujoco":
        pytest.importorskip("mujoco")
    cfg = smoke_config_3d()
    models = {"vhat": tiny_model_dir(True) / "vhat.pt", "vs": tiny_model_dir(True) / "vs.pt"}
    cs = CellSettings.from_config(cfg, "main", run)
    cell = run_cell(cs, 3, 100, models=models, backend=backend, progress=False)
    assert len(cell.frame) == cs.scenarios and cell.trajectory.positions.shape[-1] == 3
    assert cell.summary["backend"] == backend
    z = torch.from_numpy(cell.trajectory.positions[..., 2])
    slack = 1e-9 if backend == "double_integrator" else 0.05   # the drones track the banded reference (m)
    assert (z >= BAND[0] - slack).all() and (z <= BAND[1] + slack).all()
    assert cell.trajectory.goals[..., 2].tolist() == [[1.0] * 3] * cell.trajectory.goals.shape[0]


def test_two_kinds_of_3d_agents_under_the_nominal_pd():
    """Per-agent bounds on the 3-D model: a fast and a slow pair, each within its own v_max."""
    kinds = [(4.0, 4.0)] * 2 + [(1.0, 0.5)] * 2
    model = DoubleIntegrator3D(tuple(k[0] for k in kinds), tuple(k[1] for k in kinds), BAND)
    starts = model.place(torch.tensor([[[-1.5, -0.125], [-1.5, 0.125], [1.5, -0.125], [1.5, 0.125]]], dtype=torch.float64))
    goals = starts + torch.tensor([[[0.0, -3.0, 0.4], [0.0, 3.0, -0.4], [0.0, -1.0, 0.4], [0.0, 1.0, -0.4]]], dtype=torch.float64)
    res, _ = run_episode(DoubleIntegratorBackend(model, DT), NominalPD(model, 6.0, 4.9), starts, goals, 200, (0.1, 0.1, 0.3, 0.3),
                         record_every=1, progress=False)
    steps = torch.from_numpy(res.positions).diff(dim=0).abs()           # [T, 1, N, 3]
    bound = torch.tensor([k[1] for k in kinds], dtype=torch.float64)[:, None] * DT
    assert (steps <= bound + 1e-12).all() and steps[:, 0, :2].max() > 2 * kinds[2][1] * DT
    z = torch.from_numpy(res.positions[..., 2])
    assert (z >= BAND[0] - 1e-12).all() and (z <= BAND[1] + 1e-12).all()
    assert (z[-1, 0, [0, 2]] > 1.05).all() and (z[-1, 0, [1, 3]] < 0.95).all()   # toward goals 0.4 m above / below


def test_two_kinds_of_3d_agents_under_madpinn():
    """Per-agent bounds on the 3-D model under MAD-PINN (its bang-bang command clipped by each agent's
    box in the backend), with the 3-D V̂ and V_s trained on the smoke budget."""
    from madpinn.policies.madpinn import MadPinnPolicy
    from madpinn.policies.neighbours import make_selector
    from settings_helpers import madpinn_settings

    vhat, vs = tiny_models(torch.float64, three_d=True)
    spec = ObservationSettings.from_config(smoke_config_3d())
    kinds = [(4.0, 4.0)] * 2 + [(1.0, 0.5)] * 2
    model = DoubleIntegrator3D(tuple(k[0] for k in kinds), tuple(k[1] for k in kinds), BAND)
    selector = make_selector("value", spec.n_neighbours, vs=vs, radius=spec.sensing_radius)
    pol = MadPinnPolicy(vhat, selector, spec, madpinn_settings(), sim_dt=DT)
    starts = model.place(torch.tensor([[[-1.5, -0.125], [-1.5, 0.125], [1.5, -0.125], [1.5, 0.125]]], dtype=torch.float64))
    goals = starts + torch.tensor([[[0.0, -3.0, 0.0], [0.0, 3.0, 0.0], [0.0, -1.0, 0.0], [0.0, 1.0, 0.0]]], dtype=torch.float64)
    res, _ = run_episode(DoubleIntegratorBackend(model, DT), pol, starts, goals, 100, (0.1, 0.1, 0.3, 0.3),
                         record_every=1, progress=False)
    steps = torch.from_numpy(res.positions).diff(dim=0).abs()
    bound = torch.tensor([k[1] for k in kinds], dtype=torch.float64)[:, None] * DT
    assert (steps <= bound + 1e-12).all()
    assert res.collided.tolist() == [[False, False, True, True]]   # the slow pair starts inside its 0.3 m radius


def test_the_validation_figures_slice_the_3d_models_in_the_horizontal_plane():
    """The V̂ heatmap and the V_s slices of a 3-D model: its agents at one altitude, no vertical
    motion; the same numbers as the planar layout would give those agents."""
    from madpinn.value_functions.validation import HEATMAP, heatmap_observations, vs_slices

    vhat, vs = tiny_models(torch.float64, three_d=True)
    axis, obs = heatmap_observations(vhat.obs_spec, points=11)
    assert obs.shape == (121, vhat.obs_spec.dim)
    pos, vel, goal = split_observation(obs, 2)                          # [121, 3, 3] each
    assert (pos[..., 2] == 0).all() and (vel[..., 2] == 0).all() and (goal[..., 2] == 0).all()
    assert torch.equal(vel[:, 0, :2], torch.tensor(HEATMAP["ego_velocity"]).expand(121, -1))
    axis, values = vs_slices(vs, [(1.0, 0.0)], points=9)
    assert values.shape == (1, 9, 9) and torch.isfinite(values).all()


def test_the_planar_policies_refuse_the_3d_model_with_one_clear_line():
    from madpinn.marl.features import local_observation
    from madpinn.policies.mppi import MPPIPlanner
    from madpinn.value_functions.grid_reference import solve_pair_grid

    model = DoubleIntegrator3D(4.0, 4.0, BAND)
    with pytest.raises(ValueError, match="MPPI plans for the paper's planar"):
        MPPIPlanner(None, model, 0.1, torch.Generator())
    spec = ObservationSettings.from_config(smoke_config_3d())
    with pytest.raises(ValueError, match="MARL baselines are trained on the paper's"):
        local_observation(torch.zeros(1, 3, 6), torch.zeros(1, 3, 3), spec, 2)
    with pytest.raises(ValueError, match="grid reference solves the planar pair"):
        solve_pair_grid(problem_from_config(smoke_config_3d(), "vs").system, 5, 1.0, 1.0, (0.0,))


def test_mujoco_flies_the_policys_altitude_setpoint():
    """On the MuJoCo backend the 3-D model's reference carries the altitude: drones start at their
    own z, and a climb command moves the setpoint and the drone up (the planar model holds
    sim.mujoco.altitude)."""
    pytest.importorskip("mujoco")
    from madpinn.simulation.mujoco import MujocoBackend, MujocoSettings
    from settings_helpers import mujoco_section

    torch.set_num_threads(1)
    model = DoubleIntegrator3D(4.0, 4.0, BAND)
    backend = MujocoBackend(model, DT, MujocoSettings.from_config(mujoco_section()), dtype=torch.float64)
    p0 = torch.tensor([[[0.0, 0.0, 0.8], [0.5, 0.0, 1.2]]], dtype=torch.float64)
    state = backend.reset(p0, torch.zeros_like(p0))
    assert state.shape == (1, 2, 6) and torch.allclose(state[..., 2], p0[..., 2])
    backend.command(torch.tensor([[[0.0, 0.0, 2.0], [0.0, 0.0, -2.0]]], dtype=torch.float64), 0.2)
    for _ in range(80):   # 0.2 s: the setpoint moves by ±a·t²/2 = ±0.04 m
        state = backend.step()
    ref_z = torch.from_numpy(backend.reference[:, 2])
    assert torch.allclose(ref_z, torch.tensor([0.84, 1.16], dtype=torch.float64), atol=1e-9)
    assert state[0, 0, 2] > 0.81 and state[0, 1, 2] < 1.19          # the drones follow up and down
