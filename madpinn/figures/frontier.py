"""fig_large_arena_frontier (issue 33 item 4, not in the paper): the large arena's safety–cost
frontier. One panel per agent count; x: time-averaged cost over the collision-free agents (cost ÷ T,
SPEC §3, the quantity of the paper's Table II cost column), y: safety rate. One marker per run (a V̂
or a deployment-only speed governor), with 95 % bootstrap intervals over scenarios on both axes when
a cell has one seed (:func:`madpinn.evaluation.metrics.scenario_intervals`), else ± one standard
deviation over seeds. Each governor sweep of one V̂ (goal-carrot length, speed bound ``v_max``) is
joined by a line through that V̂'s own point, ordered from the longest carrot / highest speed; the
paper's Table II points (``paper_values.yaml``) are overlaid as black stars with their numbers, so a
reader sees whether they lie on any frontier we reach (up and left is better).

Every marker lies whole inside its frame (the safety axis leaves room above 100 %); markers that
would overlap each other or the star move sideways (:func:`madpinn.figures.placement.dodge`,
deterministic), a thin line joining a moved marker to a dot at its true position. Runs with a
calibrated safety level (issue 62, ``conformal``) are markers of their own, on no governor sweep.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Iterable, Mapping, Sequence

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd
from matplotlib.lines import Line2D

from madpinn.evaluation.metrics import across_seeds
from madpinn.evaluation.paper_rows import paper_cells
from madpinn.evaluation.tables import load_results, per_seed
from madpinn.figures import style
from madpinn.figures.placement import Point, draw_points

MARKERS = ("o", "s", "D", "^", "v", "P", "X", "<", ">", "h", "p", "*")
SWEEP_STYLE = {"carrot": "-", "v_max": "--"}
SWEEP_NAME = {"carrot": "carrot sweep", "v_max": "v_max sweep"}
PAPER_LABEL = "Paper (Table II)"
MARKER_PT = 7.0        # run marker size (points)
STAR_PT = 14.0         # the paper's star (points)
MOVED_LABEL = "true position of a marker moved sideways"


@dataclass(frozen=True)
class FrontierRun:
    """How one run of the study deploys (what places it on a sweep).

    run: run name ``madpinn[-variant]``; label: its display name; vhat: the V̂ model it loads
    (``vhat`` or ``vhat_<variant>``); carrot: goal-carrot bound per coordinate (m, goal_range −
    carrot_margin); v_max: speed bound per axis of its cells (m/s); neighbour_goal: the neighbour
    goal mapping (runs of another mapping are on no sweep with the others); level: its calibrated
    safety level (``conformal``: e.g. ``ε 0.05``; empty: V̂'s own level; runs of another level are on
    no sweep with the others)."""

    run: str
    label: str
    vhat: str
    carrot: float
    v_max: float
    neighbour_goal: str = "neighbour"
    level: str = ""

    @classmethod
    def of_run(cls, cfg: Mapping, run: str) -> "FrontierRun":
        from madpinn.config import method_config, run_agents, run_observation, run_vhat
        from madpinn.evaluation.conformal_settings import level_run

        obs = run_observation(cfg, run)
        level = level_run(cfg, run)
        return cls(run=run, label=str(method_config(cfg, run)[1]["label"]), vhat=run_vhat(cfg, run),
                   carrot=float(obs["goal_range"]) - float(obs["carrot_margin"]),
                   v_max=float(run_agents(cfg, run)["v_max"]), neighbour_goal=str(obs["neighbour_goal"]),
                   level="" if not level else f"ε {level['epsilon']:g}{' per speed bin' if level['binned'] else ''}")


def sweeps(runs: Sequence[FrontierRun]) -> list[tuple[str, list[str]]]:
    """The governor sweeps among ``runs``: ``(kind, [run, ...])`` for each V̂ (with one neighbour goal
    mapping and one safety level) whose runs differ in the carrot only (kind ``carrot``, longest carrot first) or in the
    speed bound only (``v_max``, fastest first), at least two runs each."""
    out = []
    for kind, fixed in (("carrot", "v_max"), ("v_max", "carrot")):
        groups: dict[tuple, list[FrontierRun]] = {}
        for r in runs:
            groups.setdefault((r.vhat, r.neighbour_goal, r.level, getattr(r, fixed)), []).append(r)
        for group in groups.values():
            values = {getattr(r, kind) for r in group}
            if len(values) >= 2:
                out.append((kind, [r.run for r in sorted(group, key=lambda r: -getattr(r, kind))]))
    return out


def frontier_data(result_paths: Iterable[str | Path]) -> pd.DataFrame:
    """Per (run, N): seed figures' mean and std and, with one seed, the bootstrap intervals
    (:func:`madpinn.evaluation.metrics.across_seeds` columns ``safety_rate_*``, ``cost_time_avg_*``)."""
    return across_seeds(per_seed(load_results(result_paths)), ["run", "n_agents"])


def paper_points(counts: Iterable[int]) -> dict[int, dict]:
    """The paper's Table II MAD-PINN cells at ``counts``: N -> {cost (time-averaged), safety (fraction)}."""
    return paper_cells("large", None, counts)


def plot_large_arena_frontier(result_paths: Iterable[str | Path], runs: Sequence[FrontierRun],
                              out_prefix: str | Path) -> list[Path]:
    """Draw the figure from evaluation result files of ``runs``; writes ``<out_prefix>.pdf`` and
    ``.png`` and returns both paths."""
    agg = frontier_data(result_paths)
    return style.save(draw_large_arena_frontier(agg, runs, paper_points(agg["n_agents"].unique())), out_prefix)


