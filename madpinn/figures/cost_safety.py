"""fig_cost_safety, after the paper's cost–safety figure (Fig. 2): time-averaged cost (cumulative
cost ÷ T, the quantity the paper's cost figures match, SPEC §3) against safety, one column per
agent count, every run as mean ± std over seeds. Better methods sit bottom-right (safe and cheap).

Deviation from the paper's axes: x is the unsafe share 100 − safety rate (%) on a log scale
(linear below ``GAP_LINEAR_PCT`` %, so 0 has a place; 0 on the right, where the paper's 100 % is),
so that runs at 98, 99.9 and 100 % safety stand apart instead of on one vertical line.

Two rows. The top row shows every run (cost from 0, the oracle's lone-agent lower bound dashed).
The bottom row zooms into the runs at safety ≥ ``ZOOM_SAFETY_PCT`` %, where the best methods
crowd, with a cost range fitted to them (outlined in the top row).

In both rows a run whose cost exceeds ``OUTLIER_FACTOR`` × the panel's median run cost is an
outlier: it sits on the top edge with its cost written beside an upward arrow, so the scale serves
the other runs. Markers that would overlap move sideways in steps of about a marker width
(:func:`madpinn.figures.placement.dodge`, deterministic); a thin line joins a moved marker to a dot
at its true position. Bars are ± one standard deviation over seeds on both axes, clipped to the
possible range. Every marker lies whole inside its frame.
"""

from __future__ import annotations

from pathlib import Path
from typing import Iterable

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd
from matplotlib.lines import Line2D
from matplotlib.patches import Rectangle
from matplotlib.ticker import NullLocator

from madpinn.evaluation.tables import ORACLE_RUN, table_data
from madpinn.figures import style
from madpinn.figures.placement import Point, draw_points

MARKERS = ("o", "s", "D", "^", "v", "P", "X", "<", ">", "h", "*", "p")
MARKER_PT = 7.5            # marker size (points), the same for every run
ZOOM_SAFETY_PCT = 95.0     # the bottom row shows the runs at safety rates from here to 100 %
GAP_LINEAR_PCT = 0.1       # the unsafe-share axis is linear below this (%), logarithmic above
OVERVIEW_TICKS = (50, 10, 1, GAP_LINEAR_PCT, 0)         # labelled unsafe shares (%), top row
ZOOM_TICKS = (5, 2, 1, 0.5, 0.2, GAP_LINEAR_PCT, 0)      # and bottom row
OUTLIER_FACTOR = 1.5       # a run costing more than this × the panel's median run cost sits on the top edge
ORACLE_LABEL = "Oracle (lone-agent lower bound)"
MOVED_LABEL = "true position of a marker moved sideways"


def plot_cost_safety(result_paths: Iterable[str | Path], cfg: dict, out_prefix: str | Path,
                     oracle_paths: Iterable[str | Path] = ()) -> list[Path]:
    """Draw the figure from evaluation result files (and oracle files for the lower-bound line);
    writes ``<out_prefix>.pdf`` and ``.png`` and returns both paths."""
    agg = table_data(result_paths, cfg, oracle_paths)
    return style.save(draw_cost_safety(agg), out_prefix)


def outliers(costs: Iterable[float]) -> np.ndarray:
    """Mask of the costs above ``OUTLIER_FACTOR`` × their median (the runs drawn on the top edge)."""
    c = np.asarray(list(costs), dtype=float)
    return c > OUTLIER_FACTOR * np.median(c) if c.size else np.zeros(0, bool)


def _zoom_y(points: list[Point]) -> tuple[float, float]:
    """Cost range of a zoom panel: the runs' mean ± std with 15 % padding, at least ±4 % of the mean."""
    lo = min(p.y - p.y_lo for p in points)
    hi = max(p.y + p.y_hi for p in points)
    mid = 0.5 * (lo + hi)
    half = max(0.5 * (hi - lo) * 1.15, 0.04 * abs(mid), 1e-3)
    return mid - half, mid + half


def _points(agg_n: pd.DataFrame, runs: list[str], colours: dict, zoom: bool) -> list[Point]:
    """The panel's points in run order, x = 100 − safety (%); ``zoom``: only the runs at ≥ ``ZOOM_SAFETY_PCT`` %."""
    out = []
    for i, run in enumerate(runs):
        row = agg_n[agg_n["run"] == run]
        if row.empty:
            continue
        r = row.iloc[0]
        s, ss = 100 * r["safety_rate_mean"], 100 * r["safety_rate_std"]
        ss = 0.0 if not np.isfinite(ss) else ss
        if zoom and s < ZOOM_SAFETY_PCT:
            continue
        x, lo, hi = 100.0 - s, min(ss, 100.0 - s), min(ss, s)
        y = float(r["cost_time_avg_mean"])
        sy = float(r["cost_time_avg_std"]) if np.isfinite(r["cost_time_avg_std"]) else 0.0
        out.append(Point(r["label"], colours[run], MARKERS[i % len(MARKERS)], x, lo, hi, y, min(sy, y), sy))
    return out


