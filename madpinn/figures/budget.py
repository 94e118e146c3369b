"""fig_vhat_budget (issue 46): does the scalability claim fail, or is V̂ under-trained? Safety rate
against V̂'s training samples (batch × iterations, log axis), one panel per study of the budget group
(Table II's large arena, Table I's small arena, a structured conflict), one line per agent count,
from cells whose runs differ only in the V̂ they load. The paper's safety for its own method at that
setting and N (Table II, Table I; none for a structured conflict, which the paper does not test) is
a dashed line of the same colour. Budgets are grouped by learning-rate schedule, since a curve across
schedules mixes two changes: our shipped recipe anneals the rate, the paper's keeps it constant, and
budgets of one schedule differ in samples only. A least-squares trend ``safety = a + b·log10(samples)``
per N and schedule (at least two budgets of it) is extended to where it would reach the paper's
value, and the budget it would need is printed (none when the trend does not rise). Error bars: 95 % bootstrap intervals over
scenarios (one seed), else ± one standard deviation over seeds. With each V̂'s scenario verification
(``verify-vhat``), the CSV also carries its ε on uniform and on conflict states; each point has its
interval and its infeasible share (agent-steps with no feasible budget) there too. Two kinds of run are
no budget and stay out of the trends: a training-seed replicate of a budget (drawn as that budget's
range over seeds) and a recipe variant at a budget's samples and schedule (e.g. uniform states
instead of conflict sampling; a labelled marker at its samples, its own CSV rows).
"""

from __future__ import annotations

import math
import textwrap
from dataclasses import dataclass, field
from pathlib import Path
from typing import Iterable, Mapping, Sequence

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd

from madpinn.config.vf_variants import FROM
from madpinn.evaluation.metrics import across_seeds
from madpinn.evaluation.paper_rows import paper_safety
from madpinn.evaluation.tables import cell_infeasible_shares, load_results, per_seed
from madpinn.figures import style
from madpinn.figures.frontier import _interval
from madpinn.scenarios import UNIFORM

PAPER_SAMPLES = 65536 * 100000
"""the paper's V̂ recipe (DeepReach practice: 65 536 states × 100 000 iterations)"""
SEED_RANGE_LABEL = "training-seed range"
"""legend entry of a budget's range over training seeds (issue 60 item 3)"""
RECIPE_MARKERS = {"D": "diamond", "P": "plus", "X": "cross", "^": "triangle", "v": "down-triangle"}
"""markers of the recipe variants (issue 61 item 4), in the order of the runs, and their names in the legend text"""
ANNEALED, CONSTANT = "annealed lr", "constant lr (paper's)"
"""the two learning-rate schedules of the budgets: ours (decaying lr → lr_final) and the paper's constant rate"""
SCHEDULE_STYLE = {ANNEALED: dict(fmt="o-", mfc="white"), CONSTANT: dict(fmt="s-.", mfc=None)}
"""marker and line per schedule (mfc None: filled in the line's colour)"""


@dataclass(frozen=True)
class BudgetRun:
    """One V̂ budget: the run that deploys it, its label and its training samples."""

    run: str
    label: str
    samples: int
    """training states seen: batch_size × (iterations + batch_offset) of the model (a fine-tune
    continues its initial model's batch stream, so the offset counts those samples)"""
    schedule: str
    """:data:`ANNEALED` or :data:`CONSTANT` (:func:`model_schedule`): trends are fitted within one"""
    verification: Mapping | None = None
    """the model's ``verify-vhat`` report (ε on uniform and conflict states), when given"""
    replicates: str | None = None
    """the run whose V̂ recipe this one repeats with another training seed (issue 60 item 3): no
    budget of its own, drawn as that budget's training-seed range and left out of the trends"""
    recipe_of: str | None = None
    """the run whose budget and schedule this one keeps with another recipe (e.g. uniform states, issue
    61 item 4): no budget of its own, a labelled marker at its samples, left out of the trends"""

    @property
    def budget(self) -> bool:
        """Whether this run is a point of the budget trends (neither a replicate nor a recipe variant)."""
        return self.replicates is None and self.recipe_of is None


@dataclass(frozen=True)
class BudgetPanel:
    """One panel: the cells of one study and the paper's safety for its own method there."""

    study: str
    title: str
    paper: Mapping[int, float] = field(default_factory=dict)
    """N -> the paper's safety (%) at this setting; empty where the paper reports none"""


