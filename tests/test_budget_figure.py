"""fig_vhat_budget (issue 46): training samples read from the models, the log-linear trend and the
budget at which it would reach the paper, a panel per budget study with the paper's values of its
setting, each V̂'s verification ε, and the figure drawn through the workflow's function."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest

from conftest import REPO
from madpinn.evaluation.paper_rows import paper_safety
from madpinn.figures.budget import (ANNEALED, CONSTANT, BudgetRun, budget_panel, budget_table, draw_vhat_budget,
                                    model_samples, model_schedule, trend, verification_epsilon)
from madpinn.value_functions.model import read_checkpoint


def test_samples_of_the_shipped_models():
    assert model_samples(read_checkpoint(REPO / "models/vhat.pt", "vhat")["meta"]) == 4096 * 60000
    # a fine-tune continues its initial model's batch stream: those samples count too
    assert model_samples(read_checkpoint(REPO / "models/vhat_speed.pt", "vhat")["meta"]) == 4096 * (20000 + 60000)
    with pytest.raises(ValueError, match="not a train-value model"):
        model_samples({"iterations": 3})


def test_schedule_of_the_shipped_budgets():
    """The shipped recipe anneals its rate; the 2x / 3x budgets keep the paper's constant 2e-5."""
    def schedule(name):
        return model_schedule(read_checkpoint(REPO / f"models/{name}.pt", "vhat")["meta"])

    assert [schedule(m) for m in ("vhat", "vhat_b05", "vhat_b15")] == [ANNEALED] * 3
    assert [schedule(m) for m in ("vhat_b2x", "vhat_b3x")] == [CONSTANT] * 2
    with pytest.raises(ValueError, match="not a train-value model"):
        model_schedule({"settings": {"lr": 1e-3}})


def test_trend_reaches_the_target_only_when_it_rises():
    a, b, needed = trend([1e8, 1e9], [80.0, 90.0], 100.0)
    assert b == pytest.approx(10.0) and needed == pytest.approx(1e10)
    assert trend([1e8, 1e9], [80.0, 70.0], 100.0)[2] is None
    assert trend([1e8, 1e8], [80.0, 82.0], 100.0)[2] is None


def _agg(safety: dict) -> pd.DataFrame:
    rows = [{"run": run, "n_agents": n, "safety_rate_mean": s, "safety_rate_std": np.nan, "safety_rate_ci_lo": s - 0.02,
             "safety_rate_ci_hi": min(1.0, s + 0.02)} for (run, n), s in safety.items()]
    return pd.DataFrame(rows)


def test_panels_carry_the_papers_values_of_their_setting_only():
    large = budget_panel("vhat_budget", "large", "uniform", [64, 128, 256])
    assert large.paper == {64: 100.0, 128: 98.75, 256: 96.25} and large.title == "Table II setting"
    small = budget_panel("vhat_budget_small", "small", "uniform", [12, 16])
    assert small.paper == {12: pytest.approx(99.3), 16: pytest.approx(98.3)} and small.title == "Table I setting"
    # the paper tests no structured conflict: no line to compare with
    circle = budget_panel("vhat_budget_circle", "small", "circle_swap", [16])
    assert circle.paper == {} and "circle_swap" in circle.title
    assert paper_safety("small", None, [3, 64]) == {3: 100.0}   # Table I has no 64


def test_verification_epsilon_takes_the_most_conservative_bound():
    report = {"uniform": {"any": {"epsilon": {"0.001": 0.05, "1e-06": 0.06}}}}
    assert verification_epsilon(report, "uniform") == 0.06


