"""V̂'s recipe re-chosen on validation seeds (issue 61 item 4), by the rule fixed before its cells
(:data:`PLAN`). The shipped recipe has two components the paper does not state: F, a second,
fine-tuning stage, and C, conflict sampling. Per cell (study, N) the **training band** is [min, max]
of the safety rate over the base recipe and its training-seed replicates; the model −X lacks X:

- X is *needed* when −X lies below the band's minimum by ≥ ``margin_points`` in ≥ ``quorum``
  deciding cells and above its maximum by that much in none; *harmful* the other way round;
  otherwise *indistinguishable from training variance*;
- the action each verdict fixes (:data:`ACTIONS`): F is kept unless harmful (−F trains on half the
  samples); C is kept only if needed, else the paper's uniform states are adopted.

A band missing a configured replicate's cells is *degenerate*: the verdict is computed over the
models present and marked provisional (the plan's last section). Safety is the mean scenario
safety rate, scenarios pooled over the cell's seeds; intervals are 95 % bootstraps over scenarios
(shown, not judged).
"""

from __future__ import annotations

import pandas as pd

from madpinn.evaluation.metrics import bootstrap_interval
from madpinn.evaluation.recipe_settings import RecipeSettings

PLAN = "docs/findings/2026-11-29-vhat-recipe-preregistered.md"
"""the rule, fixed before any of its cells ran"""
FIRST_CHOICE = "docs/findings/2026-11-21-vhat-training-results.md"
"""where the recipe was first chosen, on protocol seeds 0 and 1"""
NEEDED, HARMFUL, INDISTINGUISHABLE = "needed", "harmful", "indistinguishable from training variance"
COMPONENTS = {"F": "the fine-tuning stage", "C": "conflict sampling"}
"""the recipe's components the rule judges"""
ACTIONS = {
    "F": {NEEDED: "kept", INDISTINGUISHABLE: "kept", HARMFUL: "dropped"},
    "C": {NEEDED: "kept", INDISTINGUISHABLE: "replaced by the paper's uniform states",
          HARMFUL: "replaced by the paper's uniform states"},
}
"""component -> verdict -> what the rule fixes (the plan's "What follows")"""
TOLERANCE = 1e-9
"""points: a gap equal to the margin counts as reaching it, whatever the float rounding"""


def cell_safety(frame: pd.DataFrame) -> pd.DataFrame:
    """One row per (study, n_agents, run) of scenario rows ``frame``: ``safety`` (%), its 95 %
    bootstrap interval ``safety_lo`` / ``safety_hi``, ``scenarios`` and ``seeds`` (space-separated)."""
    g = frame.groupby(["study", "n_agents", "run"], sort=False)
    out = g["safety_rate"].agg(safety="mean", scenarios="size")
    out["safety"] *= 100.0
    ci = g["safety_rate"].apply(lambda v: bootstrap_interval(v.to_numpy(dtype=float)))
    out["safety_lo"], out["safety_hi"] = 100.0 * ci.str[0], 100.0 * ci.str[1]
    out["seeds"] = g["seed"].agg(lambda s: " ".join(map(str, sorted(set(map(int, s))))))
    out = out.reset_index()
    out["n_agents"] = out["n_agents"].astype(int)
    return out


def _cells(settings: RecipeSettings) -> pd.DataFrame:
    rows = [(st, n, "deciding") for st, n in settings.deciding] + [(st, n, "reported") for st, n in settings.reported]
    return pd.DataFrame(rows, columns=["study", "n_agents", "role"])


def _cell_safety_table(safety: pd.DataFrame, settings: RecipeSettings, runs: list[str]) -> pd.DataFrame:
    """One row per configured cell (:func:`_cells`) with a column per run of ``runs``: its safety (%),
    NaN where its cell is absent."""
    wide = safety.pivot_table(index=["study", "n_agents"], columns="run", values="safety", aggfunc="first")
    return _cells(settings).join(wide.reindex(columns=runs), on=["study", "n_agents"])


