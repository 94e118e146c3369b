"""Gap decomposition (issue 14): the same MAD-PINN models, cause by cause.

Each *variant* is a backend plus a config overlay; every variant runs the same cells (N agents,
validation seeds ≥ 100, the same scenarios and policy seeds as ``evaluate``), so the rows differ
only by the switched cause. Default variants (:func:`default_variants`):

====================================  =================  ==========================================
row                                   backend            observation mapping
====================================  =================  ==========================================
``double_integrator / old mapping``   double integrator  carrot on the box edge, ego-relative g_j
``mujoco / old mapping``              MuJoCo             same (the tracking gap = this − row above)
``mujoco + carrot_margin``            MuJoCo             carrot ``carrot_margin`` inside the box
``mujoco + neighbour_goal``           MuJoCo             g_j shortened relative to the neighbour
``mujoco + look_ahead``               MuJoCo             own state predicted τ ahead (actuator lag)
``mujoco + all fixes``                MuJoCo             all three
``double_integrator + all fixes``     double integrator  all three
====================================  =================  ==========================================

The old mapping has no look-ahead (``methods.madpinn.look_ahead: 0``, the measured state); the
look-ahead rows are left out when ``look_ahead`` is 0.

plus optional carrot-margin sweep rows (double integrator, neighbour mapping old) to choose the
margin. Per row: safety rate, safe scenarios, cumulative cost and time-averaged cost (cumulative
÷ episode length) as means over seeds, and the collision diagnostics of
:mod:`madpinn.evaluation.collisions` pooled over seeds. Files first: ``decomposition.csv``,
``decomposition.md`` and ``decomposition.json`` (events summary per row).
"""

from __future__ import annotations

import json
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Mapping

import pandas as pd

from madpinn.config import deep_merge
from madpinn.device import resolve_device, resolve_dtype, seed_everything
from madpinn.evaluation.cell import CellSettings, cell_batches
from madpinn.evaluation.collisions import CollisionProbe, summarise
from madpinn.evaluation.metrics import scenario_metrics, seed_summary

OLD_MAPPING = {"observation": {"carrot_margin": 0.0, "neighbour_goal": "ego"}, "methods": {"madpinn": {"look_ahead": 0.0}}}
FIRST_VALIDATION_SEED = 100


@dataclass(frozen=True)
class Variant:
    """One row: ``backend`` and a config ``overlay`` applied on top of the base config."""

    name: str
    backend: str
    overlay: dict = field(default_factory=dict)


def default_variants(carrot_margin: float, margin_sweep: tuple[float, ...] = (), look_ahead: float = 0.0) -> list[Variant]:
    """The decomposition rows (module docstring); ``carrot_margin`` (m, > 0) is the fix's margin,
    ``look_ahead`` (s, ≥ 0) the lag compensation's τ (0: no look-ahead rows)."""
    if not carrot_margin > 0:
        raise ValueError(f"the carrot-margin fix needs a margin > 0 m, got {carrot_margin}")
    if not look_ahead >= 0:
        raise ValueError(f"look_ahead must be ≥ 0 s, got {look_ahead}")
    margin = {"observation": {"carrot_margin": float(carrot_margin)}}
    neighbour = {"observation": {"neighbour_goal": "neighbour"}}
    ahead = {"methods": {"madpinn": {"look_ahead": float(look_ahead)}}}
    fixed = deep_merge(deep_merge(margin, neighbour), ahead)
    rows = [
        Variant("double_integrator / old mapping", "double_integrator", OLD_MAPPING),
        Variant("mujoco / old mapping", "mujoco", OLD_MAPPING),
        Variant("mujoco + carrot_margin", "mujoco", deep_merge(OLD_MAPPING, margin)),
        Variant("mujoco + neighbour_goal", "mujoco", deep_merge(OLD_MAPPING, neighbour)),
    ]
    if look_ahead > 0:
        rows.append(Variant("mujoco + look_ahead", "mujoco", deep_merge(OLD_MAPPING, ahead)))
    rows += [
        Variant("mujoco + all fixes", "mujoco", deep_merge(OLD_MAPPING, fixed)),
        Variant("double_integrator + all fixes", "double_integrator", deep_merge(OLD_MAPPING, fixed)),
    ]
    for m in margin_sweep:
        rows.append(Variant(f"double_integrator + carrot_margin={m:g}", "double_integrator",
                            deep_merge(OLD_MAPPING, {"observation": {"carrot_margin": float(m)}})))
    return rows


def study_for(cfg: dict, n_agents: int) -> str:
    """The study whose agent counts contain ``n_agents`` (main before scaling)."""
    for study in ("main", "scaling"):
        if n_agents in cfg["studies"].get(study, {}).get("agent_counts", []):
            return study
    raise ValueError(f"{n_agents} agents are in no study's agent_counts (main, scaling); the cell's arena is undefined")


def run_cell(cfg: dict, backend: str, run: str, study: str, n_agents: int, seed: int, scenarios: int,
             progress: bool = False, models: Mapping[str, str | Path] | None = None) -> tuple[dict, list[dict]]:
    """One (variant config, N, seed) cell as ``evaluate`` runs it, with the collision probe:
    the seed's summary (plus ``cost_time_avg``) and the collision-onset events. ``models``: the
    run's trained files (``{"vhat": …, "vs": …}``)."""
    cs = CellSettings.from_config(cfg, study, run)
    if cs.method != "madpinn":
        raise ValueError(f"the gap decomposition evaluates MAD-PINN runs (madpinn[-variant]), got '{run}'")
    device, dtype = resolve_device(cs.device), resolve_dtype(cs.dtype)
    seed_everything(seed)   # as evaluate does (thread count left to the caller)
    r = cs.limits.collision_radius
    frames, events = [], []

    def probe(policy, first):
        p = CollisionProbe(policy, r)
        p.scenario_offset = first
        return p

    for first, policy, result, _ in cell_batches(cs, n_agents, seed, backend, device, dtype, models, scenarios,
                                                 wrap=probe, progress=progress):
        frames.append(scenario_metrics(result, first_index=first))
        events += [{**e, "seed": seed} for e in policy.events]
    summary = seed_summary(pd.concat(frames, ignore_index=True))
    summary["cost_time_avg"] = summary["cost"] / cs.arena.episode_s
    return summary, events


