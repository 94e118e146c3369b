"""Paper figures: every run visible in every panel, nothing cut at an edge, labels that say what
is drawn (small frames and files of the same layout as the workflow's; fast)."""

import numpy as np
import pandas as pd
import pytest

from madpinn.evaluation.tables import ORACLE_RUN
from madpinn.figures.cost_safety import ORACLE_LABEL, ZOOM_SAFETY_PCT, draw_cost_safety
from settings_helpers import pair_system

RUNS = {   # run -> (label, {N: (safety fraction, cost ÷ T)}): a crowd at 100 % and an outlier, as in the protocol
    "madpinn": ("Ours (paper's deployment)", {3: (1.0, 0.284), 16: (0.980, 0.552)}),
    "madpinn-lookahead": ("Ours + 75 ms look-ahead (not in paper)", {3: (1.0, 0.289), 16: (0.992, 0.562)}),
    "safemarl": ("SafeMARL", {3: (1.0, 0.296), 16: (0.987, 0.573)}),
    "safemarl-layered": ("SafeMARL (layered filter)", {3: (1.0, 0.557), 16: (1.0, 1.347)}),
    "mppi": ("MPPI", {3: (0.996, 0.38), 16: (0.775, 0.44)}),
    "nominal": ("Nominal PD (no safety)", {3: (0.841, 0.293), 16: (0.339, 0.24)}),
}
OUTLIER = "SafeMARL (layered filter)"


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


def test_cost_safety_shows_every_run_whole_apart_and_zooms_into_the_crowd_at_100():
    import matplotlib.pyplot as plt

    from madpinn.figures.placement import overlapping_pairs

    fig = draw_cost_safety(_agg())
    fig.canvas.draw()
    axes = np.array(fig.axes).reshape(2, 2)                   # overview row, zoom row; N = 3, 16
    for col, n in enumerate((3, 16)):
        top, zoom = axes[0][col], axes[1][col]
        assert top.get_title() == f"{n} agents"
        assert {m[0] for m in _markers(top)} == {label for label, _ in RUNS.values()}
        crowd = {label for label, cells in RUNS.values() if 100 * cells[n][0] >= ZOOM_SAFETY_PCT}
        assert {m[0] for m in _markers(zoom)} == crowd
        for ax in (top, zoom):
            marks = _markers(ax)
            box = ax.get_window_extent()
            (x0, x1), (y0, y1) = sorted(ax.get_xlim()), ax.get_ylim()
            for label, x, y, ms in marks:                       # each whole marker inside its axes
                assert x0 <= x <= x1 and y0 <= y <= y1, (n, label)
                px, py = ax.transData.transform((x, y))
                r = ms / 2 * fig.dpi / 72
                assert box.x0 <= px - r and px + r <= box.x1 and box.y0 <= py - r and py + r <= box.y1, (n, label)
            # no marker covers another (the protocol's crowd at 100 % used to stack)
            assert not overlapping_pairs(ax, max(m[3] for m in marks), [m[0] for m in marks],
                                         np.array([m[1:3] for m in marks])), (n, ax.get_xlabel())
            # the outlier sits on the top edge, its cost written beside it; the others set the scale
            assert y1 < RUNS["safemarl-layered"][1][n][1]
            assert any(t.get_text().startswith(f"{RUNS['safemarl-layered'][1][n][1]:.2f}") for t in ax.texts)
    # the zoom's cost range is set by the crowd: 16 agents spans 0.55 … 0.57, not up to the outlier's 1.35
    assert np.diff(axes[1][1].get_ylim())[0] < 0.1
    assert axes[0][0].get_ylabel().startswith("cost ÷ T")
    labels = [t.get_text() for t in fig.legends[0].get_texts()]
    assert ORACLE_LABEL in labels and "Ours + 75 ms look-ahead (not in paper)" in labels
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


def _traj_file(path, collide: bool, wander: bool = False):
    """A trajectory file in the layout evaluation/cell.py writes: 3 agents on straight lines to their
    goals over 1 s (agents 1 and 2 meet at the centre when ``collide``; agent 3 heads far out of
    the arena when ``wander``)."""
    times = np.linspace(0.0, 1.0, 21)
    start = np.array([[-0.8, 0.0], [0.8, 0.0], [0.0, -0.8]])
    goals = np.array([[0.8, 0.0], [-0.8, 0.0] if collide else [0.8, 0.6], [1.9, 0.8] if wander else [0.0, 0.8]])
    pos = start[None] + times[:, None, None] * (goals - start)[None]
    first = np.array([200, 200, -1]) if collide else np.full(3, -1)
    np.savez(path, times=times, positions=pos.astype(np.float32), goals=goals.astype(np.float32),
             collided=first >= 0, first_collision_step=first, dt=0.0025, collision_radius=0.1, half_width=1.0)
    return path


