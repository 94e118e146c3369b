"""Validation tools on small trained models: z* bisection, V_s rollouts, heatmap observations,
and the CLI commands end to end (train -> validate -> figures) on the smoke configuration."""

import json

import pytest
import torch

from madpinn.commands import main
from madpinn.config import ConfigError, REPO_ROOT, load_config, validate_config
from madpinn.value_functions.epigraph import EpigraphSystem
from madpinn.dynamics.pair import PairSystem
from madpinn.value_functions import load_vhat, load_vs, min_feasible_z
from madpinn.value_functions.model import VHat, PairValue, build_network
from madpinn.value_functions.problems import EpigraphProblem, PairProblem
from madpinn.value_functions.validation import HEATMAP, heatmap_observations, vs_rollouts
from madpinn.value_functions.z_search import ZGrid, grid_value
from settings_helpers import epigraph_system, observation_settings, pair_system

NET = {"hidden": 16, "layers": 2, "first_omega": 30.0, "hidden_omega": 30.0}
CONFIGS = [str(REPO_ROOT / "config.yaml"), str(REPO_ROOT / "workflow/configs/smoke.yaml")]


def test_min_feasible_z_is_a_crossing_of_the_deployed_grid():
    torch.manual_seed(0)
    spec = observation_settings()
    problem = EpigraphProblem(epigraph_system(spec=spec, z_max=21.45))
    vhat = VHat(problem, build_network(problem, NET), 1.0)
    obs, _ = problem.system.sample(200, torch.Generator().manual_seed(1))
    z, ok = min_feasible_z(vhat, obs, 1e-3)
    grid = ZGrid.of(vhat.z_max, 1e-3)
    assert grid.cells == 1024 and ok.any()
    i = torch.round(z / (vhat.z_max / grid.cells)).long()
    assert torch.equal(grid.z(i, obs.dtype), z)                    # z* is a grid point
    assert (vhat.value(obs[ok], z[ok]) <= 0).all()
    # one cell below is unsafe (the first cell: z_0 = 0 is never evaluated)
    below = (i[ok] - 1).clamp_min(1)
    assert (grid_value(vhat, obs[ok], grid, below) > 0).logical_or(i[ok] == 1).all()
    assert (z[~ok] == vhat.z_max).all()
    assert (vhat.value(obs[~ok], torch.full_like(z[~ok], vhat.z_max)) > 0).all()


def test_rollouts_of_an_untrained_network_report_consistent_rates():
    torch.manual_seed(0)
    problem = PairProblem(pair_system())
    vs = PairValue(problem, build_network(problem, NET), 1.0)
    r = vs_rollouts(vs, 500, 0.05, seed=0)
    assert r["samples"] == 500
    assert 0.0 <= r["false_safe_rate"] <= r["predicted_safe_fraction"] <= 1.0
    assert r["false_safe_rate"] <= r["rollout_collision_fraction"]
    assert r["mean_abs_error"] >= abs(r["mean_error"])


def test_heatmap_observation_is_the_papers_configuration():
    spec = observation_settings()
    axis, obs = heatmap_observations(spec, 1.0, points=5)
    p = torch.stack(torch.meshgrid(axis, axis, indexing="ij")[::-1], -1).reshape(-1, 2)
    assert torch.allclose(obs[:, 0:2], torch.tensor(HEATMAP["ego_velocity"]).expand(25, 2))
    assert torch.allclose(obs[:, 2:4], torch.tensor(HEATMAP["ego_goal"]) - p)
    assert torch.allclose(obs[:, 4:6], torch.tensor(HEATMAP["neighbours"][0]) - p)
    assert torch.allclose(obs[:, 6:8], torch.tensor(HEATMAP["neighbour_velocity"]).expand(25, 2))


def test_schema_rejects_bad_value_function_keys():
    cfg = load_config(CONFIGS)
    cfg["value_functions"]["vhat"]["bogus"] = 1
    with pytest.raises(ConfigError, match="bogus"):
        validate_config(cfg)
    cfg = load_config(CONFIGS)
    cfg["value_functions"]["vs"]["lr"] = -1
    with pytest.raises(ConfigError, match="value_functions.vs.lr"):
        validate_config(cfg)
    cfg = load_config(CONFIGS)
    del cfg["value_functions"]
    with pytest.raises(ConfigError, match="value_functions"):
        validate_config(cfg)


