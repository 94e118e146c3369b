"""Issue 33 item 4, the large arena's safety–cost frontier: V̂ variants as workflow models (their
merged settings and training hash, the CLI's --variant, the rule planned only where a study uses
one), the per-run speed bound (a deployment-only governor), and fig_large_arena_frontier drawn from
real small cells (smoke models, double integrator)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import torch

from conftest import REPO, SMOKE
from madpinn.commands import main
from madpinn.config import ConfigError, deep_merge, load_config, run_agents, run_vhat, validate_config, with_vf_variant
from madpinn.commands import settings_hash
from madpinn.provenance import model_training_hash
from madpinn.value_functions.build import training_hash
from policy_models import tiny_model_dir
from workflow_helpers import NO_TRACKING, TINY, copy_repo, planned_jobs, run_in, write_overlay


def test_variant_merges_over_the_base_and_has_its_own_training_hash(smoke_cfg):
    merged = with_vf_variant(smoke_cfg, "vhat", "h04")["value_functions"]["vhat"]
    base = smoke_cfg["value_functions"]["vhat"]
    cs = with_vf_variant(smoke_cfg, "vhat", "cs")["value_functions"]["vhat"]   # h04: {from: cs, horizon: 0.4}
    assert cs == {**base, "conflict_sampling": {**base["conflict_sampling"], "fraction": 0.5}}
    assert merged == {**cs, "horizon": 0.4}
    speed = with_vf_variant(smoke_cfg, "vhat", "speed")["value_functions"]["vhat"]
    assert speed["fine_tune"] is None and speed["init_from"] == "models/vhat_cs.pt" and speed["iterations"] == 30
    hashes = {n: model_training_hash(smoke_cfg, n) for n in ("vhat", "vhat_h04", "vhat_h03", "vhat_speed")}
    assert hashes["vhat"] == training_hash(smoke_cfg, "vhat") and len(set(hashes.values())) == 4
    # the rule's param is the variant's training hash
    assert settings_hash(smoke_cfg, "train-value", kind="vhat", variant="h04") == settings_hash(
        with_vf_variant(smoke_cfg, "vhat", "h04"), "train-value", kind="vhat") != settings_hash(smoke_cfg, "train-value", kind="vhat")
    # editing or adding a variant leaves the base V̂'s hash (and every other model's) alone ...
    edited = deep_merge(smoke_cfg, {"value_functions": {"vhat_variants": {"h04": {"horizon": 0.5}, "x": {"lr": 1.0e-3}}}})
    assert training_hash(edited, "vhat") == hashes["vhat"] and model_training_hash(edited, "vhat_speed") == hashes["vhat_speed"]
    assert model_training_hash(edited, "vhat_h04") != hashes["vhat_h04"]
    # ... while a base setting the variant does not override retrains it (it is merged over the base)
    assert model_training_hash(deep_merge(smoke_cfg, {"value_functions": {"vhat": {"lr": 2.0e-4}}}), "vhat_h04") != hashes["vhat_h04"]
    with pytest.raises(ConfigError, match="unknown vhat variant 'nope'"):
        with_vf_variant(smoke_cfg, "vhat", "nope")
    # a `from` chain: editing cs retrains what derives from it, not the base; a bad chain is one line
    chained = deep_merge(smoke_cfg, {"value_functions": {"vhat_variants": {"cs": {"conflict_sampling": {"fraction": 0.25}}}}})
    assert model_training_hash(chained, "vhat_h04") != hashes["vhat_h04"] and training_hash(chained, "vhat") == hashes["vhat"]
    for bad, message in (({"h04": {"from": "nope"}}, r"unknown vhat variant 'nope' \(value_functions.vhat_variants.h04.from"),
                         ({"cs": {"from": "h04"}}, r"'from' chain returns to 'h04' \(h04 -> cs -> h04\)")):
        with pytest.raises(ConfigError, match=message):
            validate_config(deep_merge(smoke_cfg, {"value_functions": {"vhat_variants": bad}}))


def test_runs_select_their_vhat_and_speed_bound(paper_cfg):
    assert run_vhat(paper_cfg, "madpinn") == "vhat" and run_vhat(paper_cfg, "madpinn-h04") == "vhat_h04"
    # issue 61: the deployed V̂ is trained on uniform states (the paper's), the earlier recipe is the labelled row cs
    assert paper_cfg["value_functions"]["vhat"]["conflict_sampling"]["fraction"] == 0.0 and run_vhat(paper_cfg, "madpinn-cs") == "vhat_cs"
    assert model_training_hash(paper_cfg, "vhat") == model_training_hash(paper_cfg, "vhat_nocs") != model_training_hash(paper_cfg, "vhat_cs")
    assert {"madpinn-cs"} <= set(paper_cfg["studies"]["main"]["runs"]) & set(paper_cfg["studies"]["scaling"]["runs"])
    assert run_agents(paper_cfg, "madpinn-vmax1")["v_max"] == 1.0 and run_agents(paper_cfg, "madpinn")["v_max"] == 4.0
    # a governor is a deployment setting: its cells rerun, no training does
    assert settings_hash(paper_cfg, "evaluate", study="large_arena_frontier", run="madpinn-vmax1") != settings_hash(
        paper_cfg, "evaluate", study="large_arena_frontier", run="madpinn")
    bad = deep_merge(paper_cfg, {"methods": {"madpinn": {"variants": {"fast": {"agents": {"v_max": 8.0}}, "x": {"vhat": "h9"}}}}})
    from madpinn.config import validate_config

    with pytest.raises(ConfigError) as exc:
        validate_config(bad)
    assert "variants.fast.agents.v_max" in str(exc.value) and "unknown V̂ variant 'h9'" in str(exc.value)
    with pytest.raises(ConfigError, match=r"vhat_variants.h04.horizon' \(merged over value_functions.vhat\)"):
        validate_config(deep_merge(paper_cfg, {"value_functions": {"vhat_variants": {"h04": {"horizon": -1.0}}}}))


def test_a_calibrated_level_is_a_marker_of_its_own_on_no_governor_sweep(paper_cfg):
    """Issue 62 item 3: the level rows stand on the frontier beside the governors; they share V̂, carrot
    and speed bound with the base run, so without their level they would join its carrot sweep."""
    from madpinn.figures.frontier import FrontierRun, sweeps

    runs = {r: FrontierRun.of_run(paper_cfg, r) for r in ("madpinn", "madpinn-carrot10", "madpinn-carrot05",
                                                          "madpinn-cpeps05", "madpinn-cpeps01")}
    assert {"madpinn-cpeps05", "madpinn-cpeps01"} <= set(paper_cfg["studies"]["large_arena_frontier"]["runs"])
    assert (runs["madpinn"].level, runs["madpinn-cpeps05"].level, runs["madpinn-cpeps01"].level) == ("", "ε 0.05", "ε 0.01")
    assert runs["madpinn-cpeps05"].carrot == runs["madpinn"].carrot and runs["madpinn-cpeps05"].vhat == runs["madpinn"].vhat
    assert sweeps(list(runs.values())) == [("carrot", ["madpinn", "madpinn-carrot10", "madpinn-carrot05"])]
    # the same runs without their level: a carrot sweep through points at one carrot length
    flat = [FrontierRun(r.run, r.label, r.vhat, r.carrot, r.v_max, r.neighbour_goal) for r in runs.values()]
    assert set(sweeps(flat)[0][1]) == set(runs)


def test_train_value_variant_trains_the_merged_settings(tmp_path, one_thread):
    out = tmp_path / "models" / "vhat_h04.pt"
    assert main(["train-value", "--config", str(REPO / "config.yaml"), str(SMOKE), "--kind", "vhat", "--variant", "h04",
                 "--out", str(out), "--no-track", "--no-progress", "--threads", "1"]) == 0
    meta = torch.load(out, map_location="cpu", weights_only=True)["meta"]
    cfg = load_config([REPO / "config.yaml", SMOKE])
    assert meta["settings"]["horizon"] == 0.4 and meta["config_hash"] == model_training_hash(cfg, "vhat_h04")
    assert (tmp_path / "models" / "checkpoints" / "vhat_h04.ckpt.pt").is_file()   # not the base V̂'s checkpoint
    assert main(["train-value", "--config", str(REPO / "config.yaml"), str(SMOKE), "--kind", "vhat", "--variant", "nope",
                 "--out", str(tmp_path / "x.pt"), "--no-track"]) != 0
    assert not (tmp_path / "x.pt").exists()


# --- real small cells: the smoke V̂ and V_s, double integrator, the large arena -------------------

RUNS = ["madpinn", "madpinn-carrot05", "madpinn-vmax2", "madpinn-vmax1"]
CELL_OVERLAY = {"sim": {"backend": "double_integrator", "record_every": 1},
                "arenas": {"large": {"half_width": 4.0, "episode_s": 0.6}},
                "studies": {"large_arena_frontier": {"agent_counts": [4, 64], "scenarios": 2, "runs": [*RUNS, "madpinn-h04"]}}}


@pytest.fixture(scope="module")
def cells(tmp_path_factory):
    """Evaluation cells of four runs at 4 agents (one scenario batch of 2, 0.6 s) and, for the
    paper's overlay, the plain run and one governor at 64 agents, through the evaluate command."""
    d = tmp_path_factory.mktemp("frontier")
    overlay = write_overlay(d / "cells.yaml", CELL_OVERLAY)
    models = tiny_model_dir()
    torch.set_num_threads(1)
    paths = []
    for run, n in [(r, 4) for r in RUNS] + [("madpinn", 64), ("madpinn-vmax1", 64)]:
        out = d / run / f"n{n}_seed100.parquet"
        assert main(["evaluate", "--config", str(REPO / "config.yaml"), str(SMOKE), str(overlay), "--study",
                     "large_arena_frontier", "--run", run, "--n-agents", str(n), "--seed", "100", "--out", str(out),
                     "--model", f"vhat={models / 'vhat.pt'}", "--model", f"vs={models / 'vs.pt'}", "--no-track",
                     "--no-progress", "--threads", "1"]) == 0
        paths.append(out)
    cfg = load_config([REPO / "config.yaml", SMOKE, overlay])
    return cfg, paths