def _interval(r, metric: str, scale: float = 1.0) -> tuple[float, float]:
    """Lower and upper bar lengths of ``metric`` around its mean: the bootstrap interval when the
    cell has one, else ± std (both ≥ 0)."""
    mean, lo, hi = r[f"{metric}_mean"], r.get(f"{metric}_ci_lo", np.nan), r.get(f"{metric}_ci_hi", np.nan)
    if np.isfinite(lo) and np.isfinite(hi):
        return scale * max(mean - lo, 0.0), scale * max(hi - mean, 0.0)
    sd = r[f"{metric}_std"] if np.isfinite(r[f"{metric}_std"]) else 0.0
    return scale * sd, scale * sd


def draw_large_arena_frontier(agg: pd.DataFrame, runs: Sequence[FrontierRun], paper: Mapping[int, Mapping]) -> plt.Figure:
    """The figure from :func:`frontier_data`'s frame, the runs' deployments (their order: legend and
    colours) and the paper's points (N -> {cost, safety}). One panel per N of ``agg``."""
    style.setup()
    known = {r.run: r for r in runs}
    missing = sorted(set(agg["run"]) - set(known))
    if missing:
        raise ValueError(f"no deployment given for runs {missing}")
    order = [r.run for r in runs if r.run in set(agg["run"])]
    colours = style.palette(order)
    counts = sorted(int(n) for n in agg["n_agents"].unique())
    lines = sweeps([known[r] for r in order])
    fig, axes = plt.subplots(1, len(counts), figsize=(3.9 * len(counts), 4.3), squeeze=False)
    panels = []   # (axes, points, star position): markers drawn once the layout is final
    for ax, n in zip(axes[0], counts):
        rows = {r["run"]: r for _, r in agg[agg["n_agents"] == n].iterrows()}
        for kind, members in lines:
            pts = [(rows[m]["cost_time_avg_mean"], 100 * rows[m]["safety_rate_mean"]) for m in members if m in rows]
            if len(pts) >= 2:
                xs, ys = zip(*pts)
                ax.plot(xs, ys, SWEEP_STYLE[kind], color="0.55", lw=1.1, zorder=1, label=SWEEP_NAME[kind])
        points = []
        for i, run in enumerate(order):
            if run not in rows:
                continue
            r = rows[run]
            x, y = r["cost_time_avg_mean"], 100 * r["safety_rate_mean"]
            xl, xh = _interval(r, "cost_time_avg")
            yl, yh = _interval(r, "safety_rate", 100.0)
            points.append(Point(known[run].label, colours[run], MARKERS[i % len(MARKERS)], x, xl, xh,
                                y, min(yl, y), min(yh, 100.0 - y)))                # clipped to [0, 100] %
        star = None
        if n in paper:
            p = paper[n]
            star = (p["cost"], 100 * p["safety"])
            ax.plot(*star, "*", ms=STAR_PT, color="black", zorder=50, label=PAPER_LABEL)
            # the star's numbers in the lower-right corner (high cost, low safety: dominated and
            # empty in this study), so the label covers no marker
            ax.text(0.98, 0.04, f"paper ★: {100 * p['safety']:.4g} %, cost {p['cost']:.3g}", transform=ax.transAxes,
                    ha="right", va="bottom", fontsize=7.5, zorder=51)
        xs = [v for q in points for v in (q.x - q.x_lo, q.x + q.x_hi)] + ([star[0]] if star else [])
        ys = [q.y - q.y_lo for q in points] + ([star[1]] if star else [])
        x0, x1 = min(xs), max(xs)
        ax.set_xlim(x0 - 0.07 * (x1 - x0), x1 + 0.07 * (x1 - x0))
        y0 = min(*ys, 95.0)                # at least 5 % of safety shown (all runs at 100 %: no empty range)
        ax.set_ylim(y0 - 0.06 * (100.0 - y0), 100.0 + 0.09 * (100.0 - y0))      # room for a whole marker at 100 %
        ax.set_title(f"{n} agents")
        ax.set_xlabel("cost ÷ T (time-averaged)")
        panels.append((ax, points, star))
    axes[0][0].set_ylabel("safety rate (%)")
    present = {q.label: q for _, points, _ in panels for q in points}
    handles = {k: Line2D([], [], marker=q.marker, ls="none", ms=MARKER_PT, mfc="white", mew=1.5, color=q.colour)
               for k, q in present.items()}                       # runs first, then the sweeps and the paper
    handles.update({SWEEP_NAME[kind]: Line2D([], [], ls=SWEEP_STYLE[kind], color="0.55", lw=1.1)
                    for kind in dict.fromkeys(kind for kind, _ in lines)})
    if any(star for _, _, star in panels):
        handles[PAPER_LABEL] = Line2D([], [], marker="*", ls="none", ms=STAR_PT, color="black")
    handles[MOVED_LABEL] = Line2D([], [], ls="-", lw=0.8, marker=".", ms=4, color="0.3")
    ncol = min(len(handles), 3)
    legend_in = 0.25 * -(-len(handles) // max(ncol, 1)) + 0.2
    fig.tight_layout(rect=(0, legend_in / fig.get_figheight(), 1, 1))
    fig.legend(list(handles.values()), list(handles), loc="lower center", ncol=ncol, frameon=False, bbox_to_anchor=(0.5, 0.0))
    for ax, points, star in panels:
        draw_points(ax, points, MARKER_PT, fixed=[star] if star else ())
    return fig
