"""fig_trajectories: top view of one scenario per run (the same initial conditions and goals),
one large panel per run.

Each agent has its own colour and number: a hollow numbered circle where it starts, its whole
path as a line with a dot every ``tick_s`` seconds (spacing = speed), a filled disc of radius r/2
where it ends (two discs touch exactly when agents collide), and its goal as a filled square
with the same number (numbers ``NUMBER_PT`` points, legible at print size). Agents that collide
get a red ring of radius r where their first collision happened, and the panel title counts
them. Axes in metres, equal aspect, ticks every ``TICK_M``: each panel is cropped to its own
scenario (starts, paths and goals plus ``MARGIN_M``; the arena's edge dashed where it shows), so
no panel is mostly empty because another run's agent left the arena.
"""

from __future__ import annotations

from pathlib import Path
from typing import Sequence

import matplotlib.pyplot as plt
import numpy as np
import seaborn as sns
from matplotlib.lines import Line2D
from matplotlib.patches import Circle, Rectangle

from madpinn.figures import style

COLLISION_COLOUR = "#d62728"    # red marks collisions only: no agent gets a red colour
NUMBER_PT = 8.0                 # agent numbers (points)
LABEL_MARKER_PT = 14.0          # start circles and goal squares that carry a number (points)
MARGIN_M = 0.12                 # room around a panel's scenario (m)
TICK_M = 0.5                    # tick spacing (m)


def agent_colours(n: int) -> list[tuple]:
    """``n`` agent colours without red: tab10 less its red (9 colours), then tab20's light shades."""
    base = [c for i, c in enumerate(sns.color_palette("tab10", 10)) if i != 3]
    light = [c for i, c in enumerate(sns.color_palette("tab20", 20)) if i % 2 == 1 and i != 7]
    palette = base + light
    return [palette[i % len(palette)] for i in range(n)]


def panel_limits(d) -> tuple[tuple[float, float], tuple[float, float]]:
    """x and y range (m) of one scenario's panel: every position and goal plus ``MARGIN_M`` (the
    panel is the horizontal plane: a 3-D model's altitude is not drawn)."""
    positions, goals = np.asarray(d["positions"]), np.asarray(d["goals"])
    pts = np.concatenate([positions.reshape(-1, positions.shape[-1]), goals.reshape(-1, goals.shape[-1])])
    lo, hi = pts.min(0) - MARGIN_M, pts.max(0) + MARGIN_M
    return (float(lo[0]), float(hi[0])), (float(lo[1]), float(hi[1]))


def _fit_equal(ax) -> None:
    """Widen the shorter side of ``ax``'s limits (about their centre) so that one metre is as long
    on both axes in its final box: the scenario fills the panel at equal aspect."""
    box = ax.get_position()
    w, h = box.width * ax.figure.get_figwidth(), box.height * ax.figure.get_figheight()
    (x0, x1), (y0, y1) = ax.get_xlim(), ax.get_ylim()
    scale = max((x1 - x0) / w, (y1 - y0) / h)            # metres per inch
    cx, cy = 0.5 * (x0 + x1), 0.5 * (y0 + y1)
    ax.set_xlim(cx - 0.5 * scale * w, cx + 0.5 * scale * w)
    ax.set_ylim(cy - 0.5 * scale * h, cy + 0.5 * scale * h)
    ax.set_aspect("equal", adjustable="box")