def budget_base(variants: Mapping[str, str | None], table: Mapping[str, Mapping]) -> str | None:
    """The run of the reference recipe among ``variants`` (run -> the V̂ variant it loads, None for
    the base V̂; ``table``: ``value_functions.vhat_variants``): the run loading the variant the
    others derive from (``from``), else the run loading the base V̂, else None."""
    named = [table[v].get(FROM) for v in variants.values() if v is not None]
    for run, variant in variants.items():
        if variant is not None and variant in named:
            return run
    return next((run for run, variant in variants.items() if variant is None), None)


def lineage(variant: str | None, table: Mapping[str, Mapping]) -> list[str | None]:
    """``variant`` and the variants it derives from through ``from``, ending at None (the base V̂)."""
    chain = [variant]
    while chain[-1] is not None and len(chain) <= len(table) + 1:
        chain.append(table[chain[-1]].get(FROM))
    return chain


def budget_roles(base: str | None, variants: Mapping[str, str | None], table: Mapping[str, Mapping],
                 budgets: Mapping[str, tuple[int, str]]) -> dict[str, dict[str, str | None]]:
    """Per run (``variants``: run -> its V̂ variant, None for the base V̂; ``table``:
    ``value_functions.vhat_variants``; ``budgets``: run -> its V̂'s (samples, schedule)), the
    :class:`BudgetRun` roles. ``replicates`` names the run whose recipe a variant only reseeds (its
    own entry is a ``seed`` and, optionally, a ``from``: the run loading that ``from`` variant, or the
    base V̂ without one) when that run is among ``variants``: the reference recipe's replicates and
    those of a recipe variant alike (issue 60 item 3: the cs recipe's seeds and the deployed recipe's).
    ``recipe_of`` is set for a run that is not one of ``base``'s budgets: one whose :func:`lineage`
    lacks the base's variant (another recipe at any samples, e.g. the base V̂ with uniform states or a
    4× batch of it, when the base is ``cs``), or one that has it but keeps the base's samples and
    schedule (e.g. ``nocs``); it names the nearest run of the variant's lineage (the 4× batch: the run
    loading the base V̂, whose band it is compared with), else ``base``. Both
    None for a budget (the base and the variants derived from it at other samples or schedules)."""
    reference = variants.get(base) if base is not None else None
    by_variant = {variant: run for run, variant in variants.items()}
    out = {}
    for run, variant in variants.items():
        entry = table[variant] if variant is not None else None
        origin = entry.get(FROM) if entry is not None else None
        reseeded = entry is not None and set(entry) - {FROM} == {"seed"} and by_variant.get(origin, run) != run
        chain = lineage(variant, table)
        derived = run == base or reference in chain
        recipe = (base is not None and run != base and not reseeded
                  and (not derived or budgets[run] == budgets[base]))
        nearest = next((by_variant[v] for v in chain[1:] if v in by_variant and by_variant[v] != run), base)
        out[run] = {"replicates": by_variant[origin] if reseeded else None, "recipe_of": nearest if recipe else None}
    return out


def budget_panel(study: str, arena: str, pattern: str | None, counts: Iterable[int]) -> BudgetPanel:
    """The panel of one study: titled by its setting, with the paper's values where it has any."""
    structured = (pattern or UNIFORM) != UNIFORM
    title = (f"{pattern} conflict, {arena} arena" if structured
             else {"large": "Table II setting", "small": "Table I setting"}.get(arena, f"{arena} arena"))
    return BudgetPanel(study=study, title=title, paper=paper_safety(arena, pattern, counts))


def verification_epsilon(report: Mapping, distribution: str) -> float:
    """ε of any violation (safety or budget) on ``distribution``'s states at the report's smallest β
    (the most conservative bound it gives)."""
    eps = report[distribution]["any"]["epsilon"]
    return float(eps[min(eps, key=float)])


def model_samples(meta: Mapping) -> int:
    """Training samples of a V̂ from its model metadata (``train-value``'s ``meta``)."""
    settings = meta.get("settings") or {}
    if "batch_size" not in settings or "iterations" not in meta:
        raise ValueError("the model's metadata has no batch_size / iterations: not a train-value model")
    return int(settings["batch_size"]) * (int(meta["iterations"]) + int(meta.get("batch_offset", 0)))


