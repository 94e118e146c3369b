"""Gap decomposition (issue 14): the same MAD-PINN models, cause by cause, as a table of cells.

The rows are declared in the config, not here. ``gap_decomposition.studies`` lists studies whose
cells the ``evaluate`` rule computes like any other cell (output cache, parallel cells, one MLflow
run each): MAD-PINN runs on the study's backend (``studies.<s>.sim.backend``), validation seeds
(≥ 100), every collision onset classified into the cell's summary (``collision_events``,
:mod:`madpinn.evaluation.collisions`). Each run switches the deployment causes through its own
settings: the observation mapping (``methods.madpinn.variants.<v>.observation``: ``carrot_margin``,
``neighbour_goal``) and the actuator-lag compensation (``look_ahead``). This module only reads the
cells' JSON summaries and writes the table.

One row per (study, run, N), named from its backend and switches against the old mapping
(carrot on the box edge, ego-relative neighbour goals, no look-ahead): ``mujoco / old mapping``,
``mujoco + carrot_margin`` (the configured ``observation.carrot_margin``; another margin is
written ``carrot_margin=0.1``), ``+ neighbour_goal``, ``+ look_ahead``, ``+ all fixes`` (all
three). Per row: safety rate, safe scenarios, cumulative cost and time-averaged cost as means
over seeds, and the collision-onset diagnostics pooled over seeds; each row's safety change
against the ``gap_decomposition.reference`` row of the same N. Files: ``decomposition.csv``,
``decomposition.md`` and ``decomposition.json`` (onset summary and events per row).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Iterable, Mapping

import pandas as pd

from madpinn.config import method_config, run_observation, study_backend
from madpinn.evaluation.collisions import summarise


def switches(cfg: Mapping, run: str) -> dict:
    """The deployment causes run ``run`` switches: ``carrot_margin`` (m), ``neighbour_goal``,
    ``look_ahead`` (s), from its observation overrides and its method settings."""
    obs = run_observation(cfg, run)
    return {"carrot_margin": float(obs["carrot_margin"]), "neighbour_goal": str(obs["neighbour_goal"]),
            "look_ahead": float(method_config(cfg, run)[1]["look_ahead"])}   # required by the schema


def row_name(backend: str, sw: Mapping, configured_margin: float) -> str:
    """``<backend> / old mapping`` or ``<backend> + <fixes>`` (module docstring)."""
    fixes = []
    if sw["carrot_margin"] > 0:
        fixes.append("carrot_margin" if sw["carrot_margin"] == configured_margin else f"carrot_margin={sw['carrot_margin']:g}")
    if sw["neighbour_goal"] == "neighbour":
        fixes.append("neighbour_goal")
    if sw["look_ahead"] > 0:
        fixes.append("look_ahead")
    if not fixes:
        return f"{backend} / old mapping"
    if fixes == ["carrot_margin", "neighbour_goal", "look_ahead"]:
        return f"{backend} + all fixes"
    return f"{backend} + " + " + ".join(fixes)


def load_summaries(paths: Iterable[str | Path]) -> list[dict]:
    """The cells' JSON summaries (``evaluate``'s ``<cell>.json``; a ``.parquet`` path is mapped to it)."""
    return [json.loads(Path(p).with_suffix(".json").read_text()) for p in paths]


def decompose(cfg: Mapping, summaries: list[dict]) -> tuple[pd.DataFrame, dict]:
    """The table (one row per study × run × N, in the order of ``gap_decomposition.studies``, their
    runs and N) and the onset diagnostics per row, from the cells' summaries."""
    studies = list(cfg["gap_decomposition"]["studies"])
    cells = [s for s in summaries if s["study"] in studies]
    if not cells:
        raise ValueError(f"no cell of the gap studies {studies} among the {len(summaries)} inputs")
    margin = float(cfg["observation"]["carrot_margin"])
    order = {(st, run): (i, j) for i, st in enumerate(studies) for j, run in enumerate(cfg["studies"][st]["runs"])}
    df = pd.DataFrame(cells)
    df["_order"] = [order[(s, r)][0] * 1000 + order[(s, r)][1] if (s, r) in order else 10**9
                    for s, r in zip(df["study"], df["run"])]
    rows, diagnostics = [], {}
    for (n, _, study, run), g in df.sort_values(["n_agents", "_order", "seed"]).groupby(
            ["n_agents", "_order", "study", "run"], sort=False):
        backend = study_backend(cfg, study)
        if set(g["backend"]) != {backend}:
            raise ValueError(f"cells of {study}/{run} ran on {sorted(set(g['backend']))}, the study's backend is {backend}")
        sw = switches(cfg, run)
        name = row_name(backend, sw, margin)
        events = [e for ev in (g["collision_events"] if "collision_events" in g else []) if isinstance(ev, list) for e in ev]
        diag = summarise(events)
        diagnostics[f"{name} | N={n}"] = {**diag, "study": study, "run": run, "events": events}
        rows.append({
            "variant": name, "backend": backend, "run": run, "n_agents": int(n), "study": study,
            "seeds": " ".join(str(s) for s in g["seed"]), "scenarios_per_seed": int(g["n_scenarios"].iloc[0]), **sw,
            "safety_rate": g["safety_rate"].mean(), "safe_scenarios": g["safe_scenarios"].mean(),
            "cost": g["cost"].mean(), "cost_time_avg": g["cost_time_avg"].mean(),
            "collision_onsets": diag["collision_onsets"], "observed_both_share": diag["observed_both_share"],
            "feasible_at_onset_share": diag["feasible_at_onset_share"], "closing_speed_median": diag["closing_speed_median"],
            "wall_s": g["elapsed_s"].sum(),
        })
    return pd.DataFrame(rows), diagnostics