def test_budget_table_and_figure_from_cells():
    runs = [BudgetRun("madpinn-b05", "0.5x", 4096 * 30000, ANNEALED), BudgetRun("madpinn", "1x", 4096 * 60000, ANNEALED),
            BudgetRun("madpinn-b3x", "3x", 4096 * 180000, ANNEALED,
                      verification={d: {"any": {"epsilon": {"1e-06": e}}} for d, e in (("uniform", 0.05), ("conflict", 0.08))})]
    frames = {"vhat_budget": _agg({("madpinn-b05", 64): 0.77, ("madpinn", 64): 0.80, ("madpinn-b3x", 64): 0.86,
                                   ("madpinn-b05", 128): 0.60, ("madpinn", 128): 0.68, ("madpinn-b3x", 128): 0.66}),
              "vhat_budget_circle": _agg({("madpinn-b05", 16): 0.5, ("madpinn", 16): 0.6, ("madpinn-b3x", 16): 0.7})}
    panels = [budget_panel("vhat_budget", "large", "uniform", [64, 128]),
              budget_panel("vhat_budget_circle", "small", "circle_swap", [16])]
    table = budget_table(frames, runs, panels)
    at64 = table[(table["study"] == "vhat_budget") & (table["n_agents"] == 64)]
    assert list(at64["samples"]) == sorted(r.samples for r in runs) and (at64["paper_safety"] == 100.0).all()
    assert at64["slope_per_decade"].iloc[0] > 0 and at64["samples_to_paper"].iloc[0] > 4096 * 180000
    at128 = table[(table["study"] == "vhat_budget") & (table["n_agents"] == 128)]
    assert at128["slope_per_decade"].iloc[0] > 0 and math.isfinite(at128["samples_to_paper"].iloc[0])
    # the structured panel has no paper value, hence no budget to reach it
    circle = table[table["study"] == "vhat_budget_circle"]
    assert len(circle) == 3 and circle["paper_safety"].isna().all() and circle["samples_to_paper"].isna().all()
    # ε only where the V̂'s verification was given
    assert table.loc[table["run"] == "madpinn-b3x", "eps_conflict"].eq(0.08).all() and table.loc[table["run"] == "madpinn", "eps_uniform"].isna().all()
    # a falling trend has no budget that reaches the paper
    falling = budget_table({"vhat_budget": _agg({("madpinn-b05", 64): 0.9, ("madpinn", 64): 0.8, ("madpinn-b3x", 64): 0.7})},
                           runs, panels[:1])
    assert falling["samples_to_paper"].isna().all()
    fig = draw_vhat_budget(frames, runs, panels)
    assert len(fig.axes) == 2
    ax = fig.axes[0]
    assert ax.get_xscale() == "log" and len(ax.lines) >= 2 * 2   # a data line and a paper line per N
    assert "no paper value" in fig.axes[1].get_title()


def test_trends_are_fitted_within_one_schedule():
    """Two annealed budgets that fall and two constant-rate budgets that rise: one trend per schedule,
    never one across them (which here would rise through the mixed points)."""
    runs = [BudgetRun("madpinn-b05", "0.5x", 4096 * 30000, ANNEALED), BudgetRun("madpinn", "1x", 4096 * 60000, ANNEALED),
            BudgetRun("madpinn-b2x", "2x", 4096 * 120000, CONSTANT), BudgetRun("madpinn-b3x", "3x", 4096 * 180000, CONSTANT)]
    frames = {"vhat_budget": _agg({("madpinn-b05", 64): 0.70, ("madpinn", 64): 0.65,
                                   ("madpinn-b2x", 64): 0.72, ("madpinn-b3x", 64): 0.80})}
    panels = [budget_panel("vhat_budget", "large", "uniform", [64])]
    table = budget_table(frames, runs, panels)
    assert list(table["run"]) == ["madpinn-b05", "madpinn", "madpinn-b2x", "madpinn-b3x"]   # by samples
    annealed, constant = table[table["schedule"] == ANNEALED], table[table["schedule"] == CONSTANT]
    assert (annealed["slope_per_decade"] < 0).all() and annealed["samples_to_paper"].isna().all()
    assert (constant["slope_per_decade"] > 0).all() and (constant["samples_to_paper"] > 4096 * 180000).all()
    # a schedule with one budget has no trend
    single = budget_table({"vhat_budget": frames["vhat_budget"][frames["vhat_budget"]["run"] != "madpinn-b3x"]}, runs[:3], panels)
    assert single.loc[single["schedule"] == CONSTANT, "slope_per_decade"].isna().all()
    fig = draw_vhat_budget(frames, runs, panels)
    labels = fig.axes[0].get_legend_handles_labels()[1]
    assert labels.count("64 agents") == 1   # one entry per N, the schedules by style
    assert {ANNEALED, CONSTANT} <= {t.get_text() for t in fig.axes[0].get_legend().get_texts()}



