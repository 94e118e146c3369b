"""fig_cost_safety, in the paper's style: time-averaged cost (cumulative cost ÷ T, the quantity
the paper's cost figures match, SPEC §3) against safety rate, one panel per agent count, every
run as mean ± std over seeds. Better methods sit bottom-right (safe and cheap).

Every run stays visible where several coincide (typically at 100 % safety): each run has its own
marker shape, markers are hollow and drawn from the largest to the smallest, so coinciding runs
show as nested outlines. Error bars are clipped to the axis (safety within [0, 100] %). With
oracle files, a dashed line marks the lone-agent cost lower bound of each panel's scenarios.
"""

from __future__ import annotations

from pathlib import Path
from typing import Iterable

import matplotlib.pyplot as plt
import numpy as np

from madpinn.evaluation.tables import ORACLE_RUN, table_data
from madpinn.figures import style

MARKERS = ("o", "s", "D", "^", "v", "P", "X", "<", ">", "h", "*", "p")


def plot_cost_safety(result_paths: Iterable[str | Path], cfg: dict, out_prefix: str | Path,
                     oracle_paths: Iterable[str | Path] = ()) -> list[Path]:
    style.setup()
    agg = table_data(result_paths, cfg, oracle_paths)
    oracle, agg = agg[agg["run"] == ORACLE_RUN], agg[agg["run"] != ORACLE_RUN]
    counts = sorted(agg["n_agents"].unique())
    runs = list(dict.fromkeys(agg["run"]))
    colours = style.palette(runs)
    sizes = np.linspace(12, 5, max(len(runs), 2))   # first run largest: drawn first, beneath the others
    fig, axes = plt.subplots(1, len(counts), figsize=(3.3 * len(counts), 3.4), squeeze=False)
    for ax, n in zip(axes[0], counts):
        ymax = 0.0
        for i, run in enumerate(runs):
            row = agg[(agg["run"] == run) & (agg["n_agents"] == n)]
            if row.empty:
                continue
            r = row.iloc[0]
            x, sx = 100 * r["safety_rate_mean"], 100 * r["safety_rate_std"]
            y, sy = r["cost_time_avg_mean"], r["cost_time_avg_std"]
            xerr = [[min(sx, x)], [min(sx, 100.0 - x)]]          # clipped to [0, 100] %
            ax.errorbar(x, y, xerr=xerr, yerr=[[min(sy, y)], [sy]], fmt="none", capsize=2.5, elinewidth=1.0,
                        color=colours[run], zorder=2)
            # white-filled, largest first: a coinciding later run shows inside the earlier one's outline
            ax.plot(x, y, MARKERS[i % len(MARKERS)], ms=sizes[i], mfc="white", mew=1.6, color=colours[run],
                    label=r["label"], zorder=3 + i)
            ymax = max(ymax, y + sy)
        o = oracle[oracle["n_agents"] == n]
        if not o.empty:
            ax.axhline(o.iloc[0]["cost_time_avg_mean"], ls="--", lw=1.0, color="0.3", label="Oracle (lone-agent lower bound)", zorder=1)

            ymax = max(ymax, o.iloc[0]["cost_time_avg_mean"])
        ax.set_title(f"{n} agents")
        ax.set_xlabel("safety rate (%)")
        lo = agg[agg["n_agents"] == n]["safety_rate_mean"].min() * 100
        ax.set_xlim(max(0.0, min(lo - 5.0, 95.0)), 101.0)
        ax.xaxis.set_major_locator(plt.MaxNLocator(5, integer=True))
        ax.set_xticks([t for t in ax.get_xticks() if t <= 100])
        ax.set_ylim(0.0, 1.12 * ymax if ymax > 0 else 1.0)
    axes[0][0].set_ylabel("cost ÷ T (time-averaged)")
    handles = {}
    for ax in axes[0]:
        for h, lab in zip(*ax.get_legend_handles_labels()):
            handles.setdefault(lab, h)
    oracle_h = {k: handles.pop(k) for k in [k for k in handles if k.startswith("Oracle")]}
    handles.update(oracle_h)                                   # runs first, the oracle line last
    ncol = min(len(handles), 4)
    rows = -(-len(handles) // ncol)
    fig.tight_layout(rect=(0, 0.07 * rows, 1, 1))
    fig.legend(list(handles.values()), list(handles), loc="lower center", ncol=ncol, frameon=False,
               bbox_to_anchor=(0.5, 0.0))
    return style.save(fig, out_prefix)
