"""The 3-D study as a workflow output (issue 63 item 2): a study declares its agent model
(``studies.<s>.agents``), V̂ / V_s variants are trained for it (their ``agents``), the config check
refuses what cannot fly it in one line each, its cells fly the 3-D dynamics, the workflow plans the
variants' trainings and the table, and the table is built end to end from smoke-budget cells; the
planar studies and models keep every hash."""

from __future__ import annotations

import copy
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import torch
import yaml

from conftest import REPO, SMOKE
from madpinn.config import (ConfigError, RunSettings, deep_merge, hashed_method, job_config, load_config,
                            validate_config, with_vf_variant)
from madpinn.dynamics import DoubleIntegrator
from madpinn.dynamics.double_integrator_3d import DoubleIntegrator3D
from madpinn.evaluation.agent_models import TITLE, agent_models_table, recorded_passes
from madpinn.evaluation.cell import CellSettings, run_cell, write_cell
from madpinn.provenance import model_training_hash, registry

OVERLAY = REPO / "workflow" / "configs" / "agent_models.yaml"
STUDIES = ("model_planar", "model_3d", "model_planar_mujoco", "model_3d_mujoco")


def smoke_overlay(scenarios: int = 2, seeds=(100,)) -> dict:
    """The agent-model overlay at smoke size: 3 agents, the given validation seeds and scenarios."""
    cfg = yaml.safe_load(OVERLAY.read_text())
    for name in STUDIES:
        cfg["studies"][name].update(agent_counts=[3], seeds=list(seeds), scenarios=scenarios)
    return cfg


def configured(tmp_path: Path, *extra: dict, scenarios: int = 2, seeds=(100,)) -> dict:
    """config.yaml + smoke + the agent-model overlay at smoke size (+ ``extra`` overlays), validated."""
    path = tmp_path / "agent_models_smoke.yaml"
    overlay = smoke_overlay(scenarios, seeds)
    for e in extra:
        overlay = deep_merge(overlay, e)
    path.write_text(yaml.safe_dump(overlay, sort_keys=False))
    return load_config([REPO / "config.yaml", SMOKE, path])


# --- the study's model reaches its cells ---------------------------------------------------------------------------

def test_a_study_flies_its_own_model_and_the_planar_one_keeps_its_hash(tmp_path):
    cfg = configured(tmp_path)
    three, planar = CellSettings.from_config(cfg, "model_3d", "madpinn-3d"), CellSettings.from_config(cfg, "model_planar", "madpinn")
    assert type(three.limits.dynamics()) is DoubleIntegrator3D and three.limits.dynamics().altitude_band == (0.5, 1.5)
    assert type(planar.limits.dynamics()) is DoubleIntegrator
    assert three.observation.agent.position_dim == 3 and planar.observation.agent.position_dim == 2
    assert cfg["agents"]["model"] == "double_integrator"           # the shared section stays planar
    r = RunSettings.resolve(cfg, "model_3d", "madpinn-3d")
    assert (r.vhat, r.vs) == ("vhat_3d", "vs_3d") and r.study_agents["model"] == "double_integrator_3d"
    # the planar study hashes as a study without the keys would; a base run hashes without `vs: null`
    bare = copy.deepcopy(cfg)
    assert job_config(bare, "model_planar", "madpinn") == job_config(cfg, "model_planar", "madpinn")
    assert "vs" not in job_config(cfg, "model_planar", "madpinn")["method_config"]
    assert job_config(cfg, "model_3d", "madpinn-3d")["method_config"]["vs"] == "3d"
    assert hashed_method({"vs": None, "validation": 1, "a": 2}) == {"a": 2}
    # the study's agents overlay is what separates the two studies' hashes besides the run
    assert job_config(cfg, "model_3d", "madpinn-3d")["agents"]["model"] == "double_integrator_3d"


def test_the_planar_models_and_cells_keep_their_hashes_and_the_3d_variants_get_their_own(tmp_path):
    plain = load_config([REPO / "config.yaml"])
    cfg = load_config([REPO / "config.yaml", OVERLAY])
    for name in ("vhat", "vs", "vhat_h04", "vhat_s1"):
        assert model_training_hash(cfg, name) == model_training_hash(plain, name)
    for study in ("main", "scaling", "gap_mujoco"):
        for run in plain["studies"][study]["runs"]:
            assert job_config(cfg, study, run) == job_config(plain, study, run)
    three = {name: model_training_hash(cfg, name) for name in ("vhat_3d", "vs_3d")}
    assert three["vhat_3d"] not in (model_training_hash(plain, "vhat"), None)
    assert three["vs_3d"] not in (model_training_hash(plain, "vs"), None)
    trained = with_vf_variant(cfg, "vs", "3d")
    assert trained["agents"]["model"] == "double_integrator_3d" and "agents" not in trained["value_functions"]["vs"]
    assert trained["value_functions"]["vs"] == cfg["value_functions"]["vs"]   # the base recipe, another model


