"""Collision conventions (SPEC §1, issue 38): safety at any radius from one episode, contact
physics in MuJoCo (CF2X collision cylinders), the frozen-agent analogue in the double integrator."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import torch

from madpinn.config import REPO_ROOT, job_config, load_config, validate_config
from madpinn.evaluation.cell import CellSettings
from madpinn.evaluation.metrics import DISC_FACTOR, safety_curve, scenario_metrics, seed_summary
from madpinn.policies import PolicyContext, make_policy, policy_settings
from madpinn.scenarios import Arena, generate_scenarios
from madpinn.settings import AgentSettings
from madpinn.simulation.settings import SimSettings
from madpinn.simulation import make_backend, run_episode
from madpinn.simulation.mujoco.model import COLLISION_CYLINDER
from tests.mujoco_helpers import DT, DYN
from tests.settings_helpers import mujoco_section

R = 0.1


def _head_on(backend, s: int = 1, speed_s: float = 0.25, steps: int = 320) -> tuple[np.ndarray, np.ndarray]:
    """Two agents 1 m apart accelerate at each other for ``speed_s`` s (closing at 2 m/s), then
    coast; ``s`` identical scenarios. Returns planar positions ``[steps, s, 2, 2]`` and, for MuJoCo,
    altitudes ``[steps, s, 2]`` (zeros for the double integrator)."""
    p = torch.tensor([[-0.5, 0.0], [0.5, 0.0]], dtype=torch.float64).expand(s, 2, 2).contiguous()
    backend.reset(p, torch.zeros_like(p))
    push = torch.tensor([[4.0, 0.0], [-4.0, 0.0]], dtype=torch.float64).expand(s, 2, 2)
    pos, alt = [], []
    for k in range(steps):
        backend.command(push if k * DT < speed_s else torch.zeros_like(push), DT)
        pos.append(backend.step()[..., 0:2].to(torch.float64).numpy().copy())
        alt.append(backend.poses[..., 2].copy() if hasattr(backend, "poses") else np.zeros((s, 2)))
    return np.stack(pos), np.stack(alt)


def test_contact_drones_collide_and_both_leave_their_straight_paths():
    free, free_alt = _head_on(_mujoco(contacts=False))
    hit, hit_alt = _head_on(_mujoco(contacts=True))
    # pass-through: the drones cross on the x axis (the head-on course is symmetric: |y| ≈ 0)
    assert free[-1, 0, 0, 0] > free[-1, 0, 1, 0] + 0.2 and np.abs(free[..., 1]).max() < 1e-6
    assert np.abs(free_alt - 1.0).max() < 0.02
    # contacts: the cylinders touch (d < 2 × 0.06 m), and each drone ends up > 0.1 m (in the plane
    # plus altitude) from where the same commands put it without contact (≈ 0.2 m measured)
    sep = np.linalg.norm(hit[:, 0, 0] - hit[:, 0, 1], axis=-1)
    assert sep.min() < 2 * COLLISION_CYLINDER[0]
    off_path = np.linalg.norm(hit[:, 0] - free[:, 0], axis=-1) + np.abs(hit_alt[:, 0] - free_alt[:, 0])
    assert (off_path.max(axis=0) > 0.1).all(), off_path.max(axis=0)


def _mujoco(contacts: bool):
    from madpinn.simulation.mujoco import MujocoBackend, MujocoSettings

    torch.set_num_threads(1)
    return MujocoBackend(DYN, DT, MujocoSettings.from_config(mujoco_section()), dtype=torch.float64, contacts=contacts)


def test_drones_of_different_scenarios_never_interact():
    """Scenario 0 hovers a drone at the origin; scenario 1 flies a drone through the origin of its
    own frame. With contacts, each scenario's drones move exactly as when simulated alone."""
    starts = torch.tensor([[[0.0, 0.0], [0.8, 0.8]], [[-0.6, 0.0], [0.8, -0.8]]], dtype=torch.float64)
    accel = torch.zeros(2, 2, 2, dtype=torch.float64)
    accel[1, 0, 0] = 4.0

    def fly(idx):
        b = _mujoco(contacts=True)
        st = starts[idx]
        b.reset(st, torch.zeros_like(st))
        out = []
        for _ in range(360):   # 0.9 s: the flying drone crosses the origin
            b.command(accel[idx], DT)
            out.append(b.step().numpy().copy())
        return np.stack(out)

    both, alone0, alone1 = fly(slice(0, 2)), fly(slice(0, 1)), fly(slice(1, 2))
    assert both[:, 1, 0, 0].max() > 0.3   # scenario 1's drone passed the point scenario 0's drone holds
    np.testing.assert_allclose(both[:, 0:1], alone0, atol=1e-9)
    np.testing.assert_allclose(both[:, 1:2], alone1, atol=1e-9)


