"""fig_cost_safety, in the style of the paper's cost–safety figure (Fig. 2): time-averaged cost
(cumulative cost ÷ T, the quantity the paper's cost figures match, SPEC §3) against safety rate,
one column per agent count, every run as mean ± std over seeds. Better methods sit bottom-right
(safe and cheap).

Two rows. The top row shows every run on a common scale (cost from 0, the oracle's lone-agent
lower bound dashed). The bottom row zooms into safety ≥ ``ZOOM_SAFETY_PCT`` with a cost range
fitted to the runs there, where the best methods crowd near 100 %: the zoomed region is outlined
in the top row. Each run has its own colour and marker shape; markers are hollow and drawn from
the largest to the smallest, so runs that still coincide show as nested outlines. Bars are ± one
standard deviation over seeds on both axes, safety bars clipped to [0, 100] %. The x range leaves
room for a whole marker right of 100 %, so no marker is cut at an edge.
"""

from __future__ import annotations

from pathlib import Path
from typing import Iterable

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd
from matplotlib.patches import Rectangle

from madpinn.evaluation.tables import ORACLE_RUN, table_data
from madpinn.figures import style

MARKERS = ("o", "s", "D", "^", "v", "P", "X", "<", ">", "h", "*", "p")
ZOOM_SAFETY_PCT = 95.0     # the bottom row shows safety rates from here to 100 %
RIGHT_PAD = 0.07           # share of an axis's width kept right of 100 % (room for the largest marker)
ORACLE_LABEL = "Oracle (lone-agent lower bound)"


def plot_cost_safety(result_paths: Iterable[str | Path], cfg: dict, out_prefix: str | Path,
                     oracle_paths: Iterable[str | Path] = ()) -> list[Path]:
    """Draw the figure from evaluation result files (and oracle files for the lower-bound line);
    writes ``<out_prefix>.pdf`` and ``.png`` and returns both paths."""
    agg = table_data(result_paths, cfg, oracle_paths)
    return style.save(draw_cost_safety(agg), out_prefix)


def _x_limits(lo: float, both: bool = False) -> tuple[float, float]:
    """x range (%) from ``lo`` to 100 plus ``RIGHT_PAD`` of the axis width (``both``: the same
    room left of ``lo`` too, for a marker sitting exactly at ``lo``)."""
    pad = RIGHT_PAD * (100.0 - lo) / (1.0 - (2 if both else 1) * RIGHT_PAD)
    return (lo - pad if both else lo), 100.0 + pad


def _zoom_y(rows: pd.DataFrame) -> tuple[float, float]:
    """Cost range of the zoomed row: the runs' mean ± std with 15 % padding, at least ±4 % of the mean."""
    lo = float((rows["cost_time_avg_mean"] - rows["cost_time_avg_std"]).min())
    hi = float((rows["cost_time_avg_mean"] + rows["cost_time_avg_std"]).max())
    mid = 0.5 * (lo + hi)
    half = max(0.5 * (hi - lo) * 1.15, 0.04 * abs(mid), 1e-3)
    return mid - half, mid + half


def _draw_runs(ax, agg_n: pd.DataFrame, runs: list[str], colours: dict, sizes: np.ndarray,
               min_safety: float | None = None) -> None:
    """One hollow marker with ± std bars per run (those at safety ≥ ``min_safety`` % when given)."""
    for i, run in enumerate(runs):
        row = agg_n[agg_n["run"] == run]
        if row.empty:
            continue
        r = row.iloc[0]
        x, sx = 100 * r["safety_rate_mean"], 100 * r["safety_rate_std"]
        y, sy = r["cost_time_avg_mean"], r["cost_time_avg_std"]
        if min_safety is not None and x < min_safety:
            continue
        xerr = [[min(sx, x)], [min(sx, 100.0 - x)]]          # clipped to [0, 100] %
        ax.errorbar(x, y, xerr=xerr, yerr=[[min(sy, y)], [sy]], fmt="none", capsize=2.5, elinewidth=1.0,
                    color=colours[run], zorder=2)
        # white-filled, largest first: a coinciding later run shows inside the earlier one's outline
        ax.plot(x, y, MARKERS[i % len(MARKERS)], ms=sizes[i], mfc="white", mew=1.6, color=colours[run],
                label=r["label"], zorder=3 + i)


def _safety_ticks(ax, lo: float) -> None:
    ax.xaxis.set_major_locator(plt.MaxNLocator(5, steps=[1, 2, 5, 10], integer=True))
    ticks = [t for t in ax.get_xticks() if lo <= t <= 100]
    if 100 not in ticks:
        ticks = [t for t in ticks if 100 - t >= 0.12 * (100 - lo)] + [100]   # 100 % always labelled
    ax.set_xticks(ticks)