def test_a_3d_study_cell_flies_the_3d_dynamics(tmp_path):
    """A cell of the 3-D study under MAD-PINN with the 3-D value functions (smoke budget): its
    agents start at the band's middle and change altitude; the planar study's cell, on the same
    scenarios, stays in the plane."""
    from policy_models import tiny_model_dir

    cfg = configured(tmp_path)
    three_models = {k: tiny_model_dir(True) / f"{k}.pt" for k in ("vhat", "vs")}
    cell = run_cell(CellSettings.from_config(cfg, "model_3d", "madpinn-3d"), 3, 100, models=three_models,
                    backend="double_integrator", progress=False)
    pos = cell.trajectory.positions                                     # [T, S, N, 3]
    assert pos.shape[-1] == 3 and np.allclose(pos[0, ..., 2], 1.0)
    assert np.abs(pos[..., 2] - 1.0).max() > 1e-3                      # the altitude moves
    assert (pos[..., 2] >= 0.5 - 1e-9).all() and (pos[..., 2] <= 1.5 + 1e-9).all()
    planar_models = {k: tiny_model_dir(False) / f"{k}.pt" for k in ("vhat", "vs")}
    flat = run_cell(CellSettings.from_config(cfg, "model_planar", "madpinn"), 3, 100, models=planar_models,
                    backend="double_integrator", progress=False)
    assert flat.trajectory.positions.shape[-1] == 2
    np.testing.assert_allclose(flat.trajectory.positions[0], pos[0, ..., :2])   # the same starts in the plane
    with pytest.raises(ValueError, match="V̂ was trained with observation.model = double_integrator"):   # a planar V̂ cannot fly it
        run_cell(CellSettings.from_config(cfg, "model_3d", "madpinn-3d"), 3, 100, models=planar_models,
                 backend="double_integrator", progress=False)


def test_the_methods_that_fly_a_model_are_the_policies_that_accept_it():
    """The schema's x-flown-by names the policies that fly the 3-D model; the rest refuse it when built or run
    (MPPI here; the MARL baselines' features: tests/test_agent_model_3d.py)."""
    from madpinn.policies import PolicyContext, make_policy, policy_settings
    from madpinn.observation import ObservationSettings
    from policy_models import smoke_config_3d

    cfg = smoke_config_3d()
    from madpinn.config.schema import node_at
    from madpinn.dynamics import MODELS, PAPER_MODEL

    from madpinn.config import model_methods

    MODEL_METHODS = model_methods()
    assert set(MODEL_METHODS) == set(node_at("agents.model")["enum"]) - {PAPER_MODEL} == set(MODELS) - {PAPER_MODEL}
    assert set(MODEL_METHODS["double_integrator_3d"]) < set(registry("madpinn.policies.base"))
    assert set(registry("madpinn.policies.base")) - set(MODEL_METHODS["double_integrator_3d"]) == {"mppi", "safemarl", "defmarl"}
    model = DoubleIntegrator3D(4.0, 4.0, (0.5, 1.5))
    ctx = PolicyContext(method=policy_settings("mppi", cfg["methods"]["mppi"]), dynamics=model,
                        obs_spec=ObservationSettings.from_config(cfg), device=torch.device("cpu"), dtype=torch.float64,
                        seed=0, sim_dt=0.0025, policy_period=1)
    with pytest.raises(ValueError, match="MPPI plans for the paper's planar"):
        make_policy("mppi", ctx)
    nominal = run_cell(CellSettings.from_config(cfg, "main", "nominal"), 3, 100, backend="double_integrator", progress=False)
    assert nominal.trajectory.positions.shape[-1] == 3


# --- one-line errors at config check -------------------------------------------------------------------------------