def test_trajectories_one_panel_per_run_with_numbered_agents_and_goals(tmp_path):
    import matplotlib.pyplot as plt

    from madpinn.figures import trajectories

    paths = [_traj_file(tmp_path / "a.npz", True), _traj_file(tmp_path / "b.npz", False, wander=True)]
    files = trajectories.plot_trajectories(paths, ["Run A", "Run B"], tmp_path / "fig_trajectories")
    data = [np.load(p) for p in paths]
    fig = trajectories.draw_trajectories(data, ["Run A", "Run B"])
    fig.canvas.draw()
    assert [f.suffix for f in files] == [".pdf", ".png"] and all(f.stat().st_size > 1000 for f in files)
    axes = [ax for ax in fig.axes if ax.get_visible()]
    assert [ax.get_title() for ax in axes] == ["Run A\n2 of 3 agents collided", "Run B\nno collision"]
    for ax, d in zip(axes, data):   # every agent's number twice (start and goal), legible in print
        assert sorted(t.get_text() for t in ax.texts) == ["1", "1", "2", "2", "3", "3"]
        assert min(t.get_fontsize() for t in ax.texts) >= 8
        # cropped to its own scenario: its data span at least half the panel's area, although the
        # other run's agent left the arena (it once set every panel's scale)
        pts = np.concatenate([d["positions"].reshape(-1, 2), d["goals"]])
        span = np.prod(pts.max(0) - pts.min(0))
        assert span >= 0.5 * np.diff(ax.get_xlim())[0] * np.diff(ax.get_ylim())[0], ax.get_title()
    colours = trajectories.agent_colours(12)
    assert len({tuple(c) for c in colours[:9]}) == 9
    assert all(not (c[0] > 0.7 and c[1] < 0.3 and c[2] < 0.3) for c in colours)     # no red: red marks collisions
    plt.close("all")


def test_value_heatmap_scale_is_not_set_by_the_rims():
    """A few large values (the rims of the infeasible regions) must not set the colour scale: it
    ends at the HEATMAP_CLIP_PERCENTILE-th percentile, the arrow of the colour bar says more exists."""
    import matplotlib.pyplot as plt
    import torch

    from madpinn.value_functions.figures import HEATMAP_CLIP_PERCENTILE, draw_value_heatmap

    axis = torch.linspace(-1.0, 1.0, 41)
    yy, xx = torch.meshgrid(axis, axis, indexing="ij")
    z = 1.5 + ((xx + 0.5) ** 2 + yy ** 2).sqrt()             # low at the goal (-0.5, 0), ≤ 3.3
    rim = ((xx + 0.3) ** 2 + (yy - 0.4) ** 2).sqrt()
    feasible = rim > 0.12
    z = torch.where(rim < 0.18, torch.full_like(z, 21.0), z)  # the rim: a few cells at 21
    fig = draw_value_heatmap(axis, z, feasible)
    mesh = fig.axes[0].collections[0]
    expected = float(np.percentile(z[feasible].numpy(), HEATMAP_CLIP_PERCENTILE))
    assert mesh.norm.vmax == pytest.approx(expected) and mesh.norm.vmax < 4.0
    cbar = fig.axes[1]
    assert "clipped" in cbar.get_ylabel() and "21.0" in cbar.get_ylabel()
    plt.close(fig)