def test_figure_command_draws_a_panel_per_study_from_real_cells(tmp_path, capsys):
    """Through the CLI: tiny double-integrator cells of two budget runs in two studies (one structured),
    the samples read from two shipped V̂s and one verification report."""
    import torch

    from conftest import SMOKE
    from madpinn.commands import main
    from policy_models import tiny_model_dir
    from workflow_helpers import write_overlay

    overlay = write_overlay(tmp_path / "cells.yaml", {
        "sim": {"backend": "double_integrator"}, "arenas": {"large": {"half_width": 4.0, "episode_s": 0.4}, "small": {"episode_s": 0.4}},
        "studies": {"vhat_budget": {"agent_counts": [4], "scenarios": 2, "runs": ["madpinn", "madpinn-b15"]},
                    "vhat_budget_circle": {"agent_counts": [4], "scenarios": 2, "runs": ["madpinn", "madpinn-b15"]}}})
    models = tiny_model_dir()
    torch.set_num_threads(1)
    paths = []
    for study in ("vhat_budget", "vhat_budget_circle"):
        for run in ("madpinn", "madpinn-b15"):
            out = tmp_path / study / run / "n4_seed100.parquet"
            assert main(["evaluate", "--config", str(REPO / "config.yaml"), str(SMOKE), str(overlay), "--study", study,
                         "--run", run, "--n-agents", "4", "--seed", "100", "--out", str(out), "--model", f"vhat={models / 'vhat.pt'}",
                         "--model", f"vs={models / 'vs.pt'}", "--no-track", "--no-progress", "--threads", "1"]) == 0
            paths.append(str(out))
    args = ["figure", "--config", str(REPO / "config.yaml"), str(SMOKE), str(overlay), "--name", "fig_vhat_budget",
            "--inputs", *paths, "--out-dir", str(tmp_path / "fig"), "--no-track",
            "--vhat", f"madpinn={REPO / 'models/vhat.pt'}", f"madpinn-b15={REPO / 'models/vhat_speed.pt'}",
            "--verify", f"madpinn={REPO / 'training/vhat_2r/vhat_scenario.json'}", "--study", "vhat_budget", "vhat_budget_circle"]
    assert main(args) == 0
    table = pd.read_csv(tmp_path / "fig" / "fig_vhat_budget.csv")
    assert set(table["study"]) == {"vhat_budget", "vhat_budget_circle"} and len(table) == 4
    assert set(table["samples"]) == {4096 * 60000, 4096 * 80000}
    assert table.loc[table["run"] == "madpinn", "eps_conflict"].gt(0).all() and table.loc[table["run"] == "madpinn-b15", "eps_conflict"].isna().all()
    assert set(table["schedule"]) == {ANNEALED}
    # every point with its interval and its infeasible share, read from each cell's summary
    assert (table["safety_lo"] <= table["safety"]).all() and (table["safety"] <= table["safety_hi"]).all()
    assert table["infeasible"].between(0.0, 1.0).all()
    # a malformed --verify item is named as such
    capsys.readouterr()
    assert main([*args, "--verify", "madpinn"]) != 0
    assert "--verify expects NAME=PATH, got 'madpinn'" in capsys.readouterr().err
    assert (tmp_path / "fig" / "fig_vhat_budget.png").stat().st_size > 0
    # a run without its V̂ is refused, naming the missing option
    assert main([a for a in args if not a.startswith("madpinn-b15=")]) != 0
    assert "--vhat madpinn-b15=PATH" in capsys.readouterr().err


def test_training_seed_replicates_are_a_range_not_a_budget():
    """A run whose V̂ repeats the base recipe with another training seed (issue 60 item 3) is drawn
    as the base budget's range over seeds and left out of every trend."""
    runs = [BudgetRun("madpinn-b05", "0.5x", 4096 * 30000, ANNEALED), BudgetRun("madpinn", "1x", 4096 * 60000, ANNEALED),
            BudgetRun("madpinn-s1", "seed 1", 4096 * 60000, ANNEALED, replicates="madpinn"),
            BudgetRun("madpinn-b3x", "3x", 4096 * 180000, ANNEALED)]
    safety = {("madpinn-b05", 64): 0.60, ("madpinn", 64): 0.65, ("madpinn-s1", 64): 0.72, ("madpinn-b3x", 64): 0.70}
    frames = {"vhat_budget": _agg(safety)}
    panels = [budget_panel("vhat_budget", "large", "uniform", [64])]
    table = budget_table(frames, runs, panels).set_index("run")
    assert table.at["madpinn", "seed_range_lo"] == pytest.approx(65.0) and table.at["madpinn", "seed_range_hi"] == pytest.approx(72.0)
    assert table.at["madpinn-s1", "schedule"] == "training seed of madpinn"
    # the trend runs through the three budgets only: the replicate's 72 % would steepen it
    without = budget_table({"vhat_budget": _agg({k: v for k, v in safety.items() if k[0] != "madpinn-s1"})},
                           [r for r in runs if r.replicates is None], panels).set_index("run")
    assert table.at["madpinn", "slope_per_decade"] == pytest.approx(without.at["madpinn", "slope_per_decade"])
    fig = draw_vhat_budget(frames, runs, panels)
    assert fig.axes[0].get_legend_handles_labels()[1].count("training-seed range") == 1