@pytest.mark.parametrize("extra,message", [
    ({"studies": {"model_3d": {"runs": ["madpinn-3d", "mppi"]}}},
     r"'studies.model_3d.runs': run 'mppi' cannot fly the study's agent model double_integrator_3d \(the methods that do: madpinn, nominal; "
     r"the schema's agent_model x-flown-by\)"),
    ({"studies": {"model_3d": {"runs": ["madpinn"]}}},
     r"run 'madpinn' loads a V̂ trained for double_integrator, but the study flies double_integrator_3d"),
    ({"methods": {"madpinn": {"variants": {"3d": {"vs": None}}}}},
     r"run 'madpinn-3d' loads a V_s trained for double_integrator, but the study flies double_integrator_3d"),
    ({"studies": {"model_3d": {"agents": {"altitude_band": [0.2, 2.0]}}}},
     r"loads a V̂ trained for double_integrator_3d \(altitude band \[0.5, 1.5\] m\), but the study flies "
     r"double_integrator_3d \(altitude band \[0.2, 2.0\] m\)"),
    ({"methods": {"madpinn": {"variants": {"3d": {"vs": "nope"}}}}},
     r"'methods.madpinn.variants.3d.vs': unknown V_s variant 'nope' \(value_functions.vs_variants: 3d\)"),
    ({"studies": {"model_3d": {"agents": {"model": "unicycle"}}}}, r"'studies.model_3d.agents.model': 'unicycle' is not one of"),
    ({"value_functions": {"vs_variants": {"3d": {"agents": {"mass": 1.0}}}}}, r"value_functions.vs_variants.3d.agents"),
    ({"studies": {"model_3d": {"seeds": [0]}}}, r"'studies.model_3d.seeds': the agent-model table runs on validation seeds ≥ 100 only"),
    ({"studies": {"model_3d": {"scenarios": 3}}}, r"'studies.model_3d': the agent-model table pairs the same scenarios; its scenarios differ"),
    ({"agent_models": {"studies": ["model_3d", "model_3d_mujoco"]}},
     r"on backend double_integrator one study must fly the planar model double_integrator \(the reference\)"),
    ({"studies": {"model_3d": {"runs": ["madpinn-3d", "nominal"]}}}, r"run 'nominal' has no planar reference in studies.model_planar"),
])
def test_the_config_check_refuses_in_one_line(tmp_path, extra, message):
    import re

    with pytest.raises(ConfigError) as err:
        configured(tmp_path, extra)
    assert any(re.search(message, line) for line in str(err.value).splitlines()), str(err.value)


def test_a_global_3d_model_refuses_the_planar_baselines_too(tmp_path):
    cfg = load_config([REPO / "config.yaml", SMOKE])
    cfg = deep_merge({k: v for k, v in cfg.items() if k != "_defaults_filled"}, {"agents": {"model": "double_integrator_3d"}})
    with pytest.raises(ConfigError, match=r"'studies.main.runs': run 'mppi' cannot fly the study's agent model"):
        validate_config(cfg)


# --- the workflow: the study's DAG ---------------------------------------------------------------------------------

def test_the_dry_run_plans_the_3d_trainings_the_cells_and_the_table(tmp_path):
    from workflow_helpers import copy_repo, planned_jobs, run_in

    copy = copy_repo(tmp_path / "repo")
    (copy / "agent_models_smoke.yaml").write_text(yaml.safe_dump(smoke_overlay(), sort_keys=False))
    plain = planned_jobs(run_in(copy, "-n", "all"))
    with_overlay = planned_jobs(run_in(copy, "-n", "all", configfiles=("smoke.yaml", "agent_models_smoke.yaml")))
    assert with_overlay == plain                                        # not in all
    proc = run_in(copy, "-n", "-p", "table_agent_models", configfiles=("smoke.yaml", "agent_models_smoke.yaml"))
    jobs = planned_jobs(proc)
    want = {"train_vhat": 1, "train_vs": 1, "train_vhat_variant": 1, "train_vs_variant": 1, "evaluate": 4, "table_agent_models": 1}
    assert {k: jobs.get(k) for k in want} == want, jobs
    assert not {"train_safemarl_nominal", "train_defmarl", "oracle"} & set(jobs), jobs
    out = proc.stdout
    assert "train-value" in out and "--kind vs --variant 3d" in out and "--kind vhat --variant 3d" in out
    evals = [ln for ln in out.splitlines() if "python -m madpinn evaluate" in ln]
    three = [ln for ln in evals if "--study model_3d" in ln]
    assert len(three) == 2 and all("vhat=results/agent_models/models/vhat_3d.pt" in ln and
                                   "vs=results/agent_models/models/vs_3d.pt" in ln for ln in three)
    assert all("vhat=results/agent_models/models/vhat.pt" in ln and "vs=results/agent_models/models/vs.pt" in ln
               for ln in evals if "--study model_planar" in ln)
    assert any("--backend mujoco" in ln for ln in three) and any("--backend double_integrator" in ln for ln in three)


# --- the table, end to end -----------------------------------------------------------------------------------------