def _speeds(traj: Path) -> np.ndarray:
    """Per-axis speeds |Δp|/dt between recorded steps (record_every 1: every step) ``[T-1, N, 2]``."""
    d = np.load(traj)
    return np.abs(np.diff(d["positions"], axis=0)) / float(d["dt"])


def test_speed_bound_keeps_every_agent_at_or_below_it(cells):
    _, paths = cells
    free = _speeds(paths[0].with_name("n4_seed100_traj.npz")).max()
    assert free > 1.5, "the uncapped run must be faster than the caps for this check to mean anything"
    for run, cap in (("madpinn-vmax2", 2.0), ("madpinn-vmax1", 1.0)):
        v = _speeds(paths[0].parent.parent / run / "n4_seed100_traj.npz")
        assert v.max() <= cap * (1 + 1e-4), (run, v.max())


def test_frontier_figure_draws_every_run_sweep_and_the_papers_point(cells, tmp_path):
    import matplotlib.pyplot as plt

    from madpinn.figures.frontier import FrontierRun, draw_large_arena_frontier, frontier_data, paper_points, sweeps
    from madpinn.figures.frontier import plot_large_arena_frontier

    cfg, paths = cells
    runs = [FrontierRun.of_run(cfg, r) for r in cfg["studies"]["large_arena_frontier"]["runs"]]
    by = {r.run: r for r in runs}
    assert by["madpinn-carrot05"].carrot == pytest.approx(0.5) and by["madpinn"].carrot == pytest.approx(1.8)
    assert by["madpinn-vmax1"].v_max == 1.0 and by["madpinn-h04"].vhat == "vhat_h04"
    present = [by[r] for r in RUNS]
    assert sweeps(present) == [("carrot", ["madpinn", "madpinn-carrot05"]), ("v_max", ["madpinn", "madpinn-vmax2", "madpinn-vmax1"])]
    agg = frontier_data(paths)
    assert set(agg["n_agents"]) == {4, 64} and np.isfinite(agg["safety_rate_ci_lo"]).all()   # one seed: intervals
    paper = paper_points(agg["n_agents"].unique())
    assert set(paper) == {64} and paper[64]["cost"] == 1.09
    fig = draw_large_arena_frontier(agg, present, paper)
    axes = fig.axes
    assert [ax.get_title() for ax in axes] == ["4 agents", "64 agents"]
    labels = [[l.get_label() for l in ax.get_lines()] for ax in axes]
    assert {by[r].label for r in RUNS} <= set(labels[0]) and "Paper (Table II)" not in labels[0]
    assert {"Paper (Table II)", "v_max sweep", by["madpinn"].label, by["madpinn-vmax1"].label} <= set(labels[1])
    assert "carrot sweep" not in labels[1]   # one point of that sweep at 64 agents: no line
    assert labels[0].count("v_max sweep") == 1 and labels[0].count("carrot sweep") == 1
    star = next(l for l in axes[1].get_lines() if l.get_label() == "Paper (Table II)")
    assert tuple(star.get_xydata()[0]) == pytest.approx((1.09, 100.0))
    assert axes[0].get_ylabel() == "safety rate (%)" and axes[0].get_xlabel().startswith("cost ÷ T")
    plt.close(fig)
    files = plot_large_arena_frontier(paths, present, tmp_path / "fig_large_arena_frontier")
    assert [f.suffix for f in files] == [".pdf", ".png"] and all(f.stat().st_size > 0 for f in files)
    with pytest.raises(ValueError, match="no deployment given"):
        draw_large_arena_frontier(agg, present[:1], paper)


