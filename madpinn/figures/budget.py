"""fig_vhat_budget (issue 46): does the scalability claim fail, or is V̂ under-trained? Safety rate
against V̂'s training samples (batch × iterations, log axis), one line per agent count, from the
cells of one study whose runs differ only in the V̂ they load. The paper's Table II safety at each
N is a dashed line of the same colour; a least-squares trend ``safety = a + b·log10(samples)``
per N (at least two budgets) is extended to where it would reach the paper's value, and the
budget it would need is printed (none when the trend does not rise). Error bars: 95 % bootstrap
intervals over scenarios (one seed), else ± one standard deviation over seeds.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Iterable, Mapping, Sequence

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd

from madpinn.figures import style
from madpinn.figures.frontier import _interval, frontier_data, paper_points

PAPER_SAMPLES = 65536 * 100000
"""the paper's V̂ recipe (DeepReach practice: 65 536 states × 100 000 iterations)"""


@dataclass(frozen=True)
class BudgetRun:
    """One V̂ budget: the run that deploys it, its label and its training samples."""

    run: str
    label: str
    samples: int
    """training states seen: batch_size × (iterations + batch_offset) of the model (a fine-tune
    continues its initial model's batch stream, so the offset counts those samples)"""


def model_samples(meta: Mapping) -> int:
    """Training samples of a V̂ from its model metadata (``train-value``'s ``meta``)."""
    settings = meta.get("settings") or {}
    if "batch_size" not in settings or "iterations" not in meta:
        raise ValueError("the model's metadata has no batch_size / iterations: not a train-value model")
    return int(settings["batch_size"]) * (int(meta["iterations"]) + int(meta.get("batch_offset", 0)))


def trend(samples: Sequence[float], safety: Sequence[float], target: float) -> tuple[float, float, float | None]:
    """Least-squares ``safety = a + b·log10(samples)``; returns ``(a, b, samples at target)`` with
    the last None when ``b ≤ 0`` (no rising trend) or fewer than two distinct budgets."""
    x = np.log10(np.asarray(samples, dtype=float))
    y = np.asarray(safety, dtype=float)
    if len(np.unique(x)) < 2:
        return float(np.mean(y)), 0.0, None
    b, a = np.polyfit(x, y, 1)
    if b <= 0:
        return float(a), float(b), None
    return float(a), float(b), float(10 ** ((target - a) / b))


def budget_table(agg: pd.DataFrame, runs: Sequence[BudgetRun], paper: Mapping[int, Mapping]) -> pd.DataFrame:
    """Per (N, run): samples, safety (%) and, per N, the trend's slope (points per decade) and the
    samples at which it reaches the paper's safety (NaN: never)."""
    by_run = {r.run: r for r in runs}
    rows = []
    for n, group in agg.groupby("n_agents"):
        pts = [(by_run[r["run"]].samples, 100 * r["safety_rate_mean"]) for _, r in group.iterrows() if r["run"] in by_run]
        target = 100 * paper[int(n)]["safety"] if int(n) in paper else math.nan
        _, slope, needed = trend(*zip(*pts), target) if pts and math.isfinite(target) else (0, math.nan, None)
        for s, y in sorted(pts):
            rows.append({"n_agents": int(n), "samples": s, "safety": y, "paper_safety": target,
                         "slope_per_decade": slope, "samples_to_paper": needed if needed is not None else math.nan})
    return pd.DataFrame(rows)


def plot_vhat_budget(result_paths: Iterable[str | Path], runs: Sequence[BudgetRun], out_prefix: str | Path) -> list[Path]:
    """Draw the figure from evaluation result files of ``runs``; writes ``<out_prefix>.{pdf,png}``
    and ``<out_prefix>.csv`` (:func:`budget_table`); returns the three paths."""
    agg = frontier_data(result_paths)
    missing = sorted(set(agg["run"]) - {r.run for r in runs})
    if missing:
        raise ValueError(f"no V̂ budget given for runs {missing}")
    paper = paper_points(agg["n_agents"].unique())
    table = budget_table(agg, runs, paper)
    out_prefix = Path(out_prefix)
    files = style.save(draw_vhat_budget(agg, runs, paper), out_prefix)
    csv = out_prefix.with_suffix(".csv")
    table.to_csv(csv, index=False, float_format="%.6g")
    return [*files, csv]


def draw_vhat_budget(agg: pd.DataFrame, runs: Sequence[BudgetRun], paper: Mapping[int, Mapping]) -> plt.Figure:
    style.setup()
    by_run = {r.run: r for r in runs}
    counts = sorted(int(n) for n in agg["n_agents"].unique())
    colours = style.palette([str(n) for n in counts])
    fig, ax = plt.subplots(figsize=(6.4, 4.2))
    x_all = [r.samples for r in runs] + [PAPER_SAMPLES]
    xs_line = np.logspace(math.log10(min(x_all)) - 0.1, math.log10(max(x_all)) + 0.1, 50)
    notes = []
    for n in counts:
        c = colours[str(n)]
        rows = sorted(((by_run[r["run"]].samples, r) for _, r in agg[agg["n_agents"] == n].iterrows()), key=lambda p: p[0])
        xs = [s for s, _ in rows]
        ys = [100 * r["safety_rate_mean"] for _, r in rows]
        err = np.array([_interval(r, "safety_rate", 100.0) for _, r in rows]).T
        ax.errorbar(xs, ys, yerr=err, fmt="o-", color=c, capsize=2.5, ms=6, mfc="white", mew=1.5, label=f"{n} agents")
        if n in paper:
            target = 100 * paper[n]["safety"]
            ax.axhline(target, ls="--", lw=1.0, color=c)
            a, b, needed = trend(xs, ys, target)
            if b > 0:
                ax.plot(xs_line, a + b * np.log10(xs_line), ":", lw=1.0, color=c)
            notes.append(f"{n}: paper {target:.4g} %; " + (f"trend +{b:.1f} pts/decade, reaches it at {needed:.2g} samples"
                                                          if needed is not None else "no rising trend"))
    ax.axvline(PAPER_SAMPLES, color="0.4", lw=0.8)
    ax.text(PAPER_SAMPLES, 1.0, " paper's recipe", transform=ax.get_xaxis_transform(), fontsize=7.5, va="top", ha="left")
    for r in runs:
        ax.annotate(r.label, (r.samples, 0.0), xycoords=("data", "axes fraction"), xytext=(0, 3), textcoords="offset points",
                    rotation=90, fontsize=7, ha="center", va="bottom", color="0.3")
    ax.set_xscale("log")
    ax.set_xlabel("V̂ training samples (batch × iterations)")
    ax.set_ylabel("safety rate (%)")
    ax.set_ylim(top=101)
    ax.legend(loc="center right", fontsize=8, frameon=True)
    fig.text(0.01, -0.02, "\n".join(notes), fontsize=7.5, va="top")
    fig.tight_layout()
    return fig