def test_contacts_keep_scenarios_whole_in_each_world():
    """Worlds split at scenario boundaries, so two drones of one scenario can always touch."""
    b = _mujoco(contacts=True)
    b.settings = dataclasses.replace(b.settings, drones_per_world=5)
    p = torch.zeros(3, 2, 2, dtype=torch.float64)
    p[:, 1, 0] = 0.5
    b.reset(p, torch.zeros_like(p))
    sizes = [sl.stop - sl.start for _, _, sl in b._worlds]
    assert sizes == [4, 2]


def test_double_integrator_freezes_collided_agents_and_keeps_them_as_obstacles():
    limits = dataclasses.replace(AgentSettings.from_config(load_config([REPO_ROOT / "config.yaml"])), collision_radius=R, u_max=4.0, v_max=4.0)
    sim = SimSettings(backend="double_integrator", dt=DT, policy_period_steps=1, scenario_batch=1, start_separation=0.2,
                      record_every=1, contacts=True, mujoco=None)
    frozen, _ = _head_on(make_backend("double_integrator", sim, limits, "cpu", torch.float64))
    passing, _ = _head_on(make_backend("double_integrator", dataclasses.replace(sim, contacts=False), limits,
                                       "cpu", torch.float64))
    assert passing[-1, 0, 0, 0] > passing[-1, 0, 1, 0]   # pass-through: they cross
    sep = np.linalg.norm(frozen[:, 0, 0] - frozen[:, 0, 1], axis=-1)
    k = int(np.argmax(sep <= R))
    assert sep[k] <= R and sep[k] > R - 2 * 4.0 * DT * 2   # stopped at the step they came within r
    np.testing.assert_array_equal(frozen[k:, 0], np.broadcast_to(frozen[k, 0], frozen[k:, 0].shape))


def _nominal_episode(cfg, radius: float, contacts: bool = False, record_every: int = 0):
    cs = CellSettings.from_config(cfg, "main", "nominal")
    arena = Arena.from_config(cfg, "small")
    starts, goals = generate_scenarios(arena, 12, 100, 8, 2 * R, "cpu", torch.float32)
    policy = make_policy("nominal", PolicyContext(method=policy_settings("nominal", cfg["methods"]["nominal"]),
                                                  dynamics=cs.limits.dynamics(), obs_spec=cs.observation,
                                                  device="cpu", dtype=torch.float32, seed=0, sim_dt=DT,
                                                  policy_period=1, models={}))
    sim = dataclasses.replace(cs.sim, backend="double_integrator", contacts=contacts)
    backend = make_backend("double_integrator", sim, cs.limits, "cpu", torch.float32)
    result, _ = run_episode(backend, policy, starts, goals, 400, radius, record_every=record_every, progress=False)
    return result