def _panel(ax, d, label: str, tick_s: float) -> int:
    """One run's scenario in ``ax``; returns how many agents collided."""
    times, pos, goals = d["times"], d["positions"], d["goals"]
    r, hw, dt = float(d["collision_radius"]), float(d["half_width"]), float(d["dt"])
    first = d["first_collision_step"]
    colours = agent_colours(pos.shape[1])
    every = max(1, int(round(tick_s / (times[1] - times[0])))) if len(times) > 1 else 1
    fs = NUMBER_PT if pos.shape[1] < 10 else NUMBER_PT - 1
    ms = LABEL_MARKER_PT if pos.shape[1] < 10 else LABEL_MARKER_PT - 2
    for a in range(pos.shape[1]):
        c = colours[a]
        ax.plot(pos[:, a, 0], pos[:, a, 1], color=c, lw=1.4, alpha=0.85, zorder=2)
        ax.plot(pos[every::every, a, 0], pos[every::every, a, 1], "o", color=c, ms=2.6, zorder=3)
        ax.plot(*goals[a], "s", color=c, ms=ms, mec="white", mew=0.8, zorder=5)     # above an end disc on it
        ax.text(*goals[a], str(a + 1), color="white", fontsize=fs, ha="center", va="center", weight="bold", zorder=6)
        ax.plot(*pos[0, a], "o", ms=ms, mfc="white", mec=c, mew=1.5, zorder=4)
        ax.text(*pos[0, a], str(a + 1), color=c, fontsize=fs, ha="center", va="center", weight="bold", zorder=6)
        ax.add_patch(Circle(pos[-1, a], r / 2, color=c, alpha=0.95, zorder=4))
        if first[a] >= 0:
            k = min(int(np.searchsorted(times, first[a] * dt - 1e-9)), len(times) - 1)
            ax.add_patch(Circle(pos[k, a], r, fill=False, ec=COLLISION_COLOUR, lw=1.6, zorder=7))
    ax.add_patch(Rectangle((-hw, -hw), 2 * hw, 2 * hw, fill=False, ls="--", lw=0.8, ec="0.55", zorder=1))
    (x0, x1), (y0, y1) = panel_limits(d)
    ax.set_xlim(x0, x1)
    ax.set_ylim(y0, y1)
    ax.xaxis.set_major_locator(plt.MultipleLocator(TICK_M))
    ax.yaxis.set_major_locator(plt.MultipleLocator(TICK_M))
    ax.tick_params(labelsize=8.5, pad=1)
    hit = int((first >= 0).sum())
    ax.set_title(f"{label}\n{hit} of {pos.shape[1]} agents collided" if hit else f"{label}\nno collision", fontsize=9.5)
    return hit


def plot_trajectories(traj_paths: Sequence[str | Path], labels: Sequence[str], out_prefix: str | Path,
                      ncols: int = 3, tick_s: float = 0.5) -> list[Path]:
    """Draw one panel per trajectory file (``*_traj.npz`` of :mod:`madpinn.evaluation.cell`),
    titled by ``labels``; writes ``<out_prefix>.pdf`` and ``.png`` and returns both paths."""
    data = [np.load(p) for p in traj_paths]
    return style.save(draw_trajectories(data, labels, ncols, tick_s), out_prefix)


def draw_trajectories(data: Sequence, labels: Sequence[str], ncols: int = 3, tick_s: float = 0.5) -> plt.Figure:
    """The figure from loaded trajectory files (mappings with ``times`` [K] s, ``positions``
    [K, N, 2] m, ``goals`` [N, 2] m, ``first_collision_step`` [N] (simulation steps of ``dt`` s,
    -1: none), ``dt``, ``collision_radius``, ``half_width``): ``ncols`` panels a row, a dot on
    each path every ``tick_s`` seconds."""
    style.setup()
    if len(labels) != len(data):
        raise ValueError(f"{len(data)} trajectory files but {len(labels)} labels")
    ncols = max(1, min(ncols, len(data)))
    nrows = -(-len(data) // ncols)
    fig, axes = plt.subplots(nrows, ncols, figsize=(3.9 * ncols, 4.1 * nrows + 0.5), squeeze=False)
    for i, (d, label) in enumerate(zip(data, labels)):
        ax = axes[i // ncols][i % ncols]
        _panel(ax, d, label, tick_s)
        if i // ncols == nrows - 1 or i + ncols >= len(data):
            ax.set_xlabel("x (m)", fontsize=9)
        if i % ncols == 0:
            ax.set_ylabel("y (m)", fontsize=9)
    for j in range(len(data), nrows * ncols):
        axes[j // ncols][j % ncols].set_visible(False)
    grey = "0.35"
    legend = [
        Line2D([], [], marker="o", ls="none", mfc="white", mec=grey, mew=1.5, ms=10, label="start (agent number)"),
        Line2D([], [], marker="o", ls="-", color=grey, ms=3, label=f"path, a dot every {tick_s:g} s"),
        Line2D([], [], marker="o", ls="none", color=grey, ms=8, label="end (disc radius r/2)"),
        Line2D([], [], marker="s", ls="none", color=grey, ms=10, label="goal (same number and colour)"),
        Line2D([], [], marker="o", ls="none", mfc="none", mec=COLLISION_COLOUR, mew=1.6, ms=11,
               label="first collision (ring radius r)"),
        Line2D([], [], ls="--", lw=0.8, color="0.55", label="arena edge"),
    ]
    fig.tight_layout(rect=(0, 0.75 / fig.get_figheight(), 1, 1))
    for ax in axes.ravel():
        if ax.get_visible():
            _fit_equal(ax)
    fig.legend(handles=legend, loc="lower center", ncol=3, frameon=False, fontsize=9,
               bbox_to_anchor=(0.5, 0.0))
    return fig