def test_frontier_markers_lie_inside_the_frame_and_apart():
    """The protocol's crowd (three governors within 1 % safety and 0.1 cost of each other, runs at
    100 %): every marker whole inside its panel, none covering another or the paper's star."""
    import matplotlib.pyplot as plt

    from madpinn.figures.frontier import MARKER_PT, FrontierRun, draw_large_arena_frontier
    from madpinn.figures.placement import overlapping_pairs

    cells = {"madpinn": (0.68, 1.66), "madpinn-carrot05": (0.985, 2.52), "madpinn-vmax1": (0.975, 2.48),
             "madpinn-vmax08": (0.98, 2.50), "madpinn-both": (1.0, 2.93)}
    runs = [FrontierRun(r, r, "vhat", 1.8 if r != "madpinn-carrot05" else 0.5, 2.0) for r in cells]
    agg = pd.DataFrame([dict(run=r, n_agents=128, safety_rate_mean=s, safety_rate_std=np.nan, safety_rate_ci_lo=s - 0.01,
                             safety_rate_ci_hi=min(1.0, s + 0.01), cost_time_avg_mean=c, cost_time_avg_std=np.nan,
                             cost_time_avg_ci_lo=c - 0.05, cost_time_avg_ci_hi=c + 0.05) for r, (s, c) in cells.items()])
    fig = draw_large_arena_frontier(agg, runs, {128: {"cost": 1.68, "safety": 0.9875}})
    fig.canvas.draw()
    ax = fig.axes[0]
    marks = [(l.get_label(), *l.get_xydata()[0]) for l in ax.get_lines() if l.get_label() in cells]
    assert sorted(m[0] for m in marks) == sorted(cells)
    box = ax.get_window_extent()
    r = MARKER_PT / 2 * fig.dpi / 72
    for label, x, y in marks:
        px, py = ax.transData.transform((x, y))
        assert box.x0 <= px - r and px + r <= box.x1 and box.y0 <= py - r and py + r <= box.y1, label
    star = next(l for l in ax.get_lines() if l.get_label() == "Paper (Table II)").get_xydata()[0]
    xy = np.array([m[1:] for m in marks] + [star])
    assert not overlapping_pairs(ax, MARKER_PT, [m[0] for m in marks] + ["paper"], xy)
    plt.close(fig)


