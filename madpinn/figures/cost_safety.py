"""fig_cost_safety: cumulative cost vs safety rate, one panel per agent count, all runs
(mean ± std over seeds). Better methods sit bottom-right (safe and cheap)."""

from __future__ import annotations

from pathlib import Path
from typing import Iterable

import matplotlib.pyplot as plt

from madpinn.evaluation.tables import load_results, summarize
from madpinn.figures import style


def plot_cost_safety(result_paths: Iterable[str | Path], cfg: dict, out_prefix: str | Path) -> list[Path]:
    style.setup()
    agg = summarize(load_results(result_paths), cfg)
    counts = sorted(agg["n_agents"].unique())
    runs = list(dict.fromkeys(agg["run"]))
    colours = style.palette(runs)
    fig, axes = plt.subplots(1, len(counts), figsize=(3.2 * len(counts), 3.2), squeeze=False)
    for ax, n in zip(axes[0], counts):
        for run in runs:
            row = agg[(agg["run"] == run) & (agg["n_agents"] == n)]
            if row.empty:
                continue
            r = row.iloc[0]
            ax.errorbar(100 * r["safety_rate_mean"], r["cost_mean"], xerr=100 * r["safety_rate_std"], yerr=r["cost_std"],
                        fmt="o", ms=7, capsize=3, color=colours[run], label=r["label"])
        ax.set_title(f"{n} agents")
        ax.set_xlabel("safety rate (%)")
        ax.set_xlim(right=101)
    axes[0][0].set_ylabel("cumulative cost")
    handles, labels = axes[0][0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="lower center", ncol=min(len(labels), 6), bbox_to_anchor=(0.5, -0.08), frameon=False)
    fig.tight_layout()
    return style.save(fig, out_prefix)
