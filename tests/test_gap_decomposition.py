"""Gap decomposition (issue 14) as studies of ordinary evaluation cells: runs switch the observation
mapping and the look-ahead, studies the backend; the table reads the cells; the collision probe
rides in the cell; bad declarations fail early; the workflow target plans evaluate jobs, not part
of all. Tiny real models, the smoke config."""

import json

import pandas as pd
import pytest

from conftest import REPO, SMOKE
from madpinn.commands import main
from madpinn.commands.evaluate import evaluate
from madpinn.config import ConfigError, deep_merge, job_config, load_config, run_observation, study_backend, validate_config
from madpinn.evaluation import gap
from madpinn.evaluation.cell import CellSettings
from policy_models import tiny_model_dir

OLD = {"carrot_margin": 0.0, "neighbour_goal": "ego"}


def _cfg() -> dict:
    return load_config([REPO / "config.yaml", SMOKE])


def _models() -> dict:
    d = tiny_model_dir()
    return {"vhat": d / "vhat.pt", "vs": d / "vs.pt"}


def test_runs_switch_the_mapping_and_studies_the_backend():
    cfg = _cfg()
    base = cfg["observation"]
    assert base["carrot_margin"] > 0 and base["neighbour_goal"] == "neighbour"
    old = CellSettings.from_config(cfg, "gap_mujoco", "madpinn-gapold").observation
    assert (old.carrot_margin, old.neighbour_goal) == (0.0, "ego")
    plain = CellSettings.from_config(cfg, "main", "madpinn").observation
    assert (plain.carrot_margin, plain.neighbour_goal) == (base["carrot_margin"], "neighbour")
    # a run without overrides deploys (and hashes) the plain observation section
    assert job_config(cfg, "main", "madpinn")["observation"] == base
    assert run_observation(cfg, "madpinn-gapmargin") == {**base, "neighbour_goal": "ego"}
    assert gap.switches(cfg, "madpinn-gaplookahead") == {**OLD, "look_ahead": gap.switches(cfg, "madpinn-lookahead")["look_ahead"]}
    assert gap.switches(cfg, "madpinn-lookahead")["look_ahead"] > 0
    assert study_backend(cfg, "gap_double_integrator") == "double_integrator"
    assert study_backend(cfg, "gap_mujoco") == "mujoco" and study_backend(cfg, "main") == cfg["sim"]["backend"]
    m = base["carrot_margin"]
    names = {run: gap.row_name("mujoco", gap.switches(cfg, run), m)
             for run in ("madpinn-gapold", "madpinn-gapmargin", "madpinn-gapneighbour", "madpinn-gaplookahead",
                         "madpinn-lookahead", "madpinn-gapmargin01")}
    assert names == {"madpinn-gapold": "mujoco / old mapping", "madpinn-gapmargin": "mujoco + carrot_margin",
                     "madpinn-gapneighbour": "mujoco + neighbour_goal", "madpinn-gaplookahead": "mujoco + look_ahead",
                     "madpinn-lookahead": "mujoco + all fixes", "madpinn-gapmargin01": "mujoco + carrot_margin=0.1"}


def test_a_gap_cell_is_the_evaluate_cell_of_its_overlay(tmp_path, one_thread):
    """The old mapping as a run variant on the double-integrator study = the plain run in the main
    study with the old mapping and the backend overlaid (same scenarios, policy, numbers); the
    collision probe only watches; the summary carries every onset."""
    cfg = _cfg()
    models = _models()
    cell = evaluate(cfg, "gap_double_integrator", "madpinn-gapold", 16, 100, tmp_path / "a.parquet", models=models,
                    progress=False, track=False)
    same = evaluate(deep_merge(cfg, {"observation": OLD}), "main", "madpinn", 16, 100, tmp_path / "b.parquet", models=models,
                    backend="double_integrator", progress=False, track=False)
    assert cell["backend"] == "double_integrator"
    for key in ("safety_rate", "safe_scenarios", "cost", "cost_time_avg"):
        assert cell[key] == same[key]
    assert "collision_events" in cell and "collision_events" not in same
    assert json.loads((tmp_path / "a.json").read_text())["collision_events"] == cell["collision_events"]


def test_collision_events_on_mujoco_cells(tmp_path, one_thread):
    cfg = _cfg()
    # 16 agents in the 1 m smoke arena: crowded enough for collisions with a tiny V̂
    s = evaluate(cfg, "main", "madpinn", 16, 100, tmp_path / "c.parquet", models=_models(), backend="mujoco",
                 progress=False, track=False, collision_events=True)
    events = s["collision_events"]
    collided_agents = round((1 - s["safety_rate"]) * 16 * 2)
    onset_agents = {(e["scenario"], a) for e in events for a in (e["i"], e["j"])}
    assert len(onset_agents) <= collided_agents                 # every onset is a recorded collision
    assert collided_agents == 0 or events                      # and collisions are seen as onsets
    for e in events:
        assert e["observed"] in ("both", "one", "none") and e["infeasible_lead_s"] >= 0 and 0 <= e["scenario"] < 2
        assert e["seed"] == 100
    with pytest.raises(ConfigError, match="not a MAD-PINN run"):
        evaluate(cfg, "main", "nominal", 3, 100, tmp_path / "d.parquet", progress=False, track=False, collision_events=True)