def _share(x: float) -> str:
    """A share of collision onsets; "–" where there was no onset (no share to give)."""
    return "–" if pd.isna(x) else f"{x:.2f}"


def markdown(table: pd.DataFrame, reference: Mapping, provenance: dict) -> str:
    """The decomposition as a markdown report: per N, every row with its safety change against the
    ``reference`` row (``{backend, run}``, the deployed baseline) of the same N."""
    ref_name = f"{reference['run']} on {reference['backend']}"
    lines = ["# MAD-PINN gap decomposition", ""]
    lines += [f"- {k}: {v}" for k, v in provenance.items()] + [""]
    for n, g in table.groupby("n_agents", sort=False):
        base = g.loc[(g["backend"] == reference["backend"]) & (g["run"] == reference["run"]), "safety_rate"]
        ref = float(base.iloc[0]) if len(base) else float("nan")
        lines += [f"## N = {n} ({', '.join(dict.fromkeys(g['study']))}; seeds {g['seeds'].iloc[0]}, "
                  f"{g['scenarios_per_seed'].iloc[0]} scenarios each)", "",
                  f"| row | run | safety rate | Δ vs {ref_name} | safe scenarios | cumulative cost | time-avg cost | onsets | "
                  "both observed | feasible at onset |",
                  "|---|---|---|---|---|---|---|---|---|---|"]
        for _, r in g.iterrows():
            lines.append(f"| {r['variant']} | {r['run']} | {100 * r['safety_rate']:.2f} % | {100 * (r['safety_rate'] - ref):+.2f} | "
                         f"{100 * r['safe_scenarios']:.1f} % | {r['cost']:.3f} | {r['cost_time_avg']:.3f} | {r['collision_onsets']} | "
                         f"{_share(r['observed_both_share'])} | {_share(r['feasible_at_onset_share'])} |")
        lines.append("")
    return "\n".join(lines)


def write(table: pd.DataFrame, diagnostics: dict, reference: Mapping, out_dir: str | Path, provenance: dict) -> list[Path]:
    """Write ``decomposition.{csv,md,json}`` under ``out_dir``; returns the paths."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    paths = [out / "decomposition.csv", out / "decomposition.md", out / "decomposition.json"]
    table.to_csv(paths[0], index=False)
    paths[1].write_text(markdown(table, reference, provenance))
    paths[2].write_text(json.dumps({"provenance": provenance, "diagnostics": diagnostics}, indent=1, default=float))
    return paths