def test_safety_at_2r_from_recorded_separations_equals_a_direct_2r_episode():
    """Validation seed 100, 8 scenarios × 12 agents, the safety-blind nominal policy (whose actions
    do not depend on r): the agents safe at 2r by the recorded minimum separations are exactly those
    an episode recorded at 2r calls collision-free."""
    cfg = load_config(["config.yaml"])
    at_r, at_2r = _nominal_episode(cfg, R), _nominal_episode(cfg, DISC_FACTOR * R)
    np.testing.assert_array_equal(at_r.safe_at(DISC_FACTOR * R), ~at_2r.collided)
    np.testing.assert_array_equal(at_r.safe_at(R), ~at_r.collided)
    assert (at_r.collided != at_2r.collided).any()   # the two readings differ on these scenarios
    frame, frame_2r = scenario_metrics(at_r), scenario_metrics(at_2r)
    np.testing.assert_array_equal(frame["safety_rate_2r"], frame_2r["safety_rate"])
    np.testing.assert_array_equal(frame["safe_2r"], frame_2r["safe"])
    curve = safety_curve(frame, [0.0, R, DISC_FACTOR * R, 0.5])
    assert curve["safety_rate"].is_monotonic_decreasing
    assert curve["safety_rate"].iloc[1] == pytest.approx(seed_summary(frame)["safety_rate"], abs=1e-12)
    assert curve["safety_rate"].iloc[2] == pytest.approx(seed_summary(frame)["safety_rate_2r"], abs=1e-12)


def test_frozen_agents_stay_where_they_collided():
    """Double integrator with contacts, nominal policy, 8 scenarios × 12 agents (seed 100): every
    collided agent keeps the position of its first collision step to the end of the episode."""
    cfg = load_config(["config.yaml"])
    frozen = _nominal_episode(cfg, R, contacts=True, record_every=1)
    s, i = np.nonzero(frozen.collided)
    assert len(s) > 0
    for s_, i_ in zip(s, i):
        k = frozen.first_collision_step[s_, i_]
        track = frozen.positions[k:, s_, i_]
        np.testing.assert_array_equal(track, np.broadcast_to(track[0], track.shape))
    passing = _nominal_episode(cfg, R, record_every=1)
    moved = [np.ptp(passing.positions[k:, s_, i_], axis=0).max()
             for s_, i_, k in zip(s, i, frozen.first_collision_step[s, i])]
    assert max(moved) > 0.05   # without contacts the same agents kept moving


def test_study_sim_overrides_reach_the_cell_and_its_hash():
    cfg = load_config(["config.yaml"])
    cfg["sim"]["contacts"] = False
    cfg["studies"]["conflict_pairs"]["sim"] = {"contacts": True}
    assert CellSettings.from_config(cfg, "conflict_pairs", "nominal").sim.contacts is True
    assert CellSettings.from_config(cfg, "main", "nominal").sim.contacts is False
    plain = load_config(["config.yaml"])
    plain["sim"]["contacts"] = False
    assert job_config(cfg, "conflict_pairs", "nominal") != job_config(plain, "conflict_pairs", "nominal")
    assert job_config(cfg, "main", "nominal") == job_config(plain, "main", "nominal")


def test_collision_readings_table_from_real_cells(tmp_path):
    """Tiny MAD-PINN models, double integrator, 12 agents × 2 scenarios × 0.3 s of Table IV's k = 1
    and k = ∞, pass-through and with contacts: the readings table holds every reading, the paper's
    value, and the safety at 2r never exceeds the safety at r (a subset of agents, by construction)."""
    from test_madpinn_policy import models_of, tiny_cfg

    from madpinn.commands.evaluate import evaluate
    from madpinn.evaluation.readings import READINGS, format_readings, mean_gap, readings_table

    cfg = tiny_cfg(tmp_path)
    cfg["sim"]["backend"] = "double_integrator"
    cfg["arenas"]["small"]["episode_s"] = 0.3
    base = dict(arena="small", agent_counts=[12], seeds=[100], scenarios=2, runs=["madpinn-k1", "madpinn-kinf"])
    cfg["studies"]["ablation_update"] = {**base, "sim": {"contacts": False}}
    cfg["studies"]["ablation_update_contacts"] = {**base, "sim": {"contacts": True}}
    validate_config(cfg)   # fills the new studies' defaults, as the loader does
    paths = []
    for study in ("ablation_update", "ablation_update_contacts"):
        for run in base["runs"]:
            out = tmp_path / "eval" / study / run / "n12_seed100.parquet"
            evaluate(cfg, study, run, 12, 100, out, models=models_of(cfg), progress=False, track=False)
            paths.append(out)
    table = readings_table(paths, cfg, {"ablation_update": "table_update_ablation"})
    assert list(table["run"]) == ["madpinn-k1", "madpinn-kinf"]
    assert table["paper_safety"].tolist() == [0.9999, 0.1592]
    for reading in READINGS:
        assert table[reading].between(0, 1).all()
    assert (table["2r · pass"] <= table["r · pass"]).all() and (table["2r · contact"] <= table["r · contact"]).all()
    # the airframe-contact distance (0.12 m) lies between r and 2r: its safety between theirs, by construction
    from madpinn.evaluation.readings import CONTACT_COL
    assert CONTACT_COL == "0.12 m"
    for phys in ("pass", "contact"):
        assert (table[f"2r · {phys}"] <= table[f"0.12 m · {phys}"]).all() and (table[f"0.12 m · {phys}"] <= table[f"r · {phys}"]).all()
    gap = mean_gap(table)
    assert gap["r · pass"] == pytest.approx((table["r · pass"] - table["paper_safety"]).abs().mean())
    shown = format_readings(table)
    assert shown.iloc[-1]["Table"] == "mean |ours − paper|" and shown.iloc[-1]["r · pass"].endswith(" pp")


