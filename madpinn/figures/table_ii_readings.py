"""fig_table_ii_readings (issue 60, not in the paper): every Table II reading against the paper's
row. Four panels over the agent count: safety, safe scenarios, cost ∫ over [0, T] and cost ÷ T
(collision-free agents). One line per reading (colour: the run, line style: the start/goal law,
marker: the horizon T), the paper's Table II as black stars with the scale's band (safety − 2
points, safe scenarios − 15 points, cost ± 25 %: :data:`madpinn.evaluation.table_ii_readings.SCALE`)
shaded grey, so a reading inside every band at every N reproduces the table.
"""

from __future__ import annotations

from pathlib import Path
from typing import Mapping

import matplotlib.pyplot as plt
import pandas as pd
from matplotlib.lines import Line2D

from madpinn.evaluation.table_ii_readings import SCALE, PaperRow
from madpinn.figures import style

PANELS = (("safety", "safety (%)", 100.0), ("safe_scenarios", "safe scenarios (%)", 100.0),
          ("cost", "cost ∫ over [0, T]", 1.0), ("cost_time_avg", "cost ÷ T", 1.0))
LAW_STYLES = ("-", "--", ":", "-.")
HORIZON_MARKERS = ("o", "s", "D", "^", "v")


def _band(paper: PaperRow, figure: str, n: int, scale: float) -> tuple[float, float]:
    """The scale's accepted interval around the paper's value of ``figure`` at N (display units)."""
    c = paper.cells[n]
    if figure == "safety":
        return scale * (c["safety"] - SCALE.safety_points), scale
    if figure == "safe_scenarios":
        return scale * (c["safe_scenarios"] - SCALE.safe_points), scale
    return c["cost"] * (1 - SCALE.cost_relative), c["cost"] * (1 + SCALE.cost_relative)


def identical_runs(rows: pd.DataFrame) -> dict[str, str]:
    """Each run whose every plotted figure (at every law, T and N) equals an earlier run's, mapped to
    that run: its lines, drawn later, lie exactly over the earlier one's and hide them, so the legend says so."""
    keys = ["pattern", "horizon_s", "n_agents"]
    figures = [f for f, _, _ in PANELS]

    def frame(run):
        g = rows[rows["run"] == run]
        return g[keys + figures].sort_values(keys).reset_index(drop=True)

    seen: list[tuple[str, pd.DataFrame]] = []
    same: dict[str, str] = {}
    for run in dict.fromkeys(rows["run"]):
        f = frame(run)
        twin = next((r for r, g in seen if g.shape == f.shape and g.equals(f)), None)
        if twin is None:
            seen.append((run, f))
        else:
            same[run] = twin
    return same


def draw_table_ii_readings(rows: pd.DataFrame, paper: PaperRow, labels: Mapping[str, str]) -> plt.Figure:
    """The figure from :func:`madpinn.evaluation.table_ii_readings.reading_rows`' frame."""
    style.setup()
    runs = list(dict.fromkeys(rows["run"]))
    colours = style.palette(runs)
    laws = {p: LAW_STYLES[i % len(LAW_STYLES)] for i, p in enumerate(dict.fromkeys(rows["pattern"]))}
    horizons = {h: HORIZON_MARKERS[i % len(HORIZON_MARKERS)] for i, h in enumerate(sorted(rows["horizon_s"].unique()))}
    counts = sorted(paper.cells)
    fig, axes = plt.subplots(1, len(PANELS), figsize=(3.6 * len(PANELS), 3.8), squeeze=False)
    for ax, (figure, title, scale) in zip(axes[0], PANELS):
        for i, n in enumerate(counts):
            lo, hi = _band(paper, figure, n, scale)
            ax.fill_between([i - 0.3, i + 0.3], lo, hi, color="0.85", zorder=0, lw=0)
            ax.plot(i, scale * paper.cells[n]["cost" if figure.startswith("cost") else figure], "*", color="black",
                    ms=12, zorder=5)
        for (study, run, h), g in rows.groupby(["study", "run", "horizon_s"], sort=False):
            g = g.set_index("n_agents").reindex(counts)
            ax.plot(range(len(counts)), scale * g[figure].to_numpy(dtype=float), laws[g["pattern"].dropna().iloc[0]],
                    marker=horizons[h], color=colours[run], lw=1.2, ms=5, zorder=3)
        ax.set_xticks(range(len(counts)), [str(n) for n in counts])
        ax.set_xlabel("agents")
        ax.set_title(title)
    twins = identical_runs(rows)
    handles = {labels.get(r, r) + (f" (identical to {labels.get(twins[r], twins[r])}: its line hides that one)" if r in twins else ""):
               Line2D([], [], color=colours[r], lw=2) for r in runs}
    handles.update({f"law: {p}": Line2D([], [], ls=s, color="0.3") for p, s in laws.items()})
    handles.update({f"T = {h:g} s": Line2D([], [], marker=m, ls="none", color="0.3") for h, m in horizons.items()})
    handles["paper (Table II) and the scale's band"] = Line2D([], [], marker="*", ls="none", ms=12, color="black")
    ncol = 3
    rows_in = -(-len(handles) // ncol)
    fig.tight_layout(rect=(0, (0.25 * rows_in + 0.2) / fig.get_figheight(), 1, 1))
    fig.legend(list(handles.values()), list(handles), loc="lower center", ncol=ncol, frameon=False, fontsize=8)
    return fig


def plot_table_ii_readings(rows: pd.DataFrame, paper: PaperRow, labels: Mapping[str, str], out_prefix: str | Path) -> list[Path]:
    """Write ``<out_prefix>.pdf`` and ``.png``; returns both paths."""
    return style.save(draw_table_ii_readings(rows, paper, labels), out_prefix)
