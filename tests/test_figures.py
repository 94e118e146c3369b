"""Paper figures: every run visible in every panel, nothing cut at an edge, labels that say what
is drawn (small frames and files of the same layout as the workflow's; fast)."""

import numpy as np
import pandas as pd
import pytest

from madpinn.evaluation.tables import ORACLE_RUN
from madpinn.figures.cost_safety import ORACLE_LABEL, ZOOM_SAFETY_PCT, draw_cost_safety

RUNS = {   # run -> (label, {N: (safety fraction, cost ÷ T)}): a crowd at 100 % as in the protocol
    "madpinn": ("Ours (paper's deployment)", {3: (1.0, 0.284), 16: (0.980, 0.552)}),
    "madpinn-lookahead": ("Ours + 75 ms look-ahead (not in paper)", {3: (1.0, 0.289), 16: (0.992, 0.562)}),
    "safemarl": ("SafeMARL", {3: (1.0, 0.296), 16: (0.987, 0.573)}),
    "mppi": ("MPPI", {3: (0.996, 0.38), 16: (0.775, 0.44)}),
    "nominal": ("Nominal PD (no safety)", {3: (0.841, 0.293), 16: (0.339, 0.24)}),
}


def _agg():
    rows = [dict(run=run, label=label, n_agents=n, safety_rate_mean=s, safety_rate_std=0.004,
                 cost_time_avg_mean=c, cost_time_avg_std=0.003)
            for run, (label, cells) in RUNS.items() for n, (s, c) in cells.items()]
    rows += [dict(run=ORACLE_RUN, label=ORACLE_LABEL, n_agents=n, safety_rate_mean=np.nan, safety_rate_std=np.nan,
                  cost_time_avg_mean=0.18, cost_time_avg_std=0.01) for n in (3, 16)]
    return pd.DataFrame(rows)


def _markers(ax):
    """(label, x, y, size in points) of the run markers drawn in ``ax``."""
    return [(l.get_label(), *l.get_xydata()[0], l.get_markersize()) for l in ax.get_lines()
            if l.get_marker() not in (None, "None", "") and not l.get_label().startswith("_")]


def test_cost_safety_shows_every_run_whole_and_zooms_into_the_crowd_at_100():
    import matplotlib.pyplot as plt

    fig = draw_cost_safety(_agg())
    fig.canvas.draw()
    axes = np.array(fig.axes).reshape(2, 2)                   # overview row, zoom row; N = 3, 16
    for col, n in enumerate((3, 16)):
        top, zoom = axes[0][col], axes[1][col]
        assert top.get_title() == f"{n} agents"
        assert {m[0] for m in _markers(top)} == {label for label, _ in RUNS.values()}
        crowd = {label for label, cells in RUNS.values() if 100 * cells[n][0] >= ZOOM_SAFETY_PCT}
        assert {m[0] for m in _markers(zoom)} == crowd
        for ax in (top, zoom):                                 # each whole marker inside its axes
            box = ax.get_window_extent()
            for label, x, y, ms in _markers(ax):
                px, py = ax.transData.transform((x, y))
                r = ms / 2 * fig.dpi / 72
                assert box.x0 <= px - r and px + r <= box.x1 and box.y0 <= py - r and py + r <= box.y1, (n, label)
        # the zoom separates the three runs at 100 % that the overview stacks (3 agents: costs 0.284 … 0.296)
        if n == 3:
            ys = sorted(zoom.transData.transform((100.0, c))[1] for _, cells in RUNS.values()
                        for s, c in [cells[3]] if s == 1.0)
            ys_top = sorted(top.transData.transform((100.0, c))[1] for _, cells in RUNS.values()
                            for s, c in [cells[3]] if s == 1.0)
            assert ys[-1] - ys[0] > 2 * (ys_top[-1] - ys_top[0])
    assert axes[0][0].get_ylabel().startswith("cost ÷ T")
    labels = [t.get_text() for t in fig.legends[0].get_texts()]
    assert labels[-1] == ORACLE_LABEL and "Ours + 75 ms look-ahead (not in paper)" in labels
    plt.close(fig)


def test_cost_safety_without_a_run_above_the_zoom_has_one_row():
    import matplotlib.pyplot as plt

    agg = _agg()
    agg = agg[(agg["run"] == "nominal") | (agg["run"] == ORACLE_RUN)]
    fig = draw_cost_safety(agg)
    assert len(fig.axes) == 2 and all(ax.get_title().endswith("agents") for ax in fig.axes)
    plt.close(fig)


@pytest.fixture(autouse=True)
def _headless():
    import matplotlib

    matplotlib.use("Agg")