def test_the_table_from_smoke_budget_cells(tmp_path):
    """Cells of the two double-integrator studies (smoke V̂ / V_s of each model, two seeds) -> the
    agent-models command -> one planar and one 3-D row, paired on the same scenarios."""
    from madpinn.commands import main
    from policy_models import tiny_model_dir

    overlay = tmp_path / "overlay.yaml"
    overlay.write_text(yaml.safe_dump(smoke_overlay(scenarios=2, seeds=(100, 101)), sort_keys=False))
    cfg = load_config([REPO / "config.yaml", SMOKE, overlay])
    cells = []
    for study, run, three_d in (("model_planar", "madpinn", False), ("model_3d", "madpinn-3d", True)):
        models = {k: tiny_model_dir(three_d) / f"{k}.pt" for k in ("vhat", "vs")}
        cs = CellSettings.from_config(cfg, study, run)
        for seed in (100, 101):
            cell = run_cell(cs, 3, seed, models=models, backend="double_integrator", progress=False)
            cells.append(write_cell(cell, tmp_path / "eval" / study / run / f"n3_seed{seed}.parquet")[0])
    out = tmp_path / "out"
    assert main(["agent-models", "--config", str(REPO / "config.yaml"), str(SMOKE), str(overlay), "--inputs",
                 *map(str, cells), "--out-dir", str(out), "--no-track"]) == 0
    table = pd.read_csv(out / "table_agent_models.csv")
    assert list(table["study"]) == ["model_planar", "model_3d"] and set(table["backend"]) == {"double_integrator"}
    flat, three = table.iloc[0], table.iloc[1]
    assert flat["model"] == "double_integrator" and three["model"].startswith("double_integrator_3d (altitude band")
    assert three["reference"] == "model_planar/madpinn" and pd.isna(flat["safety_rate_diff"])
    frames = {s: pd.concat([pd.read_parquet(p) for p in cells if f"/{s}/" in str(p)]) for s in ("model_planar", "model_3d")}
    paired = frames["model_3d"]["cost_safe_time_avg"].mean() - frames["model_planar"]["cost_safe_time_avg"].mean()
    assert three["cost_time_avg_diff"] == pytest.approx(paired, rel=1e-6, abs=1e-9)   # both sides: 2 scenarios per seed
    assert three["safety_rate_diff"] == pytest.approx(frames["model_3d"]["safety_rate"].mean()
                                                      - frames["model_planar"]["safety_rate"].mean(), abs=1e-9)
    assert three["altitude_p90"] > 0 and pd.isna(flat["altitude_p90"]) and pd.isna(flat["overflights"])
    assert three["seeds"] == "100 101" and int(three["scenarios"]) == 4
    md = (out / "table_agent_models.md").read_text()
    assert TITLE in md and "Δ Safety vs planar" in md and (out / "table_agent_models.html").is_file()
    assert agent_models_table(cells, cfg).shape[0] == 2


@pytest.mark.slow
def test_the_workflow_builds_the_table_on_both_backends(tmp_path):
    """`snakemake table_agent_models` at smoke size: the 3-D variants trained by their rules, the
    four studies' cells (MuJoCo: the drones fly the altitude setpoint), the table (≈ 3 min)."""
    pytest.importorskip("mujoco")
    from workflow_helpers import NO_TRACKING, copy_repo, run_in, write_overlay

    copy = copy_repo(tmp_path / "repo")
    write_overlay(copy / "am.yaml", smoke_overlay(scenarios=2, seeds=(100, 101)), NO_TRACKING)
    run_in(copy, "-j1", "table_agent_models", configfiles=("smoke.yaml", "am.yaml"))
    out = copy / "results" / "agent_models" / "paper_figures" / "agent_models"
    table = pd.read_csv(out / "table_agent_models.csv")
    assert list(zip(table["backend"], table["study"])) == [("double_integrator", "model_planar"), ("double_integrator", "model_3d"),
                                                          ("mujoco", "model_planar_mujoco"), ("mujoco", "model_3d_mujoco")]
    three = table[table["study"].str.startswith("model_3d")]
    assert (three["altitude_p90"] > 0).all() and three["cost_time_avg_diff"].notna().all()
    assert list(three["reference"]) == ["model_planar/madpinn", "model_planar_mujoco/madpinn"]
    assert TITLE in (out / "table_agent_models.md").read_text()


def test_overflights_count_pairs_within_r_in_the_plane_and_apart_in_space(tmp_path):
    traj = tmp_path / "t_traj.npz"
    positions = np.array([[[0.0, 0.0, 1.0], [1.0, 0.0, 1.0], [3.0, 0.0, 1.0]],
                          [[0.5, 0.0, 0.8], [0.55, 0.0, 1.2], [3.0, 0.0, 1.0]]])   # agents 0 and 1 pass over each other
    np.savez(traj, positions=positions, collision_radius=0.1)
    got = recorded_passes(traj)
    assert got["overflights"] == 1 and got["altitude_p90"] == pytest.approx(np.percentile([0, 0, 0, 0.2, 0.2, 0], 90))
    np.savez(traj, positions=positions[..., :2], collision_radius=0.1)
    assert np.isnan(recorded_passes(traj)["overflights"])


def test_the_3d_variants_ship_as_their_kind():
    from madpinn.value_functions.shipping import model_kind

    assert (model_kind("vhat_3d"), model_kind("vs_3d"), model_kind("safemarl_nominal")) == ("vhat", "vs", "safemarl_nominal")
