"""The agent-model table (issue 63, not in the paper): does passing over each other change safety
and cost?

The studies of ``agent_models.studies`` share their scenarios (arena, pattern, agent counts,
validation seeds, scenario count: checked at config time); each flies its own agent model
(``studies.<s>.agents``, :func:`madpinn.config.study_agents`). A non-planar model places the
planar starts and goals at one altitude, the middle of its band
(:meth:`madpinn.dynamics.double_integrator_3d.DoubleIntegrator3D.place`), so the two models see the same scenarios in
the plane and differ only in the freedom to climb and descend. One row per (backend, study, run,
N): safety (d ≤ r, in the model's space), safe scenarios and the time-averaged cost over the
collision-free agents (the paper's figures; 95 % intervals as every table's,
:mod:`madpinn.evaluation.intervals`); for a non-planar row the paired difference to the planar
study's run of the same method on the same backend (same scenarios: t over seeds, or a paired
bootstrap with one seed); and two readings of the cell's recorded scenario (its ``_traj.npz``:
the first scenario, positions every ``sim.record_every`` steps): the 90th percentile of the agents'
altitude change from their start (m), and the overflights, pairs of agents that came within r of
each other in the plane while more than r apart in space (NaN for the planar model, where the two
distances are one).
"""

from __future__ import annotations

from pathlib import Path
from typing import Iterable, Mapping

import numpy as np
import pandas as pd

from madpinn.config import describe_model, study_agents, study_backend
from madpinn.config.hashing import PAPER_AGENT_MODEL
from madpinn.dynamics.double_integrator_3d import DoubleIntegrator3D
from madpinn.evaluation.intervals import paired_differences, seed_figures
from madpinn.evaluation.tables import label_of, load_results, per_seed, to_markdown

TITLE = "3-D double integrator: not in the paper"
METRICS = ("safety_rate", "safe_scenarios", "cost_time_avg")
"""the seed figures of each row (and of its paired difference)"""
REFERENCE, OTHER = "planar", "other"


def recorded_passes(traj: str | Path) -> dict:
    """Altitude change p90 (m) and overflights (pairs within r in the plane, > r apart in space)
    of one cell's recorded scenario; NaN for planar positions."""
    with np.load(traj) as z:
        pos, r = np.asarray(z["positions"], dtype=float), float(z["collision_radius"])   # [T, N, d]
    k = DoubleIntegrator3D.ALTITUDE   # the altitude's coordinate; the others span the plane
    if pos.shape[-1] <= k:
        return {"altitude_p90": np.nan, "overflights": np.nan}
    climb = np.abs(pos[..., k] - pos[:1, :, k])
    diff = pos[:, :, None, :] - pos[:, None, :, :]                       # [T, N, N, d]
    plane, space = np.linalg.norm(np.delete(diff, k, axis=-1), axis=-1), np.linalg.norm(diff, axis=-1)
    over = ((plane <= r) & (space > r)).any(axis=0)
    return {"altitude_p90": float(np.percentile(climb, 90)), "overflights": int(np.triu(over, k=1).sum())}


def _recorded(paths: Iterable[Path]) -> pd.DataFrame:
    rows = []
    for p in paths:
        traj = p.with_name(p.stem + "_traj.npz")
        cell = pd.read_parquet(p, columns=["study", "run", "n_agents", "seed"]).iloc[0]
        rows.append({"study": cell["study"], "run": cell["run"], "n_agents": int(cell["n_agents"]), "seed": int(cell["seed"]),
                     **(recorded_passes(traj) if traj.is_file() else {"altitude_p90": np.nan, "overflights": np.nan})})
    return pd.DataFrame(rows)


def reference_run(cfg: Mapping, planar: str, run: str) -> str:
    """The run of planar study ``planar`` that ``run`` is paired with: the same run name, else the
    first of the same method (config check: there is one)."""
    runs = cfg["studies"][planar]["runs"]
    return run if run in runs else next(r for r in runs if r.partition("-")[0] == run.partition("-")[0])