def model_schedule(meta: Mapping) -> str:
    """The learning-rate schedule of a V̂ from its model metadata: :data:`CONSTANT` when its (last)
    stage ran at one rate (``lr == lr_final``), else :data:`ANNEALED`."""
    settings = meta.get("settings") or {}
    if "lr" not in settings or "lr_final" not in settings:
        raise ValueError("the model's metadata has no lr / lr_final: not a train-value model")
    return CONSTANT if float(settings["lr"]) == float(settings["lr_final"]) else ANNEALED


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


def study_frames(result_paths: Iterable[str | Path]) -> dict[str, pd.DataFrame]:
    """Per study of the result files: per (run, N) the seed figures' mean and std and, with one seed,
    the bootstrap intervals (:func:`madpinn.evaluation.metrics.across_seeds` columns)."""
    df = load_results(result_paths)
    return {str(st): across_seeds(per_seed(g), ["run", "n_agents"]) for st, g in df.groupby("study", sort=False)}


def schedule_points(group: pd.DataFrame, by_run: Mapping[str, BudgetRun]) -> dict[str, list[tuple[int, pd.Series]]]:
    """The rows of one (study, N), per schedule, sorted by samples: ``{schedule: [(samples, row)]}``."""
    points: dict[str, list[tuple[int, pd.Series]]] = {}
    for _, r in group.iterrows():
        if by_run[r["run"]].budget:   # a replicate (seed_ranges) or a recipe variant is no budget
            points.setdefault(by_run[r["run"]].schedule, []).append((by_run[r["run"]].samples, r))
    return {sched: sorted(pts, key=lambda p: p[0]) for sched, pts in points.items()}


def seed_ranges(group: pd.DataFrame, by_run: Mapping[str, BudgetRun]) -> dict[str, tuple[float, float, int]]:
    """The training-seed range of each budget of one (study, N) that has replicates among the rows:
    ``{base run: (lowest safety %, highest safety %, seeds)}`` over the base and its replicates."""
    safety = {r["run"]: 100 * r["safety_rate_mean"] for _, r in group.iterrows()}
    out = {}
    for base in {by_run[run].replicates for run in safety} - {None}:
        values = [v for run, v in safety.items() if run == base or by_run[run].replicates == base]
        if base in safety and len(values) > 1:
            out[base] = (min(values), max(values), len(values))
    return out


def infeasible_by_cell(result_paths: Iterable[str | Path]) -> dict[tuple[str, str, int], float]:
    """``(study, run, N) -> `` the share of agent-steps with no feasible budget, mean over the seeds of
    the given files (:func:`madpinn.evaluation.tables.cell_infeasible_shares`)."""
    shares = cell_infeasible_shares(result_paths).groupby(["study", "run", "n_agents"])["infeasible"].mean()
    return {(str(st), str(run), int(n)): float(v) for (st, run, n), v in shares.items()}


def range_columns(ranges: Mapping[str, tuple[float, float, int]], run: str) -> dict:
    """The CSV columns of ``run``'s training-seed range (:func:`seed_ranges`): lowest and highest
    safety (%), the seeds, and whose range it is (NaN, 1 and empty where ``run`` has none)."""
    lo, hi, k = ranges.get(run, (math.nan, math.nan, 1))
    return {"seed_range_lo": lo, "seed_range_hi": hi, "seeds": k, "seed_range_of": run if run in ranges else ""}


def role_rank(b: BudgetRun, by_run: Mapping[str, BudgetRun]) -> int:
    """Order of runs at one budget: the budget (0), its training seeds (1), a recipe variant (2), the
    recipe variant's training seeds (3)."""
    if b.replicates is not None:
        return 3 if by_run[b.replicates].recipe_of is not None else 1
    return 2 if b.recipe_of is not None else 0