def judge_cells(safety: pd.DataFrame, settings: RecipeSettings) -> pd.DataFrame:
    """One row per configured cell (deciding first, then reported): the band over the base and the
    replicates present (``band_lo``, ``band_hi``, ``band_runs``), each model's safety (column = run;
    NaN where its cell is absent) and per component X: ``below_X`` / ``above_X`` (−X beyond the band by
    ≥ the margin; False where −X or the band is absent)."""
    table = _cell_safety_table(safety, settings, [*settings.band_runs, *settings.components.values()])
    band = table[list(settings.band_runs)]
    table["band_lo"], table["band_hi"] = band.min(axis=1), band.max(axis=1)
    table["band_runs"] = band.notna().apply(lambda r: " ".join(r.index[r.to_numpy(dtype=bool)]), axis=1)
    for x, run in settings.components.items():
        table[f"below_{x}"] = (table["band_lo"] - table[run]) >= settings.margin_points - TOLERANCE
        table[f"above_{x}"] = (table[run] - table["band_hi"]) >= settings.margin_points - TOLERANCE
    return table


def adopted_band(safety: pd.DataFrame, settings: RecipeSettings) -> dict | None:
    """The adopted recipe's training band per configured cell (deciding nothing; issue 60 item 3):
    ``{"runs": [...], "cells": [{study, n_agents, role, lo, hi, mean, models, safety: {run: %}}]}`` over
    the runs of ``settings.adopted_band`` with cells there (a cell with none is left out); None when
    the section names no such runs."""
    if not settings.adopted_band:
        return None
    runs = list(settings.adopted_band)
    table = _cell_safety_table(safety, settings, runs)
    cells = []
    for r in table.to_dict("records"):
        values = {run: float(r[run]) for run in runs if pd.notna(r[run])}
        if values:
            v = list(values.values())
            cells.append({"study": r["study"], "n_agents": int(r["n_agents"]), "role": r["role"], "lo": min(v), "hi": max(v),
                          "mean": sum(v) / len(v), "models": len(v), "safety": values})
    return {"runs": runs, "cells": cells}


def adopted_band_text(band: dict) -> str:
    """``the adopted recipe's training band (madpinn, …): vhat_budget N=64 60.9–68.4 % (3 models), …``."""
    cells = "; ".join(f"{c['study']} N={c['n_agents']} {c['lo']:.1f}–{c['hi']:.1f} % ({c['models']} models)" for c in band["cells"])
    return f"the adopted recipe's training band over {', '.join(band['runs'])}, deciding nothing: {cells}"


def component_verdict(below: int, above: int, quorum: int) -> str:
    """The rule on one component's counts over the deciding cells."""
    if below >= quorum and above == 0:
        return NEEDED
    if above >= quorum and below == 0:
        return HARMFUL
    return INDISTINGUISHABLE


def _require(table: pd.DataFrame, settings: RecipeSettings) -> list[str]:
    """Fail on deciding cells the rule cannot read; return the replicates missing somewhere (degenerate band)."""
    deciding = table[table["role"] == "deciding"]
    needed = [settings.base, *settings.components.values()]
    absent = [f"{st} N={n} {run}" for st, n, row in zip(deciding["study"], deciding["n_agents"], deciding[needed].itertuples(index=False))
              for run, v in zip(needed, row) if pd.isna(v)]
    if absent:
        raise ValueError(f"the rule cannot read deciding cells without these models' cells: {absent}")
    alone = deciding[deciding[list(settings.replicates)].isna().all(axis=1)]
    if len(alone):
        raise ValueError("no training-seed replicate has a cell at " + ", ".join(f"{s} N={n}" for s, n in zip(alone["study"], alone["n_agents"]))
                         + ": no training band")
    return [r for r in settings.replicates if deciding[r].isna().any()]


