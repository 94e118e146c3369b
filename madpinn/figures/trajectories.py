"""fig_trajectories: top-view snapshots of one scenario per run (same initial conditions).

Axes in metres with a 0.5 m scale bar; drones are discs of radius r/2 (two discs touch exactly
when agents collide) in one colour per agent, their paths so far as faded lines, goals as
crosses in the agent's colour, and agents that have collided ringed in red from their first
collision on. One legend explains the symbols.
"""

from __future__ import annotations

from pathlib import Path
from typing import Sequence

import matplotlib.pyplot as plt
import numpy as np
from matplotlib.lines import Line2D
from matplotlib.patches import Circle

from madpinn.figures import style


def _scale_bar(ax, hw: float, length: float) -> None:
    x0, y0 = -hw * 1.05, -hw * 1.05
    ax.plot([x0, x0 + length], [y0, y0], color="black", lw=2.5, solid_capstyle="butt")
    ax.text(x0 + length / 2, y0 + 0.03 * hw, f"{length:g} m", ha="center", va="bottom", fontsize=8)


def plot_trajectories(traj_paths: Sequence[str | Path], labels: Sequence[str], out_prefix: str | Path, snapshots: int = 4) -> list[Path]:
    style.setup()
    data = [np.load(p) for p in traj_paths]
    fig, axes = plt.subplots(len(data), snapshots, figsize=(2.7 * snapshots, 2.7 * len(data) + 0.5), squeeze=False)
    for row, (d, label) in enumerate(zip(data, labels)):
        times, pos, goals = d["times"], d["positions"], d["goals"]
        r, hw = float(d["collision_radius"]), float(d["half_width"])
        first = d["first_collision_step"]
        dt = float(d["dt"])
        idx = np.linspace(0, len(times) - 1, snapshots).round().astype(int)
        colours = plt.cm.viridis(np.linspace(0.0, 0.9, pos.shape[1]))  # no red: red marks collisions
        bar = 0.5 if hw <= 2 else 2.0
        for col, k in enumerate(idx):
            ax = axes[row][col]
            for a in range(pos.shape[1]):
                ax.plot(pos[: k + 1, a, 0], pos[: k + 1, a, 1], color=colours[a], alpha=0.35, lw=1)
                ax.add_patch(Circle(pos[k, a], r / 2, color=colours[a], alpha=0.9))
                ax.plot(*goals[a], "x", color=colours[a], ms=5, mew=1.5)
                if 0 <= first[a] <= round(times[k] / dt):
                    ax.add_patch(Circle(pos[k, a], r, fill=False, ec="red", lw=1.5))
            ax.set_xlim(-hw * 1.12, hw * 1.12)
            ax.set_ylim(-hw * 1.12, hw * 1.12)
            ax.set_aspect("equal")
            ticks = [-hw, 0.0, hw]
            ax.set_xticks(ticks)
            ax.set_yticks(ticks)
            ax.tick_params(labelsize=7, pad=1)
            if row == len(data) - 1:
                ax.set_xlabel("x (m)", fontsize=8)
            if col == 0:
                ax.set_ylabel(f"{label}\ny (m)", fontsize=8)
            else:
                ax.set_yticklabels([])
            if row != len(data) - 1:
                ax.set_xticklabels([])
            if row == 0:
                ax.set_title(f"t = {times[k]:.2f} s", fontsize=9)
            _scale_bar(ax, hw, bar)
    legend = [
        Line2D([], [], marker="o", ls="-", color=plt.cm.viridis(0.4), alpha=0.8, ms=6, label="agent (disc: r/2) and its path"),
        Line2D([], [], marker="x", ls="none", color=plt.cm.viridis(0.4), mew=1.5, ms=6, label="goal (agent's colour)"),
        Line2D([], [], marker="o", ls="none", mfc="none", mec="red", mew=1.5, ms=10, label="collided (ring: radius r)"),
    ]
    fig.legend(handles=legend, loc="lower center", ncol=3, frameon=False, bbox_to_anchor=(0.5, -0.01), fontsize=8)
    fig.tight_layout(rect=(0, 0.3 / fig.get_figheight(), 1, 1))
    return style.save(fig, out_prefix)