def test_the_table_reads_the_cells(tmp_path, one_thread):
    cfg = _cfg()
    models = _models()
    cells = [("gap_double_integrator", "madpinn-gapold"), ("gap_double_integrator", "madpinn-lookahead"),
             ("gap_mujoco", "madpinn-gapold"), ("gap_mujoco", "madpinn-gapmargin")]
    paths = []
    for study, run in cells:
        out = tmp_path / "eval" / study / f"{run}.parquet"
        evaluate(cfg, study, run, 16, 100, out, models=models, progress=False, track=False)
        paths.append(str(out.with_suffix(".json")))
    config = tmp_path / "resolved.yaml"
    import yaml

    config.write_text(yaml.safe_dump(cfg))
    assert main(["gap-decomposition", "--config", str(config), "--inputs", *paths, "--out-dir", str(tmp_path / "gap"),
                 "--no-track"]) == 0
    table = pd.read_csv(tmp_path / "gap" / "decomposition.csv")
    assert table["variant"].tolist() == ["double_integrator / old mapping", "double_integrator + all fixes",
                                         "mujoco / old mapping", "mujoco + carrot_margin"]
    assert table["run"].tolist() == [r for _, r in cells] and set(table["n_agents"]) == {16}
    row = table.set_index("variant")
    assert row.loc["mujoco / old mapping", "carrot_margin"] == 0 and row.loc["mujoco / old mapping", "neighbour_goal"] == "ego"
    assert row.loc["mujoco + carrot_margin", "carrot_margin"] == pytest.approx(cfg["observation"]["carrot_margin"])
    assert row.loc["double_integrator + all fixes", "look_ahead"] > 0
    for col in ("safety_rate", "safe_scenarios"):
        assert table[col].between(0, 1).all()
    summaries = gap.load_summaries(paths)
    for (_, r), s in zip(table.iterrows(), summaries):
        assert r["safety_rate"] == s["safety_rate"] and r["collision_onsets"] == len(s["collision_events"])
    md = (tmp_path / "gap" / "decomposition.md").read_text()
    assert "| mujoco / old mapping | madpinn-gapold |" in md and "+0.00" in md and "Δ vs madpinn-gapold on mujoco" in md
    diag = json.loads((tmp_path / "gap" / "decomposition.json").read_text())["diagnostics"]
    assert len(diag) == len(cells)


def test_bad_declarations_fail_early():
    base = deep_merge(load_config([REPO / "config.yaml"]), {})
    with pytest.raises(ConfigError, match="validation seeds"):
        validate_config(deep_merge(base, {"studies": {"gap_mujoco": {"seeds": [0, 100]}}}))
    with pytest.raises(ConfigError, match="MAD-PINN runs only"):
        validate_config(deep_merge(base, {"studies": {"gap_mujoco": {"runs": ["madpinn-gapold", "nominal"]}}}))
    with pytest.raises(ConfigError, match="unknown study"):
        validate_config(deep_merge(base, {"gap_decomposition": {"studies": ["gap_mujoco", "gap_elsewhere"]}}))
    with pytest.raises(ConfigError, match="reference"):
        validate_config(deep_merge(base, {"gap_decomposition": {"reference": {"backend": "double_integrator",
                                                                              "run": "madpinn-gapneighbour"}}}))
    with pytest.raises(ConfigError, match="methods.madpinn"):   # the schema: only deployment keys of observation
        validate_config(deep_merge(base, {"methods": {"madpinn": {"variants": {"gapold": {"observation": {"goal_range": 3.0}}}}}}))
    with pytest.raises(ConfigError, match="collision_events"):
        CellSettings.from_config(deep_merge(base, {"studies": {"main": {"collision_events": True}}}), "main", "nominal")


def test_workflow_target_plans_evaluate_cells_and_is_not_part_of_all(tmp_path):
    from conftest import run_snakemake

    target = run_snakemake(tmp_path, "-n", "-p", "gap_decomposition").stdout
    assert "rule gap_decomposition" in target and "madpinn gap-decomposition" in target
    assert ("--study gap_double_integrator --run madpinn-gapold --n-agents 16 --seed 100 --backend double_integrator"
            in target)
    assert "eval/mujoco/gap_mujoco/madpinn-gapmargin/n16_seed100.json" in target
    plan = run_snakemake(tmp_path, "-n", "all").stdout
    assert "gap_decomposition" not in plan and "gap_mujoco" not in plan
