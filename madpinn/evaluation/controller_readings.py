"""Controller readings (issue 46): the same cells flown under each reading of the paper's tracking
loop (``sim.mujoco.controller``: ``cascaded`` | ``mellinger`` | ``firmware_pid``,
:mod:`madpinn.simulation.mujoco.readings`), side by side.

A study's reading is its ``sim.mujoco.controller`` (:func:`madpinn.config.study_sim`); studies
that differ only in it are grouped by their arena. One row per (arena, run, N): per reading the
safety rate and safe scenarios (d ≤ r), the time-averaged cost over the collision-free agents
(the paper's), the share of MAD-PINN agent-steps with no feasible budget, and the 50th / 90th
percentile of the agents' planar speed in the cell's recorded scenario (its ``_traj.npz``: the
first scenario, positions every ``sim.record_every`` steps).
"""

from __future__ import annotations

from pathlib import Path
from typing import Iterable, Mapping

import numpy as np
import pandas as pd

from madpinn.config import study_sim
from madpinn.evaluation.cell_files import cell_summary
from madpinn.evaluation.tables import label_of, load_results, per_seed, run_order, to_markdown

METRICS = {"safety": "safety_rate", "safe sc.": "safe_scenarios", "cost ÷T": "cost_time_avg"}


def study_reading(cfg: Mapping, study: str) -> str:
    """The controller reading study ``study``'s MuJoCo cells fly with."""
    return str(study_sim(cfg, study)["mujoco"]["controller"])


def recorded_speeds(traj: str | Path) -> np.ndarray:
    """Planar speeds (m/s) of every agent at every recorded interval of a cell's trajectory file."""
    with np.load(traj) as z:
        pos, times = z["positions"], z["times"]
    v = np.diff(pos, axis=0) / np.diff(times)[:, None, None]
    return np.linalg.norm(v, axis=-1).ravel()


def cell_extras(parquet: str | Path) -> dict:
    """Infeasible share (from the cell's JSON summary, NaN for non-MAD-PINN runs) and speed
    percentiles (from its ``_traj.npz``, NaN when absent) of one cell file."""
    p = Path(parquet)
    stats = cell_summary(p).get("policy_stats") or {}
    traj = p.with_name(p.stem + "_traj.npz")
    speeds = recorded_speeds(traj) if traj.is_file() else np.array([np.nan])
    return {"infeasible": float(stats.get("infeasible_fraction", np.nan)),
            "speed_p50": float(np.nanpercentile(speeds, 50)) if np.isfinite(speeds).any() else np.nan,
            "speed_p90": float(np.nanpercentile(speeds, 90)) if np.isfinite(speeds).any() else np.nan}


def readings_table(result_paths: Iterable[str | Path], cfg: dict) -> pd.DataFrame:
    """One row per (arena, run, N) and one column group per reading (see module docstring)."""
    paths = [Path(p) for p in result_paths]
    df = load_results(paths)
    extras = pd.DataFrame([{"study": s, "run": r, "n_agents": int(n), "seed": int(seed), **cell_extras(p)}
                           for p in paths
                           for (s, r, n, seed) in pd.read_parquet(p, columns=["study", "run", "n_agents", "seed"]).drop_duplicates().itertuples(index=False)])
    readings = {s: study_reading(cfg, s) for s in df["study"].unique()}
    seeds = []
    for study, g in df.groupby("study", sort=False):
        s = per_seed(g)
        s["study"], s["reading"], s["arena"] = study, readings[study], str(g["arena"].iloc[0])
        seeds.append(s)
    seeds = pd.concat(seeds, ignore_index=True).merge(extras, on=["study", "run", "n_agents", "seed"], how="left")
    order = run_order(df, cfg)
    names = list(dict.fromkeys(readings.values()))
    rows = []
    for (arena, run, n), g in sorted(seeds.groupby(["arena", "run", "n_agents"]), key=lambda kv: (kv[0][0], order.get(kv[0][1], 99), kv[0][2])):
        row = {"arena": arena, "run": run, "label": label_of(cfg, run), "n_agents": int(n)}
        for reading in names:
            sel = g[g["reading"] == reading]
            for col, metric in {**METRICS, "infeasible": "infeasible", "speed p50": "speed_p50", "speed p90": "speed_p90"}.items():
                row[f"{reading}: {col}"] = float(sel[metric].mean()) if len(sel) else np.nan
        row["seeds"] = " ".join(str(int(x)) for x in sorted(g["seed"].unique()))
        rows.append(row)
    return pd.DataFrame(rows)


def format_table(table: pd.DataFrame) -> pd.DataFrame:
    """Display: percentages, costs and speeds with two decimals, '–' where a reading has no cell."""
    def fmt(col: str, x) -> str:
        if pd.isna(x):
            return "–"
        if col.endswith(("safety", "safe sc.", "infeasible")):
            return f"{100 * x:.1f}%"
        return f"{x:.2f}"

    out = table.drop(columns=["run"]).rename(columns={"label": "Method", "arena": "Arena", "n_agents": "N"})
    for col in out.columns:
        if ": " in col:
            out[col] = [fmt(col, x) for x in out[col]]
    return out


def write_controller_readings(result_paths: Iterable[str | Path], cfg: dict, out_dir: str | Path,
                              name: str = "table_controller_readings") -> list[Path]:
    """Write ``<name>.csv`` (numbers), ``.md`` and ``.html`` (display with the readings' definitions)."""
    from madpinn.evaluation.html import write_table_files

    table = readings_table(result_paths, cfg)
    text = (
        "Every cell under each reading of the paper's tracking loop (issue 46; docs/reference/mujoco.md, \"Controller readings\"):\n"
        "cascaded = ours (the firmware PID's structure, v_d and a_ff fed forward, raised gains, 45°); mellinger = the\n"
        "firmware's Mellinger controller with its gains; firmware_pid = the firmware's PID stack in absolute-position mode\n"
        "(1.1 m/s, 20°). Safety at d ≤ r; cost ÷T over the collision-free agents; infeasible = MAD-PINN agent-steps with\n"
        "no feasible budget; speeds: planar speed percentiles (m/s) of the recorded scenario. "
        f"Experiment {cfg['experiment']}; validation seeds only.\n\n" + to_markdown(format_table(table)))
    return write_table_files(table, text, out_dir, name)