def test_a_recipe_variant_at_the_base_budget_is_a_marker_not_a_second_budget():
    """A V̂ that keeps the base's samples and schedule but changes its recipe (issue 61 item 4: uniform
    states) is no second 1× point: its own rows, a labelled marker, out of the trends; the base's trend
    and tags are those without it."""
    runs = [BudgetRun("madpinn-b05", "0.5x", 4096 * 30000, ANNEALED), BudgetRun("madpinn", "1x", 4096 * 60000, ANNEALED),
            BudgetRun("madpinn-s1", "seed 1", 4096 * 60000, ANNEALED, replicates="madpinn"),
            BudgetRun("madpinn-nocs", "uniform states", 4096 * 60000, ANNEALED, recipe_of="madpinn"),
            BudgetRun("madpinn-b3x", "3x", 4096 * 180000, ANNEALED)]
    safety = {("madpinn-b05", 64): 0.60, ("madpinn", 64): 0.65, ("madpinn-s1", 64): 0.70, ("madpinn-nocs", 64): 0.95,
              ("madpinn-b3x", 64): 0.70}
    panels = [budget_panel("vhat_budget", "large", "uniform", [64])]
    table = budget_table({"vhat_budget": _agg(safety)}, runs, panels).set_index("run")
    assert table.at["madpinn-nocs", "schedule"] == "recipe variant of madpinn"
    assert table.at["madpinn-nocs", "safety"] == pytest.approx(95.0)
    assert table.at["madpinn-nocs", "seed_range_lo"] == pytest.approx(65.0) and table.at["madpinn-nocs", "seed_range_hi"] == pytest.approx(70.0)
    assert list(table.index) == ["madpinn-b05", "madpinn", "madpinn-s1", "madpinn-nocs", "madpinn-b3x"]
    # as a budget its 95 % would bend the trend; as a recipe variant the trend is the budgets' alone
    without = budget_table({"vhat_budget": _agg({k: v for k, v in safety.items() if k[0] != "madpinn-nocs"})},
                           [r for r in runs if r.run != "madpinn-nocs"], panels).set_index("run")
    assert table.at["madpinn", "slope_per_decade"] == pytest.approx(without.at["madpinn", "slope_per_decade"])
    as_budget = budget_table({"vhat_budget": _agg(safety)},
                             [BudgetRun(r.run, r.label, r.samples, r.schedule, replicates=r.replicates) for r in runs], panels)
    assert (as_budget["schedule"] == ANNEALED).sum() == 4   # the failure this role prevents: a second 1× point
    fig = draw_vhat_budget({"vhat_budget": _agg(safety)}, runs, panels)
    ax = fig.axes[0]
    assert "uniform states" in {t.get_text() for t in ax.get_legend().get_texts()}
    assert [t.get_text() for t in ax.child_axes[0].get_xticklabels()] == ["0.5×", "1×", "3×"]   # tags of the budgets only
    assert any(line.get_linestyle() == ":" for line in ax.lines)   # the budgets' trend is drawn


def test_trends_are_drawn_without_replicates():
    runs = [BudgetRun("madpinn-b05", "0.5x", 4096 * 30000, ANNEALED), BudgetRun("madpinn", "1x", 4096 * 60000, ANNEALED)]
    fig = draw_vhat_budget({"vhat_budget": _agg({("madpinn-b05", 64): 0.6, ("madpinn", 64): 0.7})}, runs,
                           [budget_panel("vhat_budget", "large", "uniform", [64])])
    assert any(line.get_linestyle() == ":" for line in fig.axes[0].lines)


