"""Gap decomposition and MuJoCo collision diagnostics (issue 14), on tiny real models and the
smoke config: the command writes its files, rows differ only by their switch, bad input fails early."""

import json

import pandas as pd
import pytest
import torch

from conftest import REPO, SMOKE
from madpinn.commands import main
from madpinn.commands.gap import lookahead_of
from madpinn.config import load_config
from madpinn.evaluation import gap
from policy_models import tiny_model_dir


def _models() -> list[str]:
    d = tiny_model_dir()
    return [f"vhat={d / 'vhat.pt'}", f"vs={d / 'vs.pt'}"]


def test_gap_decomposition_command_writes_every_row(tmp_path, one_thread):
    out = tmp_path / "gap"
    rc = main(["gap-decomposition", "--config", str(REPO / "config.yaml"), str(SMOKE), "--model", *_models(),
               "--agents", "16", "--seeds", "100", "--scenarios", "2", "--margin-sweep", "0.3",
               "--out-dir", str(out), "--no-progress"])
    assert rc == 0
    table = pd.read_csv(out / "decomposition.csv")
    ahead = lookahead_of(load_config([REPO / "config.yaml", SMOKE]))
    assert ahead > 0
    names = [v.name for v in gap.default_variants(0.2, (0.3,), ahead)]
    assert "mujoco + look_ahead" in names
    assert table["variant"].tolist() == names
    assert set(table["backend"]) == {"double_integrator", "mujoco"}
    for col in ("safety_rate", "safe_scenarios"):
        assert table[col].between(0, 1).all()
    # time-averaged cost = cumulative cost ÷ episode length (smoke small arena: 0.25 s)
    assert (table["cost_time_avg"] - table["cost"] / 0.25).abs().max() < 1e-9
    row = table.set_index("variant")
    assert row.loc["mujoco / old mapping", "carrot_margin"] == 0 and row.loc["mujoco / old mapping", "neighbour_goal"] == "ego"
    assert row.loc["mujoco + all fixes", "carrot_margin"] == pytest.approx(0.2)
    assert row.loc["mujoco + all fixes", "neighbour_goal"] == "neighbour"
    assert row.loc["double_integrator + carrot_margin=0.3", "carrot_margin"] == pytest.approx(0.3)
    assert row.loc["mujoco / old mapping", "look_ahead"] == 0
    assert row.loc["mujoco + look_ahead", "look_ahead"] == pytest.approx(ahead)
    assert row.loc["mujoco + look_ahead", "carrot_margin"] == 0
    assert row.loc["mujoco + all fixes", "look_ahead"] == pytest.approx(ahead)
    md = (out / "decomposition.md").read_text()
    assert "mujoco + all fixes" in md and "gap-decomposition --config" in md and "--seeds 100 --scenarios 2" in md
    diag = json.loads((out / "decomposition.json").read_text())["diagnostics"]
    assert len(diag) == len(names)


def test_gap_decomposition_refuses_protocol_seeds_and_unknown_counts(one_thread):
    cfg = load_config([REPO / "config.yaml", SMOKE])
    with pytest.raises(ValueError, match="validation seeds"):
        gap.decompose(cfg, gap.default_variants(0.2), [16], [0, 100], 1)
    with pytest.raises(ValueError, match="no study"):
        gap.study_for(cfg, 7)
    with pytest.raises(ValueError, match="margin"):
        gap.default_variants(0.0)
    with pytest.raises(ValueError, match="look_ahead"):
        gap.default_variants(0.2, (), -0.1)
    assert "mujoco + look_ahead" not in [v.name for v in gap.default_variants(0.2)]


def test_collision_diagnostics_run_on_mujoco(one_thread):
    cfg = load_config([REPO / "config.yaml", SMOKE])
    d = tiny_model_dir()
    # 16 agents in the 1 m smoke arena: crowded enough for collisions with a tiny V̂
    summary, events = gap.run_cell(cfg, "mujoco", "madpinn", "main", 16, 100, 2,
                                   models={"vhat": d / "vhat.pt", "vs": d / "vs.pt"})
    collided_agents = round((1 - summary["safety_rate"]) * 16 * 2)
    onset_agents = {(e["scenario"], a) for e in events for a in (e["i"], e["j"])}
    assert len(onset_agents) <= collided_agents                 # every onset is a recorded collision
    assert collided_agents == 0 or events                      # and collisions are seen as onsets
    for e in events:
        assert e["observed"] in ("both", "one", "none") and e["infeasible_lead_s"] >= 0 and 0 <= e["scenario"] < 2
    assert summary["cost_time_avg"] == pytest.approx(summary["cost"] / 0.25)


def test_workflow_target_runs_the_command_and_is_not_part_of_all(tmp_path):
    from conftest import run_snakemake

    target = run_snakemake(tmp_path, "-n", "-p", "gap_decomposition").stdout
    assert "rule gap_decomposition" in target and "madpinn gap-decomposition" in target
    assert "--model vhat=results/smoke/models/vhat.pt --model vs=results/smoke/models/vs.pt" in target
    assert "--seeds 100 " in target and "--margin-sweep 0.1" in target
    assert "gap_decomposition" not in run_snakemake(tmp_path, "-n", "all").stdout


@pytest.mark.parametrize("study, n", [("main", 3), ("conflict_circle", 4)])
def test_a_decomposition_cell_equals_the_evaluate_job_of_the_same_cell(tmp_path, one_thread, study, n):
    """Also on a structured-conflict study: the diagnostics use the study's scenario pattern."""
    from madpinn.commands.evaluate import evaluate

    cfg = load_config([REPO / "config.yaml", SMOKE])
    d = tiny_model_dir()
    models = {"vhat": d / "vhat.pt", "vs": d / "vs.pt"}
    count = cfg["studies"][study]["scenarios"]
    summary, _ = gap.run_cell(cfg, "double_integrator", "madpinn", study, n, 100, count, models=models)
    again, _ = gap.run_cell(cfg, "double_integrator", "madpinn", study, n, 100, count, models=models)
    job = evaluate(cfg, study, "madpinn", n, 100, tmp_path / "cell.parquet", models=models, backend="double_integrator",
                   progress=False, track=False)
    for key in ("safety_rate", "safe_scenarios", "cost"):
        assert summary[key] == again[key] == job[key]          # deterministic, and the same cell as evaluate's