def decompose(cfg: dict, variants: list[Variant], agent_counts: list[int], seeds: list[int], scenarios: int,
              run: str = "madpinn", progress: bool = False,
              models: Mapping[str, str | Path] | None = None) -> tuple[pd.DataFrame, dict]:
    """All rows × cells (``models``: the run's trained files). Returns the table (one row per
    variant × N) and the diagnostics per row."""
    bad = [s for s in seeds if s < FIRST_VALIDATION_SEED]
    if bad:
        raise ValueError(f"the gap decomposition runs on validation seeds ≥ {FIRST_VALIDATION_SEED} only (never the protocol seeds), got {bad}")
    if scenarios < 1 or not seeds or not agent_counts:
        raise ValueError("need ≥ 1 scenario, seed and agent count")
    rows, diagnostics = [], {}
    for n in agent_counts:
        study = study_for(cfg, n)
        for v in variants:
            vcfg = deep_merge(cfg, v.overlay)
            t0 = time.perf_counter()
            per_seed, events = [], []
            for seed in seeds:
                summary, ev = run_cell(vcfg, v.backend, run, study, n, seed, scenarios, progress, models)
                per_seed.append(summary)
                events += ev
            df = pd.DataFrame(per_seed)
            diag = summarise(events)
            diagnostics[f"{v.name} | N={n}"] = {**diag, "events": events}
            rows.append({
                "variant": v.name, "backend": v.backend, "n_agents": n, "study": study,
                "seeds": " ".join(map(str, seeds)), "scenarios_per_seed": scenarios,
                "carrot_margin": vcfg["observation"]["carrot_margin"], "neighbour_goal": vcfg["observation"]["neighbour_goal"],
                "look_ahead": float(vcfg["methods"]["madpinn"].get("look_ahead", 0.0)),
                "safety_rate": df["safety_rate"].mean(), "safe_scenarios": df["safe_scenarios"].mean(),
                "cost": df["cost"].mean(), "cost_time_avg": df["cost_time_avg"].mean(),
                "collision_onsets": diag["collision_onsets"], "observed_both_share": diag["observed_both_share"],
                "feasible_at_onset_share": diag["feasible_at_onset_share"], "closing_speed_median": diag["closing_speed_median"],
                "wall_s": time.perf_counter() - t0,
            })
            print(f"[gap] N={n} {v.name}: safety {rows[-1]['safety_rate']:.4f}, safe {rows[-1]['safe_scenarios']:.3f}, "
                  f"cost {rows[-1]['cost']:.3f} ({rows[-1]['cost_time_avg']:.3f}/s), {rows[-1]['wall_s']:.0f} s", flush=True)
    return pd.DataFrame(rows), diagnostics


def _share(x: float) -> str:
    """A share of collision onsets; "–" where there was no onset (no share to give)."""
    return "–" if pd.isna(x) else f"{x:.2f}"


def markdown(table: pd.DataFrame, provenance: dict) -> str:
    """The decomposition as a markdown report: per N, every row with its safety change against
    the MuJoCo old-mapping row (the deployed baseline)."""
    lines = ["# MAD-PINN gap decomposition", ""]
    lines += [f"- {k}: {v}" for k, v in provenance.items()] + [""]
    for n, g in table.groupby("n_agents", sort=False):
        base = g.loc[g["variant"] == "mujoco / old mapping", "safety_rate"]
        ref = float(base.iloc[0]) if len(base) else float("nan")
        lines += [f"## N = {n} ({g['study'].iloc[0]} study, seeds {g['seeds'].iloc[0]}, {g['scenarios_per_seed'].iloc[0]} scenarios each)", "",
                  "| row | safety rate | Δ vs MuJoCo old | safe scenarios | cumulative cost | time-avg cost | onsets | both observed | feasible at onset |",
                  "|---|---|---|---|---|---|---|---|---|"]
        for _, r in g.iterrows():
            lines.append(f"| {r['variant']} | {100 * r['safety_rate']:.2f} % | {100 * (r['safety_rate'] - ref):+.2f} | "
                         f"{100 * r['safe_scenarios']:.1f} % | {r['cost']:.3f} | {r['cost_time_avg']:.3f} | {r['collision_onsets']} | "
                         f"{_share(r['observed_both_share'])} | {_share(r['feasible_at_onset_share'])} |")
        lines.append("")
    return "\n".join(lines)


def write(table: pd.DataFrame, diagnostics: dict, out_dir: str | Path, provenance: dict) -> list[Path]:
    """Write ``decomposition.{csv,md,json}`` under ``out_dir``; returns the paths."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    paths = [out / "decomposition.csv", out / "decomposition.md", out / "decomposition.json"]
    table.to_csv(paths[0], index=False)
    paths[1].write_text(markdown(table, provenance))
    paths[2].write_text(json.dumps({"provenance": provenance, "diagnostics": diagnostics}, indent=1, default=float))
    return paths