def agent_models_table(result_paths: Iterable[str | Path], cfg: Mapping) -> pd.DataFrame:
    """One row per (backend, study, run, N) of the cells ``result_paths`` (see the module docstring)."""
    paths = [Path(p) for p in result_paths]
    df = load_results(paths)
    recorded = _recorded(paths)
    studies = list(dict.fromkeys(s for s in cfg["agent_models"]["studies"] if s in set(df["study"])))
    planar = {study_backend(cfg, s): s for s in studies if study_agents(cfg, s)["model"] == PAPER_AGENT_MODEL}
    rows = []
    for study in studies:
        backend, agents = study_backend(cfg, study), study_agents(cfg, study)
        sdf = df[df["study"] == study]
        for run in cfg["studies"][study]["runs"]:
            rdf = sdf[sdf["run"] == run]
            if rdf.empty:
                continue
            seeds = per_seed(rdf)
            figs = seed_figures(seeds, ["n_agents"], METRICS)
            diffs = pd.DataFrame()
            ref = planar.get(backend)
            if ref is not None and ref != study:
                ref_rows = df[(df["study"] == ref) & (df["run"] == reference_run(cfg, ref, run))].assign(run=REFERENCE)
                diffs = paired_differences(pd.concat([ref_rows, rdf.assign(run=OTHER)], ignore_index=True), REFERENCE, METRICS)
            rec = recorded[(recorded["study"] == study) & (recorded["run"] == run)]
            for _, f in figs.iterrows():
                n = int(f["n_agents"])
                row = {"backend": backend, "study": study, "model": describe_model(agents), "run": run, "label": label_of(cfg, run),
                       "n_agents": n, "seeds": " ".join(str(s) for s in sorted(rdf[rdf["n_agents"] == n]["seed"].unique())),
                       "scenarios": int((rdf["n_agents"] == n).sum())}
                row.update({k: float(f[k]) for k in f.index if k != "n_agents" and k.endswith(("_mean", "_ci_lo", "_ci_hi"))})
                d = diffs[diffs["n_agents"] == n] if len(diffs) else diffs
                for m in METRICS:
                    for suffix in ("diff", "diff_lo", "diff_hi"):
                        row[f"{m}_{suffix}"] = float(d[f"{m}_{suffix}"].iloc[0]) if len(d) else np.nan
                row["reference"] = f"{ref}/{reference_run(cfg, ref, run)}" if len(d) else ""
                cells = rec[rec["n_agents"] == n]
                row["altitude_p90"] = float(cells["altitude_p90"].mean()) if len(cells) else np.nan
                row["overflights"] = float(cells["overflights"].sum()) if len(cells) and cells["overflights"].notna().any() else np.nan
                rows.append(row)
    return pd.DataFrame(rows)


def _pct(mean: float, lo: float, hi: float) -> str:
    if pd.isna(mean):
        return "–"
    return f"{100 * mean:.1f}%" + ("" if pd.isna(lo) else f" [{100 * lo:.1f}, {100 * hi:.1f}]")


def _num(mean: float, lo: float, hi: float, sign: bool = False) -> str:
    if pd.isna(mean):
        return "–"
    f = "+.2f" if sign else ".2f"
    return f"{mean:{f}}" + ("" if pd.isna(lo) else f" [{lo:{f}}, {hi:{f}}]")


def format_table(table: pd.DataFrame) -> pd.DataFrame:
    """Display: percentages and costs with their 95 % intervals, '–' where a reading does not apply."""
    out = []
    for _, r in table.iterrows():
        out.append({
            "Backend": r["backend"], "Agent model": r["model"], "Method": r["label"], "N": int(r["n_agents"]),
            "Safety": _pct(r["safety_rate_mean"], r["safety_rate_ci_lo"], r["safety_rate_ci_hi"]),
            "Safe Sc.": _pct(r["safe_scenarios_mean"], r["safe_scenarios_ci_lo"], r["safe_scenarios_ci_hi"]),
            "Cost ÷T": _num(r["cost_time_avg_mean"], r["cost_time_avg_ci_lo"], r["cost_time_avg_ci_hi"]),
            "Δ Safety vs planar": ("–" if pd.isna(r["safety_rate_diff"]) else
                                   f"{100 * r['safety_rate_diff']:+.1f} pts" + ("" if pd.isna(r["safety_rate_diff_lo"]) else
                                   f" [{100 * r['safety_rate_diff_lo']:+.1f}, {100 * r['safety_rate_diff_hi']:+.1f}]")),
            "Δ Cost ÷T vs planar": _num(r["cost_time_avg_diff"], r["cost_time_avg_diff_lo"], r["cost_time_avg_diff_hi"], sign=True),
            "Altitude change p90 (m)": _num(r["altitude_p90"], np.nan, np.nan),
            "Overflights (recorded)": "–" if pd.isna(r["overflights"]) else f"{int(r['overflights'])}",
        })
    return pd.DataFrame(out)


def write_agent_models(result_paths: Iterable[str | Path], cfg: Mapping, out_dir: str | Path,
                       name: str = "table_agent_models") -> list[Path]:
    """Write ``<name>.csv`` (numbers), ``.md`` and ``.html`` (display, titled :data:`TITLE`)."""
    from madpinn.evaluation.html import write_table_files

    table = agent_models_table(result_paths, cfg)
    text = (
        f"## {TITLE}\n\n"
        "Does passing over each other change safety and cost? The same scenarios (starts and goals in the plane, every\n"
        "agent starting and ending at the middle of the altitude band) flown by the paper's planar double integrator and\n"
        "by the 3-D one, whose agents may climb and descend inside the band, each with V̂ and V_s trained for its model.\n"
        "Safety at d ≤ r in the model's space; cost ÷T over the collision-free agents; [95 % intervals]: t over seeds\n"
        "(bootstrap over scenarios with one seed); Δ: paired on the same scenarios, the 3-D row minus the planar one.\n"
        "Altitude change and overflights (pairs within r in the plane, more than r apart in space) read the cell's\n"
        f"recorded scenario. Experiment {cfg['experiment']}; validation seeds only.\n\n" + to_markdown(format_table(table)))
    return write_table_files(table, text, out_dir, name)
