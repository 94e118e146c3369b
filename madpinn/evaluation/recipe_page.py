"""The recipe page (issue 61 item 4): ``vhat_recipe.{md,json,csv}`` from the cells of
``vhat_recipe``'s studies (:mod:`madpinn.evaluation.recipe_choice` judges, this module writes)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Iterable

import pandas as pd

from madpinn.evaluation.recipe_choice import COMPONENTS, cell_safety, cells_text, choice_sentence, choose
from madpinn.evaluation.recipe_settings import RecipeSettings
from madpinn.evaluation.tables import load_results, to_markdown


def _models(settings: RecipeSettings) -> dict[str, str]:
    """run -> its name in the rule: base, s1 … (replicates), −F, −C."""
    return {settings.base: "base", **{r: f"s{i}" for i, r in enumerate(settings.replicates, 1)},
            **{run: f"−{x}" for x, run in settings.components.items()}}


def long_rows(table: pd.DataFrame, safety: pd.DataFrame, settings: RecipeSettings) -> pd.DataFrame:
    """The CSV: one row per (cell, model) present, with the cell's band and, for −X, whether it lies
    below / above the band by the margin."""
    model = _models(settings)
    rows = safety[safety["run"].isin(list(model))].merge(
        table[["study", "n_agents", "role", "band_lo", "band_hi", "band_runs"]], on=["study", "n_agents"])
    rows.insert(3, "model", rows["run"].map(model))
    comp = {run: x for x, run in settings.components.items()}
    marks = table.set_index(["study", "n_agents"])
    for side in ("below", "above"):
        rows[f"{side}_band"] = [marks.at[(st, n), f"{side}_{comp[run]}"] if run in comp else pd.NA
                                for st, n, run in zip(rows["study"], rows["n_agents"], rows["run"])]
    order = {(st, n): i for i, (st, n) in enumerate(zip(table["study"], table["n_agents"]))}
    rows["_o"] = [(order[(st, n)], list(model).index(run)) for st, n, run in zip(rows["study"], rows["n_agents"], rows["run"])]
    return rows.sort_values("_o").drop(columns="_o").reset_index(drop=True)


def cells_display(table: pd.DataFrame, role: str, settings: RecipeSettings) -> pd.DataFrame:
    """Per cell: the band and each model's safety %, −X marked ▼ (below the band by the margin) or ▲ (above)."""
    model = _models(settings)
    comp = {run: x for x, run in settings.components.items()}
    out = []
    for r in table[table["role"] == role].to_dict("records"):
        row = {"cell": f"{r['study']} N={r['n_agents']}",
               "band %": "–" if pd.isna(r["band_lo"]) else f"{r['band_lo']:.1f}–{r['band_hi']:.1f} ({r['band_runs'].count(' ') + 1} models)"}
        for run, name in model.items():
            v = r[run]
            mark = ("▼" if r[f"below_{comp[run]}"] else "▲" if r[f"above_{comp[run]}"] else "") if run in comp else ""
            row[name] = "–" if pd.isna(v) else f"{v:.1f}{' ' + mark if mark else ''}"
        out.append(row)
    return pd.DataFrame(out)


def adopted_band_section(band: dict, table: pd.DataFrame, settings: RecipeSettings) -> list[str]:
    """Markdown lines: per cell the adopted recipe's training band beside the base recipe's (issue 60
    item 3; added after the choice, decides nothing)."""
    base = table.set_index(["study", "n_agents"])[["band_lo", "band_hi"]]
    rows = []
    for c in band["cells"]:
        lo, hi = base.loc[(c["study"], c["n_agents"])]
        rows.append({"cell": f"{c['study']} N={c['n_agents']}",
                     "adopted band % (mean)": f"{c['lo']:.1f}–{c['hi']:.1f} ({c['mean']:.1f}; {c['models']} models)",
                     **{settings.labels[run] if run != band["runs"][0] else f"{run} (deployed)":
                        (f"{c['safety'][run]:.1f}" if run in c["safety"] else "–") for run in band["runs"]},
                     "base band %": "–" if pd.isna(lo) else f"{lo:.1f}–{hi:.1f}"})
    return ["## The adopted recipe's training band (issue 60 item 3; added after the choice, decides nothing)", "",
            f"Safety % of {', '.join(band['runs'])}: the V̂ the protocol deploys and its training-seed replicates, "
            f"beside the band over {', '.join(settings.band_runs)} (the base recipe's).", "",
            to_markdown(pd.DataFrame(rows)), ""]


def write_recipe_page(result_paths: Iterable[str | Path], settings: RecipeSettings, out_dir: str | Path) -> list[Path]:
    """Read the cells, judge them and write ``vhat_recipe.csv`` (one row per cell and model),
    ``vhat_recipe.json`` (the choice) and ``vhat_recipe.md``; returns the three paths."""
    safety = cell_safety(load_results(result_paths))
    table, choice = choose(safety, settings)
    choice["sentence"] = choice_sentence(choice)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    csv, js, md = out / "vhat_recipe.csv", out / "vhat_recipe.json", out / "vhat_recipe.md"
    long_rows(table, safety, settings).to_csv(csv, index=False, float_format="%.6g")
    js.write_text(json.dumps(choice, indent=2, sort_keys=True, ensure_ascii=False) + "\n")
    models = _models(settings)
    verdicts = pd.DataFrame([{"component": f"{x}: {c['component']}", "−X": f"{c['run']} ({settings.labels[c['run']]})",
                              "cells below (▼)": c["below"], "cells above (▲)": c["above"], "verdict": c["verdict"],
                              "action": c["action"]} for x, c in choice["components"].items()])
    text = [
        "# V̂'s recipe, re-chosen on validation seeds (issue 61 item 4)", "",
        f"**Chosen:** {choice['sentence']}.", "",
        f"Rule, fixed before these cells ran ({choice['rule']}): per deciding cell the training band is [min, max] of "
        f"safety over {', '.join(settings.band_runs)}; X is needed when −X lies ≥ {settings.margin_points:g} points below the "
        f"band in ≥ {settings.quorum} deciding cells and above it in none, harmful the other way round, else "
        "indistinguishable from training variance. F (" + COMPONENTS["F"] + ") is kept unless harmful (−F trains on half "
        "the samples) and stays a labelled deviation from the paper's constant rate; C (" + COMPONENTS["C"] + ") is kept "
        "only if needed, else the protocol's V̂ becomes −C (the paper's uniform states) at the protocol rerun, the base "
        "recipe reported beside it.", "",
        *([f"**Provisional:** no cells of {', '.join(choice['missing_replicates'])} at some deciding cell: the band "
           "is over the models present (degenerate); the reading is redone when their cells exist, and that reading "
           "is the one adopted.", ""] if choice["provisional"] else []),
        "## Verdicts", "", to_markdown(verdicts), "",
        f"## Deciding cells ({cells_text(choice['deciding'])}; seeds {', '.join(map(str, choice['seeds']))})", "",
        "Safety % per model (" + ", ".join(f"{n} = {r}" for r, n in models.items()) + "); ▼ / ▲: −X below / above "
        f"the band by ≥ {settings.margin_points:g} points. 95 % bootstrap intervals over scenarios: vhat_recipe.csv.", "",
        to_markdown(cells_display(table, "deciding", settings)), "",
    ]
    if choice["reported"]:
        text += ["## Reported beside (decide nothing)", "", to_markdown(cells_display(table, "reported", settings)), ""]
    if choice["adopted_band"]:
        text += adopted_band_section(choice["adopted_band"], table, settings)
    md.write_text("\n".join(text))
    return [csv, md, js]