def test_the_figure_command_gives_each_v_hat_variant_its_role():
    """The config decides: the base is the run whose V̂ the others derive from (``from: cs``); a
    variant that only reseeds it (s1) replicates the base; one at the base's samples and schedule with
    another recipe (the base V̂, uniform states since issue 61) is a recipe variant; a variant at other
    samples (b05) or at the base's samples under another schedule (b2x) is a budget."""
    from madpinn.config import load_config
    from madpinn.figures.budget import budget_base, budget_roles

    table = load_config([REPO / "config.yaml"])["value_functions"]["vhat_variants"]
    variants = {"madpinn": None, **{f"madpinn-{v}": v for v in ("cs", "s1", "b05", "b2x")}}
    base = budget_base(variants, table)
    assert base == "madpinn-cs"
    one = (4096 * 60000, ANNEALED)
    roles = budget_roles(base, variants, table, {"madpinn": one, "madpinn-cs": one, "madpinn-s1": one,
                                                 "madpinn-b05": (4096 * 30000, ANNEALED), "madpinn-b2x": (4096 * 60000, CONSTANT)})
    assert roles["madpinn-s1"] == {"replicates": "madpinn-cs", "recipe_of": None}
    assert roles["madpinn"] == {"replicates": None, "recipe_of": "madpinn-cs"}
    for budget in ("madpinn-cs", "madpinn-b05", "madpinn-b2x"):
        assert roles[budget] == {"replicates": None, "recipe_of": None}, budget
    # without a `from` chain (the layout before issue 61) the base V̂'s run is the base
    flat = {"s1": {"seed": 1}, "nocs": {"conflict_sampling": {"fraction": 0.0}}}
    old = {"madpinn": None, "madpinn-s1": "s1", "madpinn-nocs": "nocs"}
    assert budget_base(old, flat) == "madpinn"
    roles = budget_roles("madpinn", old, flat, {run: one for run in old})
    assert roles["madpinn-s1"]["replicates"] == "madpinn" and roles["madpinn-nocs"]["recipe_of"] == "madpinn"
    # a reseeded variant of another recipe is no replicate of this base
    assert budget_roles("madpinn", {"madpinn": None, "madpinn-s1": "s1"}, {"s1": {"from": "cs", "seed": 1}, "cs": {}},
                        {"madpinn": one, "madpinn-s1": one})["madpinn-s1"] == {"replicates": None, "recipe_of": "madpinn"}


def test_the_deployed_recipes_seeds_and_other_recipes_take_their_roles_from_the_config():
    """Issue 60 item 3: with the cs recipe as the base, the deployed recipe's training seeds (us1, us2:
    ``{seed}`` without ``from``) replicate the run loading the base V̂, which is a recipe variant; a 4×
    batch of the deployed recipe (bs16k, no ``from``) is another recipe, not a constant-rate budget of cs."""
    from madpinn.config import load_config
    from madpinn.figures.budget import budget_base, budget_roles, lineage

    table = load_config([REPO / "config.yaml"])["value_functions"]["vhat_variants"]
    assert lineage("b2x", table) == ["b2x", "cs", None] and lineage(None, table) == [None]
    variants = {"madpinn": None, **{f"madpinn-{v}": v for v in ("cs", "s1", "b2x", "us1", "us2", "bs16k")}}
    base = budget_base(variants, table)
    one = (4096 * 60000, ANNEALED)
    budgets = {run: one for run in variants} | {"madpinn-b2x": (4096 * 120000, CONSTANT), "madpinn-bs16k": (16384 * 60000, CONSTANT)}
    roles = budget_roles(base, variants, table, budgets)
    assert base == "madpinn-cs" and roles["madpinn-s1"]["replicates"] == "madpinn-cs"
    assert roles["madpinn-us1"] == roles["madpinn-us2"] == {"replicates": "madpinn", "recipe_of": None}
    assert roles["madpinn"] == {"replicates": None, "recipe_of": "madpinn-cs"}
    assert roles["madpinn-bs16k"] == {"replicates": None, "recipe_of": "madpinn"}   # compared with the deployed recipe's band
    assert roles["madpinn-b2x"] == {"replicates": None, "recipe_of": None}


