"""The calibrated level in closed loop (issue 62, not in the paper): ``conformal.{csv,md,html,json}``
and ``speed_gap.csv`` from the cells of the studies whose runs deploy a calibrated level δ
(:class:`madpinn.evaluation.conformal_settings.ConformalSettings`) and the calibrate-vhat report.

- **Cells.** Per study, run and N: safety [95 % CI], safe scenarios and cost ÷T [95 % CI], and the
  paired difference against V̂ alone (δ = 0, ``madpinn``) on the same scenarios
  (:func:`madpinn.evaluation.paired_effects.paired_effects`).
- **The sentence the issue asks for.** Where the paper gives a row (Table I in the small arena,
  Table II in the large one), does some calibrated level reach the paper's safety less
  :data:`madpinn.evaluation.table_ii_readings.SCALE`'s 2 points where V̂ alone does not, and at
  what cost against V̂ alone and against the hand-tuned rows beside it?
- **What the guarantee covers.** The level bounds the violation rate of one accepted state of V̂'s
  own model (three agents, double integrators, one horizon of 0.2 s) by ε with confidence 1 − β.
  The crowd in MuJoCo is another event: the closest closed-loop reading is the share of agents
  that collided among those whose encounter speed (relative speed to the nearest agent at the first
  collision, else at the closest approach) lies in each of the calibration's closing-speed bins.
  The relative speed bounds the closing rate from above, so an agent can land in a higher bin than
  its state would. Both are shown per bin beside the level's ε, δ and held-out rate.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Iterable, Mapping

import numpy as np
import pandas as pd

from madpinn.evaluation.conformal_settings import REFERENCE_RUN, ConformalSettings, LevelRun
from madpinn.evaluation.encounter_hazard import hazard_by_speed
from madpinn.evaluation.paired_effects import paired_effects
from madpinn.evaluation.paper_rows import paper_safety
from madpinn.evaluation.table_ii_readings import SCALE, reading_rows
from madpinn.evaluation.tables import load_results, to_markdown
from madpinn.value_functions.safety_level import bin_labels


def load_frame(result_paths: Iterable[str | Path], settings: ConformalSettings) -> pd.DataFrame:
    """Scenario rows of the given cells (the page's studies only), each with its study's ``pattern``."""
    from madpinn.config import TargetError

    df = load_results(result_paths)
    unknown = sorted(set(df["study"]) - set(settings.studies))
    if unknown:
        raise TargetError(f"cells of studies without a calibrated level: {unknown} (the page reads {list(settings.studies)})")
    df["pattern"] = df["study"].map(settings.patterns)
    return df


def cell_rows(frame: pd.DataFrame, settings: ConformalSettings) -> pd.DataFrame:
    """One row per (study, run, N) at the episode's end: safety, its interval, safe scenarios, cost ÷T
    and its interval, the paper's safety where it has a row (NaN elsewhere), and the paired Δ
    against V̂ alone (``d_*``; NaN for V̂ alone itself)."""
    rows = reading_rows(frame)
    rows = rows[rows["horizon_s"] == rows.groupby(["study", "run", "n_agents"])["horizon_s"].transform("max")]
    rows = rows.drop(columns=["horizon_s"]).reset_index(drop=True)
    paper = {s: paper_safety(settings.arenas[s], settings.patterns[s], rows.loc[rows["study"] == s, "n_agents"].unique())
             for s in settings.studies}
    rows["paper_safety"] = [paper.get(s, {}).get(int(n), np.nan) / 100 for s, n in zip(rows["study"], rows["n_agents"])]
    effects = paired_effects(frame, REFERENCE_RUN).drop(columns=["reference", "pattern", "pairs", "safety_pairs", "cost_time_avg_pairs"])
    rows = rows.merge(effects, on=["study", "run", "n_agents"], how="left")
    for c in [c for c in rows if c.startswith("d_")]:
        rows[c] = rows[c].astype(float)
    order = {r: i for i, r in enumerate((REFERENCE_RUN, *(lv.run for lv in settings.levels), *settings.others))}
    study_order = {s: i for i, s in enumerate(settings.studies)}
    rank = rows["study"].map(study_order).fillna(len(study_order)) * 1e6 + rows["n_agents"] * 1e2 + rows["run"].map(order).fillna(len(order))
    return rows.iloc[np.argsort(rank.to_numpy(), kind="stable")].reset_index(drop=True)


def _level_rows(report: Mapping | None, level: LevelRun) -> dict[str, Mapping]:
    """bin label -> the report's entry (δ, held-out rate) that the level run deploys there."""
    if not report:
        return {}
    block = report["distributions"].get(level.distribution, {})
    entries = [e for e in block.get("binned" if level.binned else "pooled", [])
               if np.isclose(e["epsilon"], level.epsilon) and np.isclose(e["beta"], level.beta)]
    return {e["bin_label"]: e for e in entries}


def _deployed_delta(entry: Mapping | None) -> float:
    """The δ a level run deploys from its report entry: NaN without a report, +∞ where the calibration
    certified no level (that bin then accepts no state: :func:`madpinn.value_functions.safety_level.read_level`)."""
    if entry is None:
        return float("nan")
    return float("inf") if entry.get("delta") is None else float(entry["delta"])


def speed_gap(frame: pd.DataFrame, settings: ConformalSettings, report: Mapping | None) -> pd.DataFrame:
    """One row per (study, run, closing-speed bin) of V̂ alone and each level run: the closed-loop
    share of agents that collided among those whose encounter speed lies in the bin [95 % Wilson],
    beside the level's ε, the δ it deploys there and the calibration's held-out violation rate and
    bound (its bin's for a binned level, the pooled figure for a pooled one; blank without a report)."""
    labels = bin_labels(settings.speed_edges)
    edges = (0.0, *settings.speed_edges)
    out = []
    for level in (None, *settings.levels):
        run = REFERENCE_RUN if level is None else level.run
        entries = _level_rows(report, level) if level else {}
        for study, g in frame[frame["run"] == run].groupby("study", sort=False):
            for label, r in zip(labels, hazard_by_speed(g, edges, settings.collision_radius).itertuples()):
                e = entries.get(label) or (next(iter(entries.values())) if entries and not level.binned else None)
                test = (e or {}).get("test", {})
                out.append({"study": study, "run": run, "bin": label, "agents": r.agents, "collided": r.collided,
                            "share": r.hazard, "share_lo": r.low, "share_hi": r.high,
                            "epsilon": level.epsilon if level else np.nan,
                            "delta": 0.0 if level is None else _deployed_delta(e),
                            "heldout_rate": test.get("rate", np.nan) if test.get("accepted") else np.nan,
                            "heldout_bound": test.get("upper_bound", np.nan) if test.get("accepted") else np.nan})
    return pd.DataFrame(out)


def uncertified_runs(gap: pd.DataFrame) -> frozenset[str]:
    """The level runs of :func:`speed_gap`'s frame whose calibration certified no finite δ in any bin
    (each accepts no state of V̂: every agent takes the infeasible branch at every step)."""
    if not len(gap):
        return frozenset()
    finite = gap.assign(finite=np.isfinite(gap["delta"].to_numpy(dtype=float)) | gap["delta"].isna())
    return frozenset(r for r, g in finite.groupby("run") if r != REFERENCE_RUN and not g["finite"].any())


def verdict(rows: pd.DataFrame, settings: ConformalSettings, uncertified: frozenset[str] = frozenset()) -> dict:
    """Per cell with a paper row: V̂ alone, the safest level run and the hand-tuned rows, whether each
    reaches the paper's safety less 2 points; and the sentence: where a level reaches it and V̂ alone
    does not, at what cost (Δ cost ÷T against V̂ alone) beside the hand-tuned rows' cost there.
    ``uncertified`` (:func:`uncertified_runs`): level runs named as such in the sentence."""
    line = SCALE.safety_points
    cells, newly = [], []
    levels = {lv.run for lv in settings.levels}
    for (study, n), g in rows[np.isfinite(rows["paper_safety"])].groupby(["study", "n_agents"], sort=False):
        g = g.set_index("run")
        if REFERENCE_RUN not in g.index:
            continue
        paper = float(g["paper_safety"].iloc[0])
        lv = g[g.index.isin(levels)]
        best = lv["safety"].idxmax() if len(lv) else None
        reach = lambda r: bool(g.at[r, "safety"] >= paper - line - 1e-12)   # noqa: E731
        cell = {"study": study, "n_agents": int(n), "paper_safety": paper, "line": paper - line,
                "alone": float(g.at[REFERENCE_RUN, "safety"]), "alone_reaches": reach(REFERENCE_RUN),
                "best_level": best, "best_safety": float(g.at[best, "safety"]) if best else np.nan,
                "best_reaches": reach(best) if best else False,
                "best_d_cost": float(g.at[best, "d_cost_time_avg"]) if best else np.nan,
                "others": {r: {"safety": float(g.at[r, "safety"]), "reaches": reach(r), "d_cost": float(g.at[r, "d_cost_time_avg"])}
                           for r in settings.others if r in g.index}}
        cells.append(cell)
        if cell["best_reaches"] and not cell["alone_reaches"]:
            newly.append(cell)
    if not cells:
        sentence = "No cell with a paper row (Table I's or Table II's setting) among these studies."
    elif not newly:
        sentence = (f"No calibrated level reaches the paper's safety (less {100 * line:g} points) in a cell where V̂ alone "
                    f"does not ({len(cells)} cells with a paper row).")
    else:
        parts = []
        for c in newly:
            gov = "; ".join(f"{settings.labels.get(r, r)} {100 * o['safety']:.1f} % at Δ cost ÷T {o['d_cost']:+.2f}"
                            for r, o in c["others"].items())
            never = " [no level certified: V̂ never trusted]" if c["best_level"] in uncertified else ""
            parts.append(f"{c['study']} N={c['n_agents']}: {settings.labels.get(c['best_level'], c['best_level'])}{never} "
                         f"{100 * c['best_safety']:.1f} % against V̂ alone {100 * c['alone']:.1f} % (line {100 * c['line']:.2f} %), "
                         f"Δ cost ÷T {c['best_d_cost']:+.2f}" + (f" (beside it: {gov})" if gov else ""))
        what = ("A level run (a calibrated level, or V̂ never trusted where none was certified)"
                if any(c["best_level"] in uncertified for c in newly) else "A calibrated level")
        sentence = (f"{what} reaches the paper's safety (less {100 * line:g} points) where V̂ alone does not in "
                    f"{len(newly)} of {len(cells)} cells with a paper row: " + "; ".join(parts) + ".")
    return {"sentence": sentence, "cells": cells, "line_points": 100 * line, "adopted": adopted_level(rows, settings)}


def adopted_level(rows: pd.DataFrame, settings: ConformalSettings) -> dict:
    """The level run the protocol adopts as its labelled row (issue 62 item 3), by the rule written
    before the closed-loop cells ran (docs/findings/2026-11-28-vhat-calibration.md, "Adoption rule"):
    over the cells with a paper row, the level run that (1) reaches the paper's safety less 2 points
    in the most cells, then (2) has the highest mean safety there, then (3) the lowest mean Δ cost ÷T
    against V̂ alone, then (4) the largest ε (the least tightening). ``beats_alone``: it reaches the
    line in more cells than V̂ alone. ``run`` None when no level run has a cell with a paper row."""
    line = SCALE.safety_points
    paper = rows[np.isfinite(rows["paper_safety"])]
    reach = paper["safety"] >= paper["paper_safety"] - line - 1e-12
    eps = {lv.run: lv.epsilon for lv in settings.levels}
    scored = []
    for run in eps:
        g, r = paper[paper["run"] == run], reach[paper["run"] == run]
        if len(g):
            scored.append({"run": run, "epsilon": eps[run], "cells": int(len(g)), "reaches": int(r.sum()),
                           "mean_safety": float(g["safety"].mean()), "mean_d_cost": float(g["d_cost_time_avg"].mean())})
    alone = int(reach[paper["run"] == REFERENCE_RUN].sum())
    if not scored:
        return {"run": None, "alone_reaches": alone, "beats_alone": False, "candidates": []}
    key = lambda c: (-c["reaches"], -c["mean_safety"], c["mean_d_cost"], -c["epsilon"])   # noqa: E731
    scored.sort(key=key)
    best = scored[0]
    return {"run": best["run"], "epsilon": best["epsilon"], "reaches": best["reaches"], "cells": best["cells"],
            "alone_reaches": alone, "beats_alone": best["reaches"] > alone, "candidates": scored}


def adopted_caveats(adopted: Mapping, rows: pd.DataFrame, uncertified: frozenset[str]) -> dict:
    """What the adoption rule weighs only as a tie-break, for the adopted run: ``cost_ratio``, its mean
    cost ÷T over the cells with a paper row against V̂ alone's on the same cells, and ``certified``,
    False where its calibration certified no finite δ (:func:`uncertified_runs`). Empty without an
    adopted run."""
    run = adopted.get("run")
    if run is None:
        return {}
    paper = rows[np.isfinite(rows["paper_safety"])]
    own, alone = paper[paper["run"] == run], paper[paper["run"] == REFERENCE_RUN]
    pairs = own.merge(alone, on=["study", "n_agents"], suffixes=("", "_alone"))
    ratio = float(pairs["cost_time_avg"].mean() / pairs["cost_time_avg_alone"].mean()) if len(pairs) else float("nan")
    return {"cost_ratio": ratio, "certified": run not in uncertified}


def _pct(x) -> str:
    return "–" if x is None or not np.isfinite(x) else f"{100 * x:.1f}"


def cells_display(rows: pd.DataFrame, settings: ConformalSettings) -> pd.DataFrame:
    out = []
    for r in rows.itertuples():
        paired = "–" if not np.isfinite(r.d_safety) else (
            f"{100 * r.d_safety:+.1f} [{100 * r.d_safety_lo:+.1f}, {100 * r.d_safety_hi:+.1f}] / "
            f"{r.d_cost_time_avg:+.2f} [{r.d_cost_time_avg_lo:+.2f}, {r.d_cost_time_avg_hi:+.2f}]")
        out.append({"study": f"{r.study} ({r.pattern})", "N": r.n_agents, "run": settings.labels.get(r.run, r.run),
                    "safety % [95 % CI]": f"{_pct(r.safety)} [{_pct(r.safety_lo)}, {_pct(r.safety_hi)}]",
                    "paper %": _pct(r.paper_safety), "safe sc. %": _pct(r.safe_scenarios),
                    "cost ÷T [95 % CI]": f"{r.cost_time_avg:.2f} [{r.cost_time_avg_lo:.2f}, {r.cost_time_avg_hi:.2f}]",
                    "Δ safety pts / Δ cost ÷T vs V̂ alone": paired, "scenarios": r.scenarios})
    return pd.DataFrame(out)


def gap_display(gap: pd.DataFrame, settings: ConformalSettings) -> pd.DataFrame:
    fmt = lambda x, d=3: "∞ (none certified)" if x == np.inf else "–" if not np.isfinite(x) else f"{x:.{d}f}"   # noqa: E731
    return pd.DataFrame({
        "study": gap["study"], "run": [settings.labels.get(r, r) for r in gap["run"]], "closing speed": gap["bin"],
        "agents": gap["agents"], "collided share [95 % Wilson]":
            ["–" if not a else f"{s:.3f} [{lo:.3f}, {hi:.3f}]" for a, s, lo, hi in zip(gap["agents"], gap["share"], gap["share_lo"], gap["share_hi"])],
        "ε": [fmt(e, 2) for e in gap["epsilon"]], "δ": [fmt(d) for d in gap["delta"]],
        "held-out rate / bound": [f"{fmt(r)} / {fmt(b)}" for r, b in zip(gap["heldout_rate"], gap["heldout_bound"])],
    })


def _adopted_text(a: Mapping, settings: ConformalSettings) -> str:
    if a["run"] is None:
        return "None: no level run has a cell with a paper row."
    how = ("it reaches the line in more cells than V̂ alone" if a["beats_alone"] else
           "it reaches the line in no more cells than V̂ alone: the row is reported, it does not close the gap")
    text = (f"**{settings.labels.get(a['run'], a['run'])}** (`{a['run']}`): the paper's safety less the line in "
            f"{a['reaches']} of {a['cells']} cells with a paper row (V̂ alone: {a['alone_reaches']}); {how}. The rule, fixed "
            "before these cells: most cells at the line, then the highest mean safety there, then the lowest mean Δ cost ÷T, "
            "then the largest ε.")
    if np.isfinite(a.get("cost_ratio", np.nan)):
        text += f" Its cost ÷T over those cells is {a['cost_ratio']:.1f}× V̂ alone's (cost enters the rule only as a tie-break)."
    if a.get("certified") is False:
        text += (" Its calibration certified no level anywhere (δ = ∞ in every bin): it accepts no state of V̂, so every "
                 "agent takes the infeasible branch (∇V̂ at z_max) at every step. The rule adopts the most conservative "
                 "deployment, not a calibrated level; the row is reported as such.")
    return text


def write_conformal_page(frame: pd.DataFrame, settings: ConformalSettings, report: Mapping | None,
                         out_dir: str | Path) -> tuple[list[Path], pd.DataFrame]:
    """Write ``conformal.csv`` (one row per study, run and N), ``speed_gap.csv``, ``conformal.json``
    (the sentence and its cells), ``conformal.md`` and ``conformal.html``; returns (paths, the cell rows)."""
    from madpinn.evaluation.html import markdown_page

    rows = cell_rows(frame, settings)
    gap = speed_gap(frame, settings, report)
    never = uncertified_runs(gap) if report else frozenset()
    v = verdict(rows, settings, never)
    v["adopted"].update(adopted_caveats(v["adopted"], rows, never))
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    csv, gap_csv, js, md, html = (out / n for n in ("conformal.csv", "speed_gap.csv", "conformal.json", "conformal.md", "conformal.html"))
    rows.to_csv(csv, index=False)
    gap.to_csv(gap_csv, index=False)
    js.write_text(json.dumps(v, indent=2, sort_keys=True, default=float) + "\n")
    text = [
        "# V̂ with a calibrated safety level δ, in closed loop (issue 62; not in the paper)", "",
        f"**{v['sentence']}**", "",
        "Each level run deploys the δ that calibrate-vhat certified for its ε and β on V̂'s own model; V̂ alone is δ = 0 "
        "(the paper's deployment). The paper's safety is Table I's (small arena) or Table II's (large arena) row of its "
        f"own method; a run reaches it at its safety ≥ the paper's − {v['line_points']:g} points (issue 60's scale). "
        "Paired differences are against V̂ alone on the same scenarios (95 % paired bootstrap); validation seeds only.", "",
        "## The level the protocol adopts", "", _adopted_text(v["adopted"], settings), "",
        "## Cells", "", to_markdown(cells_display(rows, settings)), "",
        "## What the guarantee covers, and the gap", "",
        "The level bounds one accepted state of V̂'s model (three agents, double integrators, V̂'s horizon) by ε with "
        "confidence 1 − β; the held-out rate checks it on states the calibration never saw. The crowd in MuJoCo is "
        "another event: below, the share of agents that collided among those whose encounter speed (relative speed to "
        "the nearest agent at the first collision, else at the closest approach; an upper bound of the closing rate) "
        "falls in each of the calibration's closing-speed bins.", "",
        to_markdown(gap_display(gap, settings)) if len(gap) else "No cells.", "",
    ]
    md.write_text("\n".join(text))
    html.write_text(markdown_page(md.read_text(), "conformal"))
    return [csv, gap_csv, js, md, html], rows