def _gap_axis(ax, gap_max: float, ticks: tuple) -> None:
    """x axis 100 − safety (%) from ``gap_max`` (at least 100 − ``ZOOM_SAFETY_PCT``) down to 0,
    0 on the right; the ``ticks`` up to ``gap_max`` labelled."""
    ax.set_xscale("symlog", linthresh=GAP_LINEAR_PCT, linscale=0.6)
    gap_max = max(gap_max, 100.0 - ZOOM_SAFETY_PCT)
    ax.set_xlim(1.6 * gap_max, -0.25 * GAP_LINEAR_PCT)
    ticks = [t for t in ticks if t <= gap_max]
    ax.set_xticks(ticks, [f"{t:g}" for t in ticks])
    ax.xaxis.set_minor_locator(NullLocator())
    ax.set_xlabel("100 − safety rate (%), log scale")


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
    has_zoom = bool((100 * agg["safety_rate_mean"] >= ZOOM_SAFETY_PCT).any())
    nrows = 2 if has_zoom else 1
    fig, axes = plt.subplots(nrows, len(counts), figsize=(3.6 * len(counts), 3.4 * nrows + 0.3), squeeze=False)
    panels = []   # (axes, points, outlier mask): drawn once the layout is final
    for col, n in enumerate(counts):
        agg_n = agg[agg["n_agents"] == n]
        ax = axes[0][col]
        pts = _points(agg_n, runs, colours, zoom=False)
        off = outliers([p.y for p in pts])
        ymax = max((p.y + p.y_hi for p, o in zip(pts, off) if not o), default=1.0)
        o = oracle[oracle["n_agents"] == n]
        if not o.empty:
            ax.axhline(o.iloc[0]["cost_time_avg_mean"], ls="--", lw=1.0, color="0.3", zorder=1)
            ymax = max(ymax, float(o.iloc[0]["cost_time_avg_mean"]))
        _gap_axis(ax, max(p.x for p in pts), OVERVIEW_TICKS)
        ax.set_ylim(0.0, 1.15 * ymax if ymax > 0 else 1.0)
        ax.set_title(f"{n} agents")
        panels.append((ax, pts, off))
        if not has_zoom:
            continue
        zax = axes[1][col]
        _gap_axis(zax, 100.0 - ZOOM_SAFETY_PCT, ZOOM_TICKS)
        zpts = _points(agg_n, runs, colours, zoom=True)
        for spine in zax.spines.values():
            spine.set_edgecolor("0.45")
        if not zpts:
            zax.text(0.5, 0.5, f"no run reaches\n{ZOOM_SAFETY_PCT:g} % safety", ha="center", va="center",
                     transform=zax.transAxes, color="0.4")
            zax.set_yticks([])
            continue
        zoff = outliers([p.y for p in zpts])
        y0, y1 = _zoom_y([p for p, o in zip(zpts, zoff) if not o])
        zax.set_ylim(y0, y1)
        zax.yaxis.set_major_locator(plt.MaxNLocator(5))
        panels.append((zax, zpts, zoff))
        # the zoomed runs, outlined in the overview above (their cost range; the outliers' are off it)
        right = ax.get_xlim()[1]
        ax.add_patch(Rectangle((right, y0), 100.0 - ZOOM_SAFETY_PCT - right, min(y1, ax.get_ylim()[1]) - y0,
                               fill=False, ls=":", lw=1.0, ec="0.45", zorder=1))
    axes[0][0].set_ylabel("cost ÷ T (time-averaged)")
    if has_zoom:
        axes[1][0].set_ylabel(f"cost ÷ T, runs ≥ {ZOOM_SAFETY_PCT:g} % safe")
    handles = {p.label: Line2D([], [], marker=p.marker, ls="none", ms=MARKER_PT, mfc="white", mew=1.6, color=p.colour)
               for _, pts, _ in panels for p in pts}
    handles = {lab: handles[lab] for lab in dict.fromkeys(agg.set_index("run").loc[runs, "label"]) if lab in handles}
    if not oracle.empty:
        handles[ORACLE_LABEL] = Line2D([], [], ls="--", lw=1.0, color="0.3")
    handles[MOVED_LABEL] = Line2D([], [], ls="-", lw=0.8, marker=".", ms=4, color="0.3")
    longest = max((len(k) for k in handles), default=0)
    ncol = min(len(handles), 3 if longest > 28 else 4)
    legend_in = 0.25 * -(-len(handles) // max(ncol, 1)) + 0.2
    fig.tight_layout(rect=(0, legend_in / fig.get_figheight(), 1, 1), h_pad=1.2)
    fig.legend(list(handles.values()), list(handles), loc="lower center", ncol=ncol, frameon=False,
               bbox_to_anchor=(0.5, 0.0))
    for ax, pts, off in panels:
        draw_points(ax, pts, MARKER_PT, off)
    return fig