def test_a_recipe_variant_has_its_own_training_seed_range_beside_the_base():
    """Both recipes' bands at one budget: the base's range at its samples, the recipe variant's marker
    and range just right of it; a recipe at other samples is a marker, in no trend and no tag."""
    from madpinn.figures.budget import RECIPE_OFFSET, drawn_samples

    one = 4096 * 60000
    runs = [BudgetRun("madpinn-b05", "0.5x", one // 2, ANNEALED), BudgetRun("madpinn-cs", "cs", one, ANNEALED),
            BudgetRun("madpinn-s1", "cs seed 1", one, ANNEALED, replicates="madpinn-cs"),
            BudgetRun("madpinn", "uniform states", one, ANNEALED, recipe_of="madpinn-cs"),
            BudgetRun("madpinn-us1", "uniform seed 1", one, ANNEALED, replicates="madpinn"),
            BudgetRun("madpinn-us2", "uniform seed 2", one, ANNEALED, replicates="madpinn"),
            BudgetRun("madpinn-bs16k", "4x batch", 4 * one, CONSTANT, recipe_of="madpinn"),
            BudgetRun("madpinn-b3x", "3x", 3 * one, CONSTANT), BudgetRun("madpinn-b9x", "9x", 9 * one, CONSTANT)]
    safety = {("madpinn-b05", 64): 0.60, ("madpinn-cs", 64): 0.64, ("madpinn-s1", 64): 0.66, ("madpinn", 64): 0.61,
              ("madpinn-us1", 64): 0.65, ("madpinn-us2", 64): 0.70, ("madpinn-bs16k", 64): 0.99,
              ("madpinn-b3x", 64): 0.68, ("madpinn-b9x", 64): 0.70}
    panels = [budget_panel("vhat_budget", "large", "uniform", [64])]
    table = budget_table({"vhat_budget": _agg(safety)}, runs, panels).set_index("run")
    assert table.at["madpinn", "seed_range_of"] == "madpinn"
    assert (table.at["madpinn", "seed_range_lo"], table.at["madpinn", "seed_range_hi"], table.at["madpinn", "seeds"]) == pytest.approx((61.0, 70.0, 3))
    assert table.at["madpinn-cs", "seed_range_hi"] == pytest.approx(66.0) and table.at["madpinn-cs", "seeds"] == 2
    assert table.at["madpinn-us2", "schedule"] == "training seed of madpinn"
    assert table.at["madpinn-bs16k", "schedule"] == "recipe variant of madpinn"
    assert table.at["madpinn-bs16k", "seed_range_of"] == "madpinn"   # no replicates of its own: its recipe's band beside it
    # order at one budget: the budget, its seeds, the recipe variant, its seeds
    assert list(table.index[:6]) == ["madpinn-b05", "madpinn-cs", "madpinn-s1", "madpinn", "madpinn-us1", "madpinn-us2"]
    # the constant-rate trend is the cs budgets' alone: bs16k's 99 % would make it reach the paper
    without = budget_table({"vhat_budget": _agg({k: v for k, v in safety.items() if k[0] != "madpinn-bs16k"})},
                           [r for r in runs if r.run != "madpinn-bs16k"], panels).set_index("run")
    assert table.at["madpinn-b3x", "slope_per_decade"] == pytest.approx(without.at["madpinn-b3x", "slope_per_decade"])
    x = drawn_samples(runs)
    assert x["madpinn"] == pytest.approx(one * RECIPE_OFFSET) and x["madpinn-us1"] == x["madpinn"] and x["madpinn-s1"] == one
    fig = draw_vhat_budget({"vhat_budget": _agg(safety)}, runs, panels)
    ax = fig.axes[0]
    assert [t.get_text() for t in ax.child_axes[0].get_xticklabels()] == ["0.5×", "1×", "3×", "9×"]
    ranges = [c for c in ax.collections if c.get_label() == "training-seed range" or c.get_alpha() == 0.3]
    assert len(ranges) == 2   # one band per recipe
    text = " ".join(" ".join(t.get_text() for t in fig.texts).split())   # the notes unwrapped
    assert "training-seed range at 1×: 64.0–66.0 % (2 seeds)" in text and "61.0–70.0 % (3 seeds)" in text
    assert "4x batch (plus, drawn just right of its samples: the recipe of the diamond at other samples; no budget)" in text
