"""fig_trajectories: top view of one scenario per run (the same initial conditions and goals),
one large panel per run.

Each agent has its own colour and number: a hollow numbered circle where it starts, its whole
path as a line with a dot every ``tick_s`` seconds (spacing = speed), a filled disc of radius r/2
where it ends (two discs touch exactly when agents collide), and its goal as a filled square
with the same number. Agents that collide get a red ring of radius r where their first collision
happened, and the panel title counts them. Axes in metres, every panel on one scale: the arena (dashed),
widened when an agent leaves it.
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


def agent_colours(n: int) -> list[tuple]:
    """``n`` agent colours without red: tab10 less its red (9 colours), then tab20's light shades."""
    base = [c for i, c in enumerate(sns.color_palette("tab10", 10)) if i != 3]
    light = [c for i, c in enumerate(sns.color_palette("tab20", 20)) if i % 2 == 1 and i != 7]
    palette = base + light
    return [palette[i % len(palette)] for i in range(n)]


def _panel(ax, d, label: str, tick_s: float, lim: float) -> int:
    """One run's scenario in ``ax``; returns how many agents collided."""
    times, pos, goals = d["times"], d["positions"], d["goals"]
    r, hw, dt = float(d["collision_radius"]), float(d["half_width"]), float(d["dt"])
    first = d["first_collision_step"]
    colours = agent_colours(pos.shape[1])
    every = max(1, int(round(tick_s / (times[1] - times[0])))) if len(times) > 1 else 1
    fs = 6.5 if pos.shape[1] < 10 else 5.5
    for a in range(pos.shape[1]):
        c = colours[a]
        ax.plot(pos[:, a, 0], pos[:, a, 1], color=c, lw=1.4, alpha=0.85, zorder=2)
        ax.plot(pos[every::every, a, 0], pos[every::every, a, 1], "o", color=c, ms=2.6, zorder=3)
        ax.plot(*goals[a], "s", color=c, ms=10, mec="white", mew=0.8, zorder=5)     # above an end disc on it
        ax.text(*goals[a], str(a + 1), color="white", fontsize=fs, ha="center", va="center", weight="bold", zorder=6)
        ax.add_patch(Circle(pos[0, a], r / 2, fc="white", ec=c, lw=1.5, zorder=4))
        ax.text(*pos[0, a], str(a + 1), color=c, fontsize=fs, ha="center", va="center", weight="bold", zorder=6)
        ax.add_patch(Circle(pos[-1, a], r / 2, color=c, alpha=0.95, zorder=4))
        if first[a] >= 0:
            k = min(int(np.searchsorted(times, first[a] * dt - 1e-9)), len(times) - 1)
            ax.add_patch(Circle(pos[k, a], r, fill=False, ec=COLLISION_COLOUR, lw=1.6, zorder=7))
    ax.add_patch(Rectangle((-hw, -hw), 2 * hw, 2 * hw, fill=False, ls="--", lw=0.8, ec="0.55", zorder=1))
    ax.set_xlim(-lim, lim)
    ax.set_ylim(-lim, lim)
    ax.set_aspect("equal")
    ticks = np.linspace(-hw, hw, 5)
    ax.set_xticks(ticks)
    ax.set_yticks(ticks)
    ax.tick_params(labelsize=8, pad=1)
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
    # one scale for all panels: the arena, widened when an agent leaves it
    lim = max(max(1.1 * float(d["half_width"]), float(np.abs(d["positions"]).max()) + 0.6 * float(d["collision_radius"]))
              for d in data)
    ncols = max(1, min(ncols, len(data)))
    nrows = -(-len(data) // ncols)
    fig, axes = plt.subplots(nrows, ncols, figsize=(3.9 * ncols, 4.1 * nrows + 0.5), squeeze=False)
    for i, (d, label) in enumerate(zip(data, labels)):
        ax = axes[i // ncols][i % ncols]
        _panel(ax, d, label, tick_s, lim)
        if i // ncols == nrows - 1 or i + ncols >= len(data):
            ax.set_xlabel("x (m)", fontsize=9)
        if i % ncols == 0:
            ax.set_ylabel("y (m)", fontsize=9)
    for j in range(len(data), nrows * ncols):
        axes[j // ncols][j % ncols].set_visible(False)
    grey = "0.35"
    legend = [
        Line2D([], [], marker="o", ls="none", mfc="white", mec=grey, mew=1.5, ms=9, label="start (agent number)"),
        Line2D([], [], marker="o", ls="-", color=grey, ms=3, label=f"path, a dot every {tick_s:g} s"),
        Line2D([], [], marker="o", ls="none", color=grey, ms=8, label="end (disc radius r/2)"),
        Line2D([], [], marker="s", ls="none", color=grey, ms=8, label="goal (same number and colour)"),
        Line2D([], [], marker="o", ls="none", mfc="none", mec=COLLISION_COLOUR, mew=1.6, ms=11,
               label="first collision (ring radius r)"),
    ]
    fig.tight_layout(rect=(0, 0.55 / fig.get_figheight(), 1, 1))
    fig.legend(handles=legend, loc="lower center", ncol=3 if ncols < 3 else 5, frameon=False, fontsize=9,
               bbox_to_anchor=(0.5, 0.0))
    return fig