def test_cli_train_validate_figures(tmp_path):
    out = tmp_path / "models"
    for kind in ("vs", "vhat"):
        assert main(["train-value", "--config", *CONFIGS, "--kind", kind, "--out", str(out / f"{kind}.pt"),
                     "--no-track", "--no-progress"]) == 0
    vhat, vs = load_vhat(out / "vhat.pt"), load_vs(out / "vs.pt")
    for m, iterations in ((vhat, 30 + 10), (vs, 30 + 10)):   # smoke: 30 iterations + a 10-iteration fine_tune stage
        assert m.meta["iterations"] == iterations and len(m.meta["config_hash"]) == 12
        assert m.meta["residual"]["residual_mean"] > 0 and not {"wall_s", "git_commit"} & set(m.meta)   # run record: beside it
    for kind in ("vs", "vhat"):
        record = json.loads((out / f"{kind}_train.json").read_text())
        assert record["git_commit"] and record["wall_s"] > 0
    assert (out / "vhat_loss.csv").read_text().count("\n") == 41
    assert load_vhat(out / "vhat_stage1.pt").meta["iterations"] == 30
    assert main(["validate-vs", "--config", *CONFIGS, "--model", str(out / "vs.pt"), "--out", str(tmp_path / "vs.json"),
                 "--fig-stem", str(tmp_path / "slices"), "--no-track"]) == 0
    report = json.loads((tmp_path / "vs.json").read_text())
    assert report["samples"] == 1000 and 0 <= report["false_safe_rate"] <= 1
    assert main(["validate-vhat", "--config", *CONFIGS, "--model", str(out / "vhat.pt"), "--out", str(tmp_path / "r.json"),
                 "--no-track"]) == 0
    assert json.loads((tmp_path / "r.json").read_text())["residual_samples"] == 2048
    assert main(["fig-value-heatmap", "--config", *CONFIGS, "--model", str(out / "vhat.pt"),
                 "--out-stem", str(tmp_path / "heat"), "--no-track"]) == 0
    for name in ("slices", "heat"):
        assert (tmp_path / f"{name}.pdf").stat().st_size > 1000 and (tmp_path / f"{name}.png").stat().st_size > 1000


def test_fine_tune_stage_equals_training_from_the_first_stage_model(tmp_path):
    """``fine_tune`` in one job gives the weights of two jobs: the first stage, then ``init_from``
    it with the stage's schedule (how results/models/vhat.pt was produced, docs/reference/value_functions.md)."""
    two = tmp_path / "two"
    assert main(["train-value", "--config", *CONFIGS, "--kind", "vhat", "--out", str(two / "vhat.pt"),
                 "--no-track", "--no-progress"]) == 0
    first = tmp_path / "first.yaml"
    first.write_text("value_functions:\n  vhat:\n    fine_tune: null\n")
    assert main(["train-value", "--config", *CONFIGS, str(first), "--kind", "vhat", "--out", str(tmp_path / "a" / "vhat.pt"),
                 "--no-track", "--no-progress"]) == 0
    second = tmp_path / "second.yaml"
    second.write_text(f"value_functions:\n  vhat:\n    fine_tune: null\n    init_from: {tmp_path / 'a' / 'vhat.pt'}\n"
                      "    iterations: 10\n    lr: 3.0e-5\n    lr_final: 1.0e-6\n    curriculum_fraction: 0.0\n")
    assert main(["train-value", "--config", *CONFIGS, str(second), "--kind", "vhat", "--out", str(tmp_path / "b" / "vhat.pt"),
                 "--no-track", "--no-progress"]) == 0
    a, b = load_vhat(two / "vhat.pt"), load_vhat(tmp_path / "b" / "vhat.pt")
    assert b.meta["batch_offset"] == 30
    for p, q in zip(a.net.parameters(), b.net.parameters()):
        assert torch.equal(p, q)


def test_time_limited_pieces_of_a_two_stage_training_give_the_one_job_model(tmp_path):
    """``train-value --time-limit 0``: each call trains one iteration (two where the first stage
    ends), keeps its checkpoint and exits 75 until the model is written (exit 0); the model is the
    uninterrupted job's, bit for bit (how V̂ is trained in ≤ 10-minute pieces on a lent GPU)."""
    from madpinn.commands.value_functions import EXIT_PAUSED

    small = tmp_path / "small.yaml"
    small.write_text("value_functions:\n  vhat:\n    iterations: 4\n    checkpoint_every: 3\n"
                     "    fine_tune: {iterations: 3, lr: 3.0e-5, lr_final: 1.0e-6}\n")
    args = ["train-value", "--config", *CONFIGS, str(small), "--kind", "vhat", "--no-track", "--no-progress"]
    assert main([*args, "--out", str(tmp_path / "one" / "vhat.pt")]) == 0
    out = tmp_path / "pieces" / "vhat.pt"
    codes = []
    while not codes or codes[-1] == EXIT_PAUSED:
        codes.append(main([*args, "--out", str(out), "--time-limit", "0"]))
        assert len(codes) <= 7
    assert codes == [EXIT_PAUSED] * 5 + [0]   # 4 + 3 iterations, the 4th call ends stage 1 and starts stage 2
    a, b = load_vhat(tmp_path / "one" / "vhat.pt"), load_vhat(out)
    assert b.meta["iterations"] == a.meta["iterations"] == 7
    for p, q in zip(a.net.parameters(), b.net.parameters()):
        assert torch.equal(p, q)
    assert (tmp_path / "pieces" / "vhat_loss.csv").read_text() == (tmp_path / "one" / "vhat_loss.csv").read_text()