def budget_table(frames: Mapping[str, pd.DataFrame], runs: Sequence[BudgetRun], panels: Sequence[BudgetPanel],
                 infeasible: Mapping[tuple[str, str, int], float] | None = None) -> pd.DataFrame:
    """Per (study, N, run): samples, schedule, safety (%) with its interval (95 % bootstrap over
    scenarios with one seed, else ± one std over seeds), the infeasible share (``infeasible``:
    :func:`infeasible_by_cell`; NaN where not given) and, per (study, N, schedule), the trend's slope
    (points per decade; NaN with one budget or no paper value) and the samples at which it reaches the
    paper's safety (NaN: never, or no paper value); the V̂'s verification ε where given. A replicate's
    rows read ``training seed of <base>``, a recipe variant's ``recipe variant of <base>`` (with its
    own training-seed range where it has replicates, else its base's; ``seed_range_of`` names whose);
    neither enters a trend."""
    infeasible = infeasible or {}
    by_run = {r.run: r for r in runs}
    rows = []
    for panel in panels:
        for n, group in frames[panel.study].groupby("n_agents"):
            target = panel.paper.get(int(n), math.nan)
            rows_n = []
            ranges = seed_ranges(group, by_run)
            for _, r in group.iterrows():
                b = by_run[r["run"]]
                if b.replicates is not None:
                    lo, hi = _interval(r, "safety_rate", 100.0)
                    safety = 100 * r["safety_rate_mean"]
                    rows_n.append({"study": panel.study, "n_agents": int(n), "run": r["run"], "schedule": f"training seed of {b.replicates}",
                                   "samples": b.samples, "safety": safety, "safety_lo": safety - lo,
                                   "safety_hi": safety + hi, "paper_safety": target})
                elif b.recipe_of is not None:   # beside its base's point and training-seed range, in no trend
                    lo, hi = _interval(r, "safety_rate", 100.0)
                    safety, v = 100 * r["safety_rate_mean"], b.verification
                    rows_n.append({"study": panel.study, "n_agents": int(n), "run": r["run"], "schedule": f"recipe variant of {b.recipe_of}",
                                   "samples": b.samples, "safety": safety, "safety_lo": safety - lo, "safety_hi": safety + hi,
                                   "infeasible": infeasible.get((panel.study, r["run"], int(n)), math.nan), "paper_safety": target,
                                   "eps_uniform": verification_epsilon(v, "uniform") if v else math.nan,
                                   "eps_conflict": verification_epsilon(v, "conflict") if v else math.nan,
                                   **range_columns(ranges, r["run"] if r["run"] in ranges else b.recipe_of)})
            for sched, pts in schedule_points(group, by_run).items():
                xs, ys = [p[0] for p in pts], [100 * r["safety_rate_mean"] for _, r in pts]
                _, slope, needed = (trend(xs, ys, target) if math.isfinite(target) and len(set(xs)) > 1
                                    else (0.0, math.nan, None))
                for (samples, r), safety in zip(pts, ys):
                    v = by_run[r["run"]].verification
                    lo, hi = _interval(r, "safety_rate", 100.0)
                    rows_n.append({"study": panel.study, "n_agents": int(n), "run": r["run"], "schedule": sched,
                                   "samples": samples, "safety": safety, "safety_lo": safety - lo, "safety_hi": safety + hi,
                                   "infeasible": infeasible.get((panel.study, r["run"], int(n)), math.nan),
                                   "paper_safety": target, "slope_per_decade": slope,
                                   "samples_to_paper": needed if needed is not None else math.nan,
                                   "eps_uniform": verification_epsilon(v, "uniform") if v else math.nan,
                                   "eps_conflict": verification_epsilon(v, "conflict") if v else math.nan,
                                   **range_columns(ranges, r["run"])})
            rows += sorted(rows_n, key=lambda row: (row["samples"], role_rank(by_run[row["run"]], by_run)))
    return pd.DataFrame(rows)


def plot_vhat_budget(result_paths: Iterable[str | Path], runs: Sequence[BudgetRun], panels: Sequence[BudgetPanel],
                     out_prefix: str | Path) -> list[Path]:
    """Draw the figure from evaluation result files of ``panels``' studies and ``runs``; writes
    ``<out_prefix>.{pdf,png}`` and ``<out_prefix>.csv`` (:func:`budget_table`); returns the three paths."""
    result_paths = list(result_paths)
    frames = study_frames(result_paths)
    absent = [p.study for p in panels if p.study not in frames]
    if absent:
        raise ValueError(f"no result files of studies {absent}")
    missing = sorted({run for p in panels for run in frames[p.study]["run"]} - {r.run for r in runs})
    if missing:
        raise ValueError(f"no V̂ budget given for runs {missing}")
    table = budget_table(frames, runs, panels, infeasible_by_cell(result_paths))
    out_prefix = Path(out_prefix)
    files = style.save(draw_vhat_budget(frames, runs, panels), out_prefix)
    csv = out_prefix.with_suffix(".csv")
    table.to_csv(csv, index=False, float_format="%.6g")
    return [*files, csv]


