"""Table II under the readings the paper leaves open (issue 60 items 1, 2 and 5).

A *reading* is a large-arena study (its start/goal law, the study's ``pattern``), a run (the
deployment: V̂, goal carrot, sensing radius, speed bound) and a horizon T (the study's episode or one
of its ``cost_horizons_s``, read from the same episodes). The scale that judges a reading against
all of Table II was fixed before its cells ran
(``docs/findings/2026-11-28-table-ii-readings-preregistered.md`` §3; :data:`SCALE`):

- at each of the paper's agent counts: safety ≥ the paper's − 2 points and safe scenarios ≥ the
  paper's − 15 points;
- cost within ±25 % of the paper's at every agent count in one cost reading, the same at every N:
  the integral over [0, T] or the integral ÷ T (over the collision-free agents, the protocol's
  convention; the all-agents cost is shown beside it).

:func:`claim_verdict` turns the judged readings into the claim's verdict: "holds under the
protocol's reading", "holds only under readings the paper does not state" (naming each), or "not
reproduced under any reading tried" (naming the closest). :func:`law_rule` reads the start/goal
laws against Table I's anchor by the plan's §1: the per-encounter hazard
(:func:`madpinn.evaluation.encounter_hazard.cell_hazard`) of every large-arena cell whose load lies
within ±25 % of the anchor's.

Scenarios are pooled over a reading's seeds (validation seeds 100-101 give 20 scenarios per cell,
the paper's count for Table II); intervals are percentile bootstraps over those scenarios.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping

import numpy as np
import pandas as pd

from madpinn.evaluation.encounter_hazard import cell_hazard
from madpinn.evaluation.metrics import COST_COLUMNS, bootstrap_interval, horizon_suffix


@dataclass(frozen=True)
class Scale:
    """The verdict scale of the pre-registered plan (§3) and the law rule's constants (§1)."""

    safety_points: float = 0.02
    """a reading's safety may fall this far (a share) below the paper's at each N"""
    safe_points: float = 0.15
    """a reading's safe-scenario share may fall this far below the paper's at each N"""
    cost_relative: float = 0.25
    """a reading's cost may differ by this fraction of the paper's, at every N in one cost reading"""
    load_window: float = 0.25
    """§1: a large-arena cell is load-matched when its encounters per agent lie within this fraction of the anchor's"""
    hazard_factor: float = 2.0
    """§1: "behaves like Table I" within this factor of the anchor's hazard, "harder" beyond it"""


SCALE = Scale()

COST_READINGS = {"integral": "cost", "÷T": "cost_time_avg"}
"""the two cost readings the scale accepts -> their seed-figure names (:data:`COST_COLUMNS`)"""

VERDICTS = ("holds under the protocol's reading", "holds only under readings the paper does not state",
            "not reproduced under any reading tried")


@dataclass(frozen=True)
class PaperRow:
    """Table II's row for the paper's method: per agent count, safety, safe scenarios (shares) and cost."""

    cells: Mapping[int, Mapping[str, float]]
    """N -> {"safety": share, "safe_scenarios": share, "cost": paper's cost}"""

    @classmethod
    def from_paper_values(cls, values: Mapping) -> "PaperRow":
        """From :func:`madpinn.evaluation.reproduction.paper_values` (Table II = ``table_ours_scaling``)."""
        return cls({int(n): dict(v) for n, v in values["table_ours_scaling"]["runs"]["madpinn"]["n"].items()})


def horizons_of(frame: pd.DataFrame, episode_s: float) -> list[float]:
    """The horizons (s) a cell's scenario rows can be read at: every ``_at_<H>s`` column's H and the episode."""
    found = {float(c.rpartition("_at_")[2][:-1]) for c in frame.columns if "_at_" in c and c.endswith("s")}
    return sorted(found | {float(episode_s)})


def _column(frame: pd.DataFrame, name: str, horizon: float, episode_s: float) -> np.ndarray:
    col = name if horizon == episode_s else name + horizon_suffix(horizon)
    return frame[col].to_numpy(dtype=float)


