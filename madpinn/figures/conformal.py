"""The calibrated level's figure (issue 62, not in the paper): safety and cost ÷T against the level's
ε, one column per (study, N); pooled and per-speed-bin levels as lines, V̂ alone (δ = 0) and the
hand-tuned rows as horizontal lines, the paper's safety where it has a row."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from madpinn.evaluation.conformal_settings import REFERENCE_RUN, ConformalSettings
from madpinn.figures import style

SPLITS = {False: dict(fmt="o-", color="tab:blue", label="calibrated δ (pooled)"),
          True: dict(fmt="s--", color="tab:purple", label="calibrated δ per closing speed")}
OTHER_COLOURS = ("tab:green", "tab:brown", "tab:olive", "tab:cyan")
"""the hand-tuned rows' lines (none of the levels' colours)"""
PAPER_COLOUR = "tab:red"


def draw_conformal(rows: pd.DataFrame, settings: ConformalSettings):
    """The figure of :func:`madpinn.evaluation.conformal_page.cell_rows`' ``rows``."""
    import matplotlib.pyplot as plt

    style.setup()
    cols = list(rows[["study", "n_agents"]].drop_duplicates().itertuples(index=False, name=None))
    fig, axes = plt.subplots(2, len(cols), figsize=(3.0 * len(cols), 5.6), squeeze=False, sharex=True)
    if len(settings.others) > len(OTHER_COLOURS):
        raise ValueError(f"{len(settings.others)} hand-tuned rows: at most {len(OTHER_COLOURS)} distinct lines")
    colours = dict(zip(settings.others, OTHER_COLOURS))
    ticks = sorted({lv.epsilon for lv in settings.levels})
    eps = {lv.run: lv for lv in settings.levels}
    for j, (study, n) in enumerate(cols):
        g = rows[(rows["study"] == study) & (rows["n_agents"] == n)].set_index("run")
        for i, (fig_col, lo, hi, scale, name) in enumerate((("safety", "safety_lo", "safety_hi", 100.0, "safety (%)"),
                                                              ("cost_time_avg", "cost_time_avg_lo", "cost_time_avg_hi", 1.0, "cost ÷T"))):
            ax = axes[i, j]
            for binned, kw in SPLITS.items():
                runs = sorted((r for r in g.index if r in eps and eps[r].binned == binned), key=lambda r: eps[r].epsilon)
                if runs:
                    x = [eps[r].epsilon for r in runs]
                    y = scale * g.loc[runs, fig_col].to_numpy(dtype=float)
                    err = scale * np.abs(g.loc[runs, [lo, hi]].to_numpy(dtype=float).T - y / scale)
                    ax.errorbar(x, y, yerr=err, fmt=kw["fmt"], color=kw["color"], capsize=2, label=kw["label"])
            if REFERENCE_RUN in g.index:
                ax.axhline(scale * g.at[REFERENCE_RUN, fig_col], color="0.3", lw=1.2, label="V̂ alone (δ = 0)")
            for r in settings.others:
                if r in g.index:
                    ax.axhline(scale * g.at[r, fig_col], color=colours[r], ls=":", lw=1.2, label=settings.labels.get(r, r))
            if i == 0 and np.isfinite(g["paper_safety"]).any():
                ax.axhline(100 * float(g["paper_safety"].dropna().iloc[0]), color=PAPER_COLOUR, ls="--", lw=1.0, label="paper")
            ax.set_xscale("log")
            ax.set_xticks(ticks, [f"{e:g}" for e in ticks])
            ax.minorticks_off()
            ax.set_xlim(ticks[0] / 1.5, ticks[-1] * 1.5)
            ax.set_title(f"{study}, N = {n}" if i == 0 else "")
            ax.set_ylabel(name if j == 0 else "")
            if i == 1:
                ax.set_xlabel("ε of the level")
    handles = {}
    for ax in axes.flat:
        for h, lab in zip(*ax.get_legend_handles_labels()):
            handles.setdefault(lab, h)
    fig.legend(list(handles.values()), list(handles), loc="lower center", ncol=min(5, len(handles)), bbox_to_anchor=(0.5, -0.06))
    fig.suptitle("V̂ with a calibrated safety level (not in the paper; validation seeds)")
    fig.tight_layout()
    return fig


def plot_conformal(rows: pd.DataFrame, settings: ConformalSettings, out_prefix: str | Path) -> list[Path]:
    """Write ``<out_prefix>.pdf`` and ``.png``; returns both paths."""
    return style.save(draw_conformal(rows, settings), out_prefix)