def budget_tags(runs: Sequence[BudgetRun]) -> dict[str, str]:
    """Short tag per budget of ``runs``: its samples as a multiple of the base run's (the run the
    recipe variants and replicates refer to; else the run without a variant, e.g. ``madpinn``; else the
    smallest budget), e.g. ``"0.5×"``, ``"3×"``."""
    by_run = {r.run: r for r in runs}
    refs = [r.recipe_of or r.replicates for r in runs if (r.recipe_of or r.replicates) in by_run]
    base_run = next((by_run[ref] for ref in refs if by_run[ref].budget),
                    next((r for r in runs if "-" not in r.run and r.budget), None))
    budgets = [r for r in runs if r.budget]
    base = base_run.samples if base_run is not None else min(r.samples for r in budgets)
    return {r.run: f"{r.samples / base:.3g}×" for r in budgets}


NOTE_CHARS_PER_INCH = 17
"""characters of the 7.5 pt notes under the panels per inch of figure width (their wrap width)"""
RECIPE_OFFSET = 1.12
"""x factor between a recipe variant's marker and its samples (per variant at the same samples), so that
it and its training-seed range stand beside the budget drawn there"""


def drawn_samples(runs: Sequence[BudgetRun]) -> dict[str, float]:
    """Where each run is drawn on the samples axis: a budget at its samples, the k-th recipe variant at
    the same samples at ``samples · RECIPE_OFFSET**k`` (k from 1), a replicate where its run is."""
    x, seen = {}, {}
    for r in runs:
        if r.recipe_of is not None:
            seen[r.samples] = seen.get(r.samples, 0) + 1
            x[r.run] = r.samples * RECIPE_OFFSET ** seen[r.samples]
        elif r.replicates is None:
            x[r.run] = float(r.samples)
    return {**x, **{r.run: x.get(r.replicates, float(r.samples)) for r in runs if r.replicates is not None}}