def test_value_heatmap_prints_at_300_dpi_on_a_fine_grid_with_legible_labels(tmp_path):
    import matplotlib.pyplot as plt
    import torch
    from PIL import Image

    from madpinn.value_functions.figures import HEATMAP_POINTS, draw_value_heatmap, value_heatmap

    axis = torch.linspace(-1.0, 1.0, 21)
    yy, xx = torch.meshgrid(axis, axis, indexing="ij")
    z = 1.5 + ((xx + 0.5) ** 2 + yy ** 2).sqrt()
    feasible = ((xx + 0.3) ** 2 + (yy - 0.4) ** 2).sqrt() > 0.12
    fig = draw_value_heatmap(axis, z, feasible)
    ax, cbar = fig.axes
    assert min(ax.xaxis.label.get_fontsize(), ax.yaxis.label.get_fontsize(), ax.title.get_fontsize(),
               cbar.yaxis.label.get_fontsize(), *(t.get_fontsize() for t in ax.get_xticklabels())) >= 9.5
    plt.close(fig)
    png = next(p for p in value_heatmap(axis, z, feasible, tmp_path / "fig_value_heatmap") if p.suffix == ".png")
    assert Image.open(png).info["dpi"][0] >= 299.5
    # the workflow's grid: a cell at most 1 % of the arena's width (smooth contours in print)
    assert 2.0 / (HEATMAP_POINTS - 1) <= 0.01


def test_vs_grid_panels_show_different_velocities_with_labels_apart():
    """fig_vs_grid's panels once were four times of one velocity, and V_s = 0 is the same at every
    time of the grid: each panel now shows another relative velocity (its own curves), the
    collision disk is named in the legend, and neighbouring tick labels do not meet."""
    import matplotlib.pyplot as plt
    import torch

    from conftest import REPO
    from madpinn.value_functions import load_vs
    from madpinn.value_functions.figures import draw_vs_grid
    from madpinn.value_functions.grid_reference import solve_pair_grid

    sol = solve_pair_grid(pair_system(), 9, 1.0, 6.0, (0.0, 0.25, 0.5, 0.75), accuracy="low")
    fig = draw_vs_grid(sol, load_vs(REPO / "models" / "vs.pt", dtype=torch.float64))
    fig.canvas.draw()
    titles = [ax.get_title() for ax in fig.axes]
    assert len(titles) == 4 and len(set(titles)) == 4 and all("v_{rel}" in t for t in titles)
    curves = [np.concatenate([p.vertices for p in ax.collections[1].get_paths()]) for ax in fig.axes]   # the PINN's
    assert all(not (a.shape == b.shape and np.allclose(a, b)) for i, a in enumerate(curves) for b in curves[i + 1:])
    assert any("collision disk" in t.get_text() for t in fig.legends[0].get_texts())
    renderer = fig.canvas.get_renderer()
    boxes = [[t.get_window_extent(renderer) for t in ax.get_xticklabels() + ax.get_yticklabels() if t.get_text()]
             for ax in fig.axes]
    for left, right in zip(boxes, boxes[1:]):
        assert max(b.x1 for b in left) < min(b.x0 for b in right)      # a gap between neighbours' labels
    plt.close(fig)


def test_vs_slices_colour_scale_is_centred_at_zero_and_the_circle_is_named():
    """The unsafe set (V_s < 0, a few cm deep) gets half the colour scale, not a sliver of it, and
    the magenta circle is the collision disk the legend names."""
    import matplotlib.pyplot as plt
    import torch

    from madpinn.value_functions.figures import draw_vs_slices

    axis = torch.linspace(-1.2, 1.2, 49)
    yy, xx = torch.meshgrid(axis, axis, indexing="ij")
    psi = (xx ** 2 + yy ** 2).sqrt() - 0.1                     # V_s of a static pair: -0.1 … 1.6 m
    fig = draw_vs_slices(axis, torch.stack([psi, psi - 0.05]), [(0.0, 0.0), (-2.0, 0.0)], 0.1)
    mesh = fig.axes[0].collections[0]
    assert mesh.norm(0.0) == pytest.approx(0.5) and mesh.norm(float(psi.min()) - 0.05) == pytest.approx(0.0, abs=1e-6)
    assert any("collision disk" in t.get_text() for t in fig.legends[0].get_texts())
    assert [ax.get_title() for ax in fig.axes[:2]] == [r"$v_{rel}$ = (0, 0) m/s", r"$v_{rel}$ = (-2, 0) m/s"]
    plt.close(fig)


def test_palette_gives_every_run_of_a_crowded_figure_its_own_colour():
    from madpinn.figures.style import palette
    runs = [f"run{i}" for i in range(16)]          # Table I's figure draws 12 runs
    colours = palette(runs)
    assert len({tuple(round(c, 3) for c in colours[r]) for r in runs}) == len(runs)
    with pytest.raises(ValueError, match="distinct colours"):
        palette(runs + ["one_more"])
