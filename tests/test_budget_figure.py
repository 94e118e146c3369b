"""fig_vhat_budget (issue 46): training samples read from the models, the log-linear trend and the
budget at which it would reach the paper, and the figure drawn through the workflow's function."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest

from conftest import REPO
from madpinn.figures.budget import BudgetRun, budget_table, draw_vhat_budget, model_samples, trend
from madpinn.figures.frontier import paper_points
from madpinn.value_functions.model import read_checkpoint


def test_samples_of_the_shipped_models():
    assert model_samples(read_checkpoint(REPO / "models/vhat.pt", "vhat")["meta"]) == 4096 * 60000
    # a fine-tune continues its initial model's batch stream: those samples count too
    assert model_samples(read_checkpoint(REPO / "models/vhat_speed.pt", "vhat")["meta"]) == 4096 * (20000 + 60000)
    with pytest.raises(ValueError, match="not a train-value model"):
        model_samples({"iterations": 3})


def test_trend_reaches_the_target_only_when_it_rises():
    a, b, needed = trend([1e8, 1e9], [80.0, 90.0], 100.0)
    assert b == pytest.approx(10.0) and needed == pytest.approx(1e10)
    assert trend([1e8, 1e9], [80.0, 70.0], 100.0)[2] is None
    assert trend([1e8, 1e8], [80.0, 82.0], 100.0)[2] is None


def _agg(safety: dict) -> pd.DataFrame:
    rows = [{"run": run, "n_agents": n, "safety_rate_mean": s, "safety_rate_std": np.nan, "safety_rate_ci_lo": s - 0.02,
             "safety_rate_ci_hi": min(1.0, s + 0.02)} for (run, n), s in safety.items()]
    return pd.DataFrame(rows)


def test_budget_table_and_figure_from_cells():
    runs = [BudgetRun("madpinn-b05", "0.5x", 4096 * 30000), BudgetRun("madpinn", "1x", 4096 * 60000),
            BudgetRun("madpinn-b3x", "3x", 4096 * 180000)]
    agg = _agg({("madpinn-b05", 64): 0.77, ("madpinn", 64): 0.80, ("madpinn-b3x", 64): 0.86,
                ("madpinn-b05", 128): 0.60, ("madpinn", 128): 0.68, ("madpinn-b3x", 128): 0.66})
    paper = paper_points([64, 128])
    table = budget_table(agg, runs, paper)
    at64 = table[table["n_agents"] == 64]
    assert list(at64["samples"]) == sorted(r.samples for r in runs) and (at64["paper_safety"] == 100.0).all()
    assert at64["slope_per_decade"].iloc[0] > 0 and at64["samples_to_paper"].iloc[0] > 4096 * 180000
    at128 = table[table["n_agents"] == 128]
    assert at128["slope_per_decade"].iloc[0] > 0 and math.isfinite(at128["samples_to_paper"].iloc[0])
    # a falling trend has no budget that reaches the paper
    falling = budget_table(_agg({("madpinn-b05", 64): 0.9, ("madpinn", 64): 0.8, ("madpinn-b3x", 64): 0.7}), runs, paper)
    assert falling["samples_to_paper"].isna().all()
    fig = draw_vhat_budget(agg, runs, paper)
    ax = fig.axes[0]
    assert ax.get_xscale() == "log" and len(ax.lines) >= 2 * 2   # a data line and a paper line per N