def draw_vhat_budget(frames: Mapping[str, pd.DataFrame], runs: Sequence[BudgetRun], panels: Sequence[BudgetPanel]) -> plt.Figure:
    """One axis per panel (shared axes), one line per agent count and schedule (marker and line style:
    :data:`SCHEDULE_STYLE`), the paper's values dashed; each budget's tag on the top axis, the tags'
    meaning and each trend's verdict below the panels."""
    style.setup()
    by_run = {r.run: r for r in runs}
    budgets = [r for r in runs if r.budget]
    tags = budget_tags(runs)
    recipes = {r.run: list(RECIPE_MARKERS)[i % len(RECIPE_MARKERS)] for i, r in enumerate(r for r in runs if r.recipe_of is not None)}
    x_of = drawn_samples(runs)

    def name(run: str) -> str:   # a budget by its tag, a recipe variant by its marker
        return tags[run] if run in tags else f"the {RECIPE_MARKERS[recipes[run]]}"

    counts = sorted({int(n) for p in panels for n in frames[p.study]["n_agents"].unique()})
    colours = style.palette([str(n) for n in counts])
    fig, axes = plt.subplots(1, len(panels), figsize=(4.6 * len(panels), 6.4), sharex=True, sharey=True, squeeze=False)
    x_lo, x_hi = min(r.samples for r in runs) / 1.6, PAPER_SAMPLES * 1.6
    xs_line = np.logspace(math.log10(x_lo), math.log10(x_hi), 50)
    notes = []
    for ax, panel in zip(axes[0], panels):
        agg = frames[panel.study]
        for n in sorted(int(n) for n in agg["n_agents"].unique()):
            c = colours[str(n)]
            target = panel.paper.get(n)
            if target is not None:
                ax.axhline(target, ls="--", lw=1.0, color=c)
            for i, (sched, rows) in enumerate(schedule_points(agg[agg["n_agents"] == n], by_run).items()):
                xs = [s for s, _ in rows]
                ys = [100 * r["safety_rate_mean"] for _, r in rows]
                err = np.array([_interval(r, "safety_rate", 100.0) for _, r in rows]).T
                fmt, mfc = SCHEDULE_STYLE[sched]["fmt"], SCHEDULE_STYLE[sched]["mfc"] or c
                ax.errorbar(xs, ys, yerr=err, fmt=fmt, color=c, capsize=2.5, ms=6, mfc=mfc, mew=1.5,
                            label=f"{n} agents" if i == 0 else None)
                if target is None or len(set(xs)) < 2:
                    continue
                a, b, needed = trend(xs, ys, target)
                if b > 0:
                    ax.plot(xs_line, a + b * np.log10(xs_line), ":", lw=1.0, color=c)
                notes.append(f"{panel.title}, {n} agents, {sched}, {len(xs)} budgets: paper {target:.4g} %; "
                             + (f"trend +{b:.1f} pts/decade, reaches it at {needed:.2g} samples" if needed is not None
                                else "no rising trend"))
            for base, (lo, hi, k) in seed_ranges(agg[agg["n_agents"] == n], by_run).items():
                ax.vlines(x_of[base], lo, hi, color=c, lw=7, alpha=0.3, zorder=0, label=SEED_RANGE_LABEL)
                where = name(base) + ("" if base in tags else f" ({by_run[base].label})")
                notes.append(f"{panel.title}, {n} agents: training-seed range at {where}: {lo:.1f}–{hi:.1f} % "
                             f"({k} seeds); a difference smaller than it reads as no effect")
            for _, r in agg[(agg["n_agents"] == n) & agg["run"].isin(list(recipes))].iterrows():
                ax.errorbar([x_of[r["run"]]], [100 * r["safety_rate_mean"]],
                            yerr=np.array([_interval(r, "safety_rate", 100.0)]).T, fmt=recipes[r["run"]], color=c,
                            capsize=2.5, ms=6, mfc="white", mew=1.5, zorder=3)
        ax.axvline(PAPER_SAMPLES, color="0.4", lw=0.8)
        ax.text(PAPER_SAMPLES, 0.55, "paper's recipe ", transform=ax.get_xaxis_transform(), fontsize=7.5, va="center",
                ha="right", rotation=90, color="0.3")
        ax.set_xscale("log")
        ax.set_xlim(x_lo, x_hi)
        top = ax.secondary_xaxis("top")
        top.set_xticks([r.samples for r in budgets], [tags[r.run] for r in budgets], fontsize=7.5)
        top.tick_params(axis="x", which="minor", top=False, labeltop=False)
        ax.set_title(panel.title + ("" if panel.paper else " (no paper value)"), fontsize=10, pad=16)
        ax.set_xlabel("V̂ training samples (batch × iterations)")
        schedules = [s for s in SCHEDULE_STYLE if s in {r.schedule for r in runs}]
        drawn = dict(zip(*reversed(ax.get_legend_handles_labels())))   # label -> handle, one seed-range entry
        handles = list(drawn.values()) + [
            plt.Line2D([], [], color="0.3", marker=SCHEDULE_STYLE[s]["fmt"][0], ls=SCHEDULE_STYLE[s]["fmt"][1:],
                       mfc=SCHEDULE_STYLE[s]["mfc"] or "0.3", label=s) for s in schedules] + [
            plt.Line2D([], [], color="0.3", marker=m, ls="none", mfc="white", label=by_run[run].label)
            for run, m in recipes.items() if run in set(agg["run"])]
        ax.legend(handles=handles, loc="upper center", bbox_to_anchor=(0.5, -0.15), ncol=1, fontsize=7.5, frameon=False)
    axes[0][0].set_ylabel("safety rate (%)")
    axes[0][0].set_ylim(top=101)
    legend = "; ".join(f"{tags[r.run]} = {r.label}" for r in sorted(budgets, key=lambda r: r.samples))
    replicas = [f"{r.label} (training seed of {name(r.replicates)})" for r in runs if r.replicates is not None]
    replicas += [f"{r.label} ({RECIPE_MARKERS[recipes[r.run]]}, drawn just right of its samples: "
                 + (f"the recipe of {name(r.recipe_of)} changed at its budget)" if (r.samples, r.schedule) == (by_run[r.recipe_of].samples, by_run[r.recipe_of].schedule)
                    else f"the recipe of {name(r.recipe_of)} at other samples; no budget)")
                 for r in runs if r.recipe_of is not None]
    if replicas:
        legend += "; " + ", ".join(replicas)
    width = int(NOTE_CHARS_PER_INCH * fig.get_figwidth())   # wrapped to the figure's width
    lines = [part for line in [f"Top axis: {legend}", *notes] for part in textwrap.wrap(line, width, subsequent_indent="   ")]
    fig.tight_layout()   # the legends under the panels are inside the layout; the notes go below them
    renderer = fig.canvas.get_renderer()
    bottom = min(ax.get_legend().get_window_extent(renderer).y0 for ax in axes[0]) / fig.bbox.height
    fig.text(0.01, bottom - 0.02, "\n".join(lines), fontsize=7.5, va="top")
    return fig
