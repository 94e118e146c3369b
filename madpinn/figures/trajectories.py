"""fig_trajectories: top-view snapshots of one scenario per run (same initial conditions).

Drones are discs of radius r/2 (two discs touch exactly when agents collide), goals are dots,
agents that ever collide are ringed in red at their first collision; faded lines show paths.
"""

from __future__ import annotations

from pathlib import Path
from typing import Sequence

import matplotlib.pyplot as plt
import numpy as np
from matplotlib.patches import Circle

from madpinn.figures import style


def plot_trajectories(traj_paths: Sequence[str | Path], labels: Sequence[str], out_prefix: str | Path, snapshots: int = 4) -> list[Path]:
    style.setup()
    data = [np.load(p) for p in traj_paths]
    fig, axes = plt.subplots(len(data), snapshots, figsize=(2.6 * snapshots, 2.6 * len(data)), squeeze=False)
    for row, (d, label) in enumerate(zip(data, labels)):
        times, pos, goals = d["times"], d["positions"], d["goals"]
        r, hw = float(d["collision_radius"]), float(d["half_width"])
        first = d["first_collision_step"]
        dt = float(d["dt"])
        idx = np.linspace(0, len(times) - 1, snapshots).round().astype(int)
        colours = plt.cm.viridis(np.linspace(0.0, 0.9, pos.shape[1]))  # no red: red marks collisions
        for col, k in enumerate(idx):
            ax = axes[row][col]
            for a in range(pos.shape[1]):
                ax.plot(pos[: k + 1, a, 0], pos[: k + 1, a, 1], color=colours[a], alpha=0.35, lw=1)
                ax.add_patch(Circle(pos[k, a], r / 2, color=colours[a], alpha=0.9))
                ax.plot(*goals[a], ".", color=colours[a], ms=5)
                if 0 <= first[a] <= round(times[k] / dt):
                    ax.add_patch(Circle(pos[k, a], r, fill=False, ec="red", lw=1.5))
            ax.set_xlim(-hw * 1.1, hw * 1.1)
            ax.set_ylim(-hw * 1.1, hw * 1.1)
            ax.set_aspect("equal")
            ax.set_xticks([])
            ax.set_yticks([])
            if row == 0:
                ax.set_title(f"t = {times[k]:.2f} s")
            if col == 0:
                ax.set_ylabel(label)
    fig.tight_layout()
    return style.save(fig, out_prefix)