def test_workflow_plans_a_variant_training_only_where_a_study_uses_it(tmp_path):
    copy = copy_repo(tmp_path / "clone")
    study = {"studies": {"large_arena_frontier": {"agent_counts": [8], "scenarios": 1, "runs": ["madpinn-h04", "madpinn-vmax1"]}}}
    write_overlay(copy / "tiny.yaml", TINY, NO_TRACKING, study)
    proc = run_in(copy, "-n", "-p", "fig_large_arena_frontier", configfiles=("smoke.yaml", "tiny.yaml"))
    jobs = planned_jobs(proc)
    assert jobs["train_vhat_variant"] == 1 and jobs["evaluate"] == 2 and jobs["fig_large_arena_frontier"] == 1
    out = proc.stdout + proc.stderr
    assert "--variant h04" in out and "--variant speed" not in out and "--variant h03" not in out
    assert "vhat=results/smoke/models/vhat_h04.pt" in out      # the h04 cell loads the variant ...
    assert "--run madpinn-vmax1" in out and "vhat=results/smoke/models/vhat.pt" in out   # ... the governor the base V̂
    # `all` of the tiny configuration (large_arena_frontier in_all: false there) plans no variant training
    assert "train_vhat_variant" not in planned_jobs(run_in(copy, "-n", "all", configfiles=("smoke.yaml", "tiny.yaml")))


def test_speed_bound_of_a_run_is_the_global_bound_of_the_earlier_overlay(cells, tmp_path):
    """madpinn-vmax1's cell equals the plain run's cell under an `agents: {v_max: 1}` overlay (the
    diagnostic of docs/reference/madpinn_policy.md), scenario for scenario: the per-run governor is that mechanism."""
    import pandas as pd

    cfg, paths = cells
    overlay = write_overlay(tmp_path / "vmax1.yaml", CELL_OVERLAY, {"agents": {"v_max": 1.0}},   # no variant above the bound
                            {"methods": {"madpinn": {"variants": {"vmax2": {"agents": {"v_max": 1.0}}}}}})
    models = tiny_model_dir()
    out = tmp_path / "madpinn" / "n4_seed100.parquet"
    assert main(["evaluate", "--config", str(REPO / "config.yaml"), str(SMOKE), str(overlay), "--study",
                 "large_arena_frontier", "--run", "madpinn", "--n-agents", "4", "--seed", "100", "--out", str(out),
                 "--model", f"vhat={models / 'vhat.pt'}", "--model", f"vs={models / 'vs.pt'}", "--no-track",
                 "--no-progress", "--threads", "1"]) == 0
    governed = pd.read_parquet(paths[0].parent.parent / "madpinn-vmax1" / "n4_seed100.parquet")
    overlaid = pd.read_parquet(out)
    cols = ["safety_rate", "cost_safe_mean", "min_separation", "final_distance_mean"]
    pd.testing.assert_frame_equal(governed[cols], overlaid[cols])
    free = pd.read_parquet(paths[0])
    assert not np.allclose(free["final_distance_mean"], governed["final_distance_mean"])   # the bound changed the motion