def test_a_contact_study_must_fly_with_contacts():
    from madpinn.config import ConfigError
    from madpinn.evaluation.readings import base_study

    cfg = load_config(["config.yaml"])
    cfg["sim"]["contacts"] = False
    cfg["studies"]["main_contacts"] = dict(cfg["studies"]["main"])
    with pytest.raises(ConfigError, match="sim.contacts"):
        base_study(cfg, "main_contacts")
    cfg["studies"]["main_contacts"]["sim"] = {"contacts": True}
    assert base_study(cfg, "main_contacts") == ("main", True) and base_study(cfg, "main") == ("main", False)


def test_the_reproduction_report_names_the_collision_convention():
    from madpinn.evaluation.reproduction import collision_convention

    cfg = load_config(["config.yaml"])
    assert "d ≤ r = 0.1 m" in collision_convention(cfg) and "contact physics" in collision_convention(cfg)
    cfg["sim"]["contacts"] = False
    assert "pass through" in collision_convention(cfg) and "d ≤ 2r = 0.2 m" in collision_convention(cfg)


def test_a_cell_counts_collisions_at_the_agents_radius_not_the_start_separation():
    """Reading (b) (``workflow/configs/reading_2r.yaml``): ``agents.collision_radius`` 0.2 m with the
    scenarios' ``sim.start_separation`` unchanged. The safety-blind nominal policy flies the same
    scenarios either way, so (pass-through) the 0.2 m cell's safety is the 0.1 m cell's safety at
    2r, and it is lower on these scenarios (validation seed 100, double integrator, 12 agents × 6
    scenarios, 3 s)."""
    from madpinn.evaluation.cell import run_cell

    cfg = load_config(["config.yaml"])
    cfg["sim"]["backend"], cfg["sim"]["contacts"] = "double_integrator", False   # pass-through: same paths
    cfg["arenas"]["small"]["episode_s"] = 3.0
    cfg["studies"]["main"]["scenarios"] = 6
    wide = load_config(["config.yaml", "workflow/configs/reading_2r.yaml"])
    wide["sim"], wide["arenas"], wide["studies"] = cfg["sim"], cfg["arenas"], cfg["studies"]
    assert wide["agents"]["collision_radius"] == DISC_FACTOR * R and wide["sim"]["start_separation"] == 2 * R
    at_r = run_cell(CellSettings.from_config(cfg, "main", "nominal"), 12, 100, progress=False)
    at_2r = run_cell(CellSettings.from_config(wide, "main", "nominal"), 12, 100, progress=False)
    assert at_2r.collision_radius == DISC_FACTOR * R
    np.testing.assert_array_equal(at_2r.frame["safety_rate"], at_r.frame["safety_rate_2r"])
    assert at_2r.summary["safety_rate"] < at_r.summary["safety_rate"]