def reading_rows(frame: pd.DataFrame) -> pd.DataFrame:
    """One row per (study, run, horizon, N) of large-arena scenario rows ``frame`` (cells of any
    seeds, concatenated, with a ``pattern`` column: the study's start/goal law): scenarios pooled over seeds; safety, safe scenarios, the four costs with
    95 % bootstrap intervals for safety and cost ÷T, the mean goal distance at the episode's end (m;
    NaN at earlier horizons), load and hazard per encounter."""
    rows = []
    for (study, run, n), g in frame.groupby(["study", "run", "n_agents"], sort=False):
        episode_s = float(g["episode_s"].iloc[0])
        load = cell_hazard(g) if "encounters_per_agent" in g else {}
        for h in horizons_of(g, episode_s):
            safety = _column(g, "safety_rate", h, episode_s)
            row = {"study": study, "run": run, "horizon_s": h, "n_agents": int(n),
                   "pattern": str(g["pattern"].iloc[0]), "seeds": " ".join(str(int(s)) for s in sorted(g["seed"].unique())), "scenarios": len(g),
                   "safety": float(safety.mean()), "safe_scenarios": float(_column(g, "safe", h, episode_s).mean())}
            row["safety_lo"], row["safety_hi"] = bootstrap_interval(safety)
            for name, col in COST_COLUMNS.items():
                vals = _column(g, col, h, episode_s)
                row[name] = float(np.nanmean(vals)) if np.isfinite(vals).any() else float("nan")
            row["cost_time_avg_lo"], row["cost_time_avg_hi"] = bootstrap_interval(
                _column(g, COST_COLUMNS["cost_time_avg"], h, episode_s))
            row["goal_distance"] = (float(g["final_distance_mean"].mean())
                                    if h == episode_s and "final_distance_mean" in g else float("nan"))
            row["encounters_per_agent"] = load.get("encounters_per_agent", float("nan"))
            row["hazard"] = load.get("hazard", float("nan")) if h == episode_s else float("nan")
            rows.append(row)
    return pd.DataFrame(rows)


def judge(rows: pd.DataFrame, paper: PaperRow, scale: Scale = SCALE) -> pd.DataFrame:
    """One row per reading (study, run, horizon) that has a cell at every paper N: the checks of
    :data:`SCALE` per N, the cost reading that matches (or "none"), ``checks_passed`` of
    ``3 · len(N)``, ``reproduces`` and ``failed`` (each failed check with its value and line, "; "-joined;
    cost in the best-matching reading). Readings missing an N are left out (they cannot be judged)."""
    counts = sorted(paper.cells)
    out = []
    for (study, run, h), g in rows.groupby(["study", "run", "horizon_s"], sort=False):
        g = g.set_index("n_agents")
        if not set(counts) <= set(g.index):
            continue
        row = {"study": study, "run": run, "horizon_s": h, "pattern": g["pattern"].iloc[0], "seeds": g["seeds"].iloc[0]}
        passed, failed = 0, []
        for n in counts:
            for key, points, ok_key in (("safety", scale.safety_points, "safety_ok"), ("safe_scenarios", scale.safe_points, "safe_ok")):
                line = paper.cells[n][key] - points
                ok = g.at[n, key] >= line - 1e-12
                row[f"{ok_key}_{n}"] = bool(ok)
                passed += int(ok)
                if not ok:
                    failed.append(f"{key.replace('_', ' ')} at N={n}: {100 * g.at[n, key]:.2f} % < {100 * line:.2f} %")
        cost_hits = {}
        for reading, figure in COST_READINGS.items():
            cost_hits[reading] = [bool(abs(g.at[n, figure] / paper.cells[n]["cost"] - 1.0) <= scale.cost_relative)
                                  for n in counts]
        best = max(cost_hits, key=lambda k: sum(cost_hits[k]))
        for n, ok in zip(counts, cost_hits[best]):
            row[f"cost_ok_{n}"] = ok
            if not ok:
                failed.append(f"cost {best} at N={n}: {100 * (g.at[n, COST_READINGS[best]] / paper.cells[n]['cost'] - 1.0):+.2f} % "
                              f"(band ±{100 * scale.cost_relative:g} %)")
        passed += sum(cost_hits[best])
        row["failed"] = "; ".join(failed)
        row["cost_reading"] = best if all(cost_hits[best]) else "none"
        row["checks_passed"], row["checks"] = passed, 3 * len(counts)
        row["reproduces"] = passed == 3 * len(counts)
        row["mean_safety"] = float(np.mean([g.at[n, "safety"] for n in counts]))
        out.append(row)
    return pd.DataFrame(out)