def draw_cost_safety(agg: pd.DataFrame) -> plt.Figure:
    """The figure from :func:`madpinn.evaluation.tables.table_data`'s frame (columns ``run``,
    ``label``, ``n_agents``, ``safety_rate_mean|std`` (fraction), ``cost_time_avg_mean|std``;
    oracle rows under ``ORACLE_RUN``). Row 0: overview; row 1 (when any run reaches
    ``ZOOM_SAFETY_PCT``): the zoom."""
    style.setup()
    oracle, agg = agg[agg["run"] == ORACLE_RUN], agg[agg["run"] != ORACLE_RUN]
    counts = sorted(agg["n_agents"].unique())
    runs = list(dict.fromkeys(agg["run"]))
    colours = style.palette(runs)
    sizes = np.linspace(12, 5, max(len(runs), 2))   # first run largest: drawn first, beneath the others
    zoom_rows = agg[100 * agg["safety_rate_mean"] >= ZOOM_SAFETY_PCT]
    has_zoom = not zoom_rows.empty
    nrows = 2 if has_zoom else 1
    fig, axes = plt.subplots(nrows, len(counts), figsize=(3.4 * len(counts), 3.3 * nrows + 0.2), squeeze=False,
                             gridspec_kw={"height_ratios": [1.0, 1.0][:nrows]})
    for col, n in enumerate(counts):
        agg_n = agg[agg["n_agents"] == n]
        ax = axes[0][col]
        _draw_runs(ax, agg_n, runs, colours, sizes)
        ymax = float((agg_n["cost_time_avg_mean"] + agg_n["cost_time_avg_std"]).max())
        o = oracle[oracle["n_agents"] == n]
        if not o.empty:
            ax.axhline(o.iloc[0]["cost_time_avg_mean"], ls="--", lw=1.0, color="0.3", label=ORACLE_LABEL, zorder=1)
            ymax = max(ymax, float(o.iloc[0]["cost_time_avg_mean"]))
        lo = max(0.0, min(100 * agg_n["safety_rate_mean"].min() - 5.0, ZOOM_SAFETY_PCT - 5.0))
        lo = 5.0 * np.floor(lo / 5.0)
        ax.set_xlim(*_x_limits(lo))
        _safety_ticks(ax, lo)
        ax.set_ylim(0.0, 1.12 * ymax if ymax > 0 else 1.0)
        ax.set_title(f"{n} agents")
        ax.set_xlabel("safety rate (%)")
        if not has_zoom:
            continue
        zax = axes[1][col]
        in_zoom = zoom_rows[zoom_rows["n_agents"] == n]
        zx = _x_limits(ZOOM_SAFETY_PCT, both=True)
        zax.set_xlim(*zx)
        zax.set_xticks([95, 96, 97, 98, 99, 100] if ZOOM_SAFETY_PCT == 95.0 else [ZOOM_SAFETY_PCT, 100])
        zax.set_xlabel(f"safety rate (%), zoom ≥ {ZOOM_SAFETY_PCT:g} %")
        if in_zoom.empty:
            zax.text(0.5, 0.5, f"no run reaches\n{ZOOM_SAFETY_PCT:g} % safety", ha="center", va="center",
                     transform=zax.transAxes, color="0.4")
            zax.set_yticks([])
            continue
        _draw_runs(zax, agg_n, runs, colours, sizes, min_safety=ZOOM_SAFETY_PCT)
        y0, y1 = _zoom_y(in_zoom)
        zax.set_ylim(y0, y1)
        zax.yaxis.set_major_locator(plt.MaxNLocator(4))
        for spine in zax.spines.values():
            spine.set_edgecolor("0.45")
        # the zoomed region, outlined in the overview above
        ax.add_patch(Rectangle((zx[0], y0), zx[1] - zx[0], y1 - y0, fill=False, ls=":",
                               lw=1.0, ec="0.45", zorder=1))
    axes[0][0].set_ylabel("cost ÷ T (time-averaged)")
    if has_zoom:
        axes[1][0].set_ylabel("cost ÷ T, zoom")
    handles = {}
    for ax in axes.ravel():
        for h, lab in zip(*ax.get_legend_handles_labels()):
            handles.setdefault(lab, h)
    oracle_h = {k: handles.pop(k) for k in [k for k in handles if k == ORACLE_LABEL]}
    handles.update(oracle_h)                                   # runs first, the oracle line last
    longest = max((len(k) for k in handles), default=0)
    ncol = min(len(handles), 3 if longest > 28 else 4)
    rows = -(-len(handles) // max(ncol, 1))
    legend_in = 0.25 * rows + 0.2
    fig.tight_layout(rect=(0, legend_in / fig.get_figheight(), 1, 1), h_pad=1.2)
    fig.legend(list(handles.values()), list(handles), loc="lower center", ncol=ncol, frameon=False,
               bbox_to_anchor=(0.5, 0.0))
    return fig