def choose(safety: pd.DataFrame, settings: RecipeSettings) -> tuple[pd.DataFrame, dict]:
    """The judged cells (:func:`judge_cells`) and the choice: ``{"components": {X: {run, verdict,
    action, below, above}}, "provisional", "missing_replicates", "band_runs", "deciding", "reported",
    "seeds", "margin_points", "quorum", "rule", "adopted_band"}`` (the last: :func:`adopted_band`). Protocol seeds (< 100) and cells of studies outside
    the section are refused."""
    protocol = sorted({int(s) for seeds in safety["seeds"] for s in str(seeds).split() if int(s) < 100})
    if protocol:
        raise ValueError(f"cells on protocol seeds {protocol}: the recipe is re-chosen on validation seeds (≥ 100) only")
    outside = sorted(set(safety["study"]) - {st for st, _ in (*settings.deciding, *settings.reported)})
    if outside:
        raise ValueError(f"cells of studies outside vhat_recipe: {outside}")
    table = judge_cells(safety, settings)
    missing = _require(table, settings)
    deciding = table[table["role"] == "deciding"]
    components = {}
    for x, run in settings.components.items():
        below, above = int(deciding[f"below_{x}"].sum()), int(deciding[f"above_{x}"].sum())
        verdict = component_verdict(below, above, settings.quorum)
        components[x] = {"component": COMPONENTS[x], "run": run, "verdict": verdict, "action": ACTIONS[x][verdict],
                         "below": below, "above": above}
    used = safety.merge(deciding[["study", "n_agents"]], on=["study", "n_agents"])
    seeds = sorted({int(s) for v in used["seeds"] for s in str(v).split()})
    cells = lambda t: [{"study": s, "n_agents": int(n)} for s, n in zip(t["study"], t["n_agents"])]   # noqa: E731
    return table, {"components": components, "provisional": bool(missing), "missing_replicates": missing,
                   "band_runs": [settings.base, *[r for r in settings.replicates if r not in missing]],
                   "deciding": cells(deciding), "reported": cells(table[table["role"] == "reported"]), "seeds": seeds,
                   "margin_points": settings.margin_points, "quorum": settings.quorum, "rule": PLAN,
                   "adopted_band": adopted_band(safety, settings)}


def cells_text(cells: list[dict]) -> str:
    """``vhat_budget_small at 12 and 16 agents, vhat_budget_circle at 16 agents``."""
    by_study: dict[str, list[int]] = {}
    for c in cells:
        by_study.setdefault(c["study"], []).append(int(c["n_agents"]))
    join = lambda ns: ", ".join(map(str, ns[:-1])) + " and " + str(ns[-1]) if len(ns) > 1 else str(ns[0])   # noqa: E731
    return ", ".join(f"{st} at {join(ns)} agents" for st, ns in by_study.items())


def choice_sentence(choice: dict) -> str:
    """What was chosen, where, on which seeds, by which rule: the claims page's seed-provenance line."""
    parts = [f"{c['component']} ({x}) is {c['verdict']}, so {c['action']}" for x, c in choice["components"].items()]
    seeds = ", ".join(map(str, choice["seeds"]))
    text = (f"the V̂ recipe was re-chosen on validation seed{'s' if len(choice['seeds']) > 1 else ''} {seeds} "
            f"({cells_text(choice['deciding'])}) by the rule fixed before its cells ({choice['rule']}): "
            + "; ".join(parts) + f"; band over {', '.join(choice['band_runs'])}")
    if choice["provisional"]:
        text += (f" (provisional: {', '.join(choice['missing_replicates'])} without cells, a degenerate band; "
                 "re-read when they exist)")
    text += f". First chosen on protocol seeds 0 and 1 ({FIRST_CHOICE})"
    return text + (f". Since: {adopted_band_text(choice['adopted_band'])}" if choice.get("adopted_band") else "")