def claim_verdict(judged: pd.DataFrame, protocol: tuple[str, str, float]) -> dict:
    """The Table II claim's verdict from judged readings; ``protocol`` = (study, run, horizon_s) of
    the protocol's own reading. ``{"verdict", "protocol", "protocol_reproduces", "reproducing", "closest",
    "readings_judged", "judged"}`` (each reading: study, run, horizon_s, checks_passed, checks, cost_reading, failed)."""
    if judged.empty:
        raise ValueError("no reading has a cell at every agent count of Table II")
    key = judged[["study", "run", "horizon_s"]].apply(tuple, axis=1)
    proto = judged[key == tuple(protocol)]
    if proto.empty:
        raise ValueError(f"the protocol's reading {protocol} is not among the judged readings")
    hits = judged[judged["reproduces"]]
    name = lambda r: {"study": r["study"], "run": r["run"], "horizon_s": float(r["horizon_s"]),   # noqa: E731
                      "checks_passed": int(r["checks_passed"]), "checks": int(r["checks"]), "cost_reading": r["cost_reading"],
                      "failed": str(r["failed"])}
    closest = judged.sort_values(["checks_passed", "mean_safety"], ascending=False).iloc[0]
    if bool(proto["reproduces"].iloc[0]):
        verdict = VERDICTS[0]
    elif len(hits):
        verdict = VERDICTS[1]
    else:
        verdict = VERDICTS[2]
    return {"verdict": verdict, "protocol": name(proto.iloc[0]), "protocol_reproduces": bool(proto["reproduces"].iloc[0]),
            "reproducing": [name(r) for _, r in hits.iterrows()], "closest": name(closest),
            "readings_judged": int(len(judged)),
            "judged": [{**name(r), "reproduces": bool(r["reproduces"]), "pattern": str(r["pattern"])} for _, r in judged.iterrows()]}


def law_rule(anchor: pd.DataFrame, large: pd.DataFrame, anchor_n: int, scale: Scale = SCALE) -> pd.DataFrame:
    """§1 of the plan, one row per large-arena cell (study, run, N, seed) of scenario rows ``large``:
    its load and hazard with interval, the same seed's anchor cell (``anchor_n`` agents; pooled over
    the anchor's seeds where that seed has none), ``load_matched`` and the rule's reading
    ("behaves like Table I", "harder per encounter", "undetermined at this sample size"; empty when
    the load is not matched)."""
    ref = {}
    pooled = cell_hazard(anchor[anchor["n_agents"] == anchor_n])
    for seed, g in anchor[anchor["n_agents"] == anchor_n].groupby("seed"):
        ref[int(seed)] = cell_hazard(g)
    rows = []
    for (study, run, n, seed), g in large.groupby(["study", "run", "n_agents", "seed"], sort=False):
        h, a = cell_hazard(g), ref.get(int(seed), pooled)
        matched = abs(h["encounters_per_agent"] / a["encounters_per_agent"] - 1.0) <= scale.load_window
        reading = ""
        if matched:
            overlap = h["low"] <= a["high"] and a["low"] <= h["high"]
            ratio = h["hazard"] / a["hazard"] if a["hazard"] > 0 else float("inf")
            if ratio <= scale.hazard_factor and 1.0 / scale.hazard_factor <= ratio and overlap:
                reading = "behaves like Table I"
            elif ratio > scale.hazard_factor and not overlap:
                reading = "harder per encounter"
            else:
                reading = "undetermined at this sample size"
        rows.append({"study": study, "run": run, "n_agents": int(n), "seed": int(seed),
                     "pattern": str(g["pattern"].iloc[0]), "encounters_per_agent": h["encounters_per_agent"], "safety": h["safety_rate"],
                     "hazard": h["hazard"], "hazard_lo": h["low"], "hazard_hi": h["high"],
                     "anchor_load": a["encounters_per_agent"], "anchor_hazard": a["hazard"],
                     "anchor_lo": a["low"], "anchor_hi": a["high"], "load_matched": bool(matched), "reading": reading})
    return pd.DataFrame(rows)


def law_reading(rule: pd.DataFrame) -> str:
    """The §1 rule over all load-matched cells: their one shared reading, "mixed: …" when they
    disagree, or "no large-arena cell at the anchor's load"."""
    readings = sorted(set(rule.loc[rule["load_matched"], "reading"]))
    if not readings:
        return "no large-arena cell at the anchor's load"
    return readings[0] if len(readings) == 1 else "mixed: " + "; ".join(readings)


BASELINE_READINGS = ("hard for MAD-PINN alone", "hard for every method tried")


def baseline_reading(rows: pd.DataFrame, paper: PaperRow, scale: Scale = SCALE) -> dict:
    """Item 4's rule (fixed before the cells, docs/findings/2026-11-29-table-ii-grid-plan.md): the
    baselines' :func:`reading_rows` at their episode length; a baseline *reaches Table II's safety*
    when its safety ≥ the paper's − 2 points at every paper N. ``{"reading", "reaching": [run, ...]}``:
    "hard for MAD-PINN alone" when some baseline reaches it, else "hard for every method tried"."""
    reaching = []
    for run, g in rows.groupby("run", sort=False):
        g = g[g["horizon_s"] == g["horizon_s"].max()].set_index("n_agents")
        if set(paper.cells) <= set(g.index) and all(
                g.at[n, "safety"] >= c["safety"] - scale.safety_points - 1e-12 for n, c in paper.cells.items()):
            reaching.append(str(run))
    return {"reading": BASELINE_READINGS[0] if reaching else BASELINE_READINGS[1], "reaching": reaching}
