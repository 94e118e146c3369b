"""Paired effects: a run against a reference run on the same scenarios (per-scenario differences of
safety and cost ÷T with paired bootstrap intervals), the Table II readings page's "what each choice
moves" (issue 60) and the calibrated level's page (issue 62)."""

from __future__ import annotations

import numpy as np
import pandas as pd

from madpinn.evaluation.intervals import PAIR_KEYS, paired_bootstrap
from madpinn.evaluation.metrics import COST_COLUMNS

# Scenario rows of two cells under the same start/goal law pair on PAIR_KEYS: a scenario is a pure function of
# (arena, law, N, seed, index) (:mod:`madpinn.scenarios`), so a pair is one layout under two deployments.


EFFECT_COLUMNS = ["study", "run", "reference", "pattern", "n_agents", "pairs",
                  "d_safety", "d_safety_lo", "d_safety_hi", "safety_pairs",
                  "d_cost_time_avg", "d_cost_time_avg_lo", "d_cost_time_avg_hi", "cost_time_avg_pairs"]
"""the columns of :func:`paired_effects`, in order"""


def paired_effects(frame: pd.DataFrame, reference_run: str) -> pd.DataFrame:
    """What each run moves against ``reference_run``, on the same scenarios: every (study, run) of the
    scenario rows ``frame`` (with their ``pattern``: the start/goal law) other than ``reference_run``, paired
    per scenario (:data:`PAIR_KEYS`) with ``reference_run`` under the same start/goal law (the same
    study where it holds that run, else another study of that law), at the episode's end. One row
    per (study, run, N): the pairs, Δ safety and Δ cost ÷T (collision-free agents), run − reference,
    with 95 % paired bootstrap intervals over scenarios (seeds pooled). Scenarios without a partner
    are left out (``pairs`` counts the rest), and so, per figure, are pairs where either side lacks it
    (cost over collision-free agents is NaN in a scenario where every agent collided;
    ``<figure>_pairs`` counts what each Δ rests on). The straight-line encounters cannot check the pairing:
    they are counted at the run's own v_max."""
    ref_rows = frame[frame["run"] == reference_run]
    cost = COST_COLUMNS["cost_time_avg"]
    out = []
    for (study, run), g in frame[frame["run"] != reference_run].groupby(["study", "run"], sort=False):
        pattern = g["pattern"].iloc[0]
        ref = ref_rows[ref_rows["pattern"] == pattern]
        if ref.empty:
            continue
        ref_study = ref["study"].iloc[0] if study not in set(ref["study"]) else study
        ref = ref[ref["study"] == ref_study]
        keys = list(PAIR_KEYS)
        pairs = g.drop_duplicates(keys).merge(ref.drop_duplicates(keys), on=keys, suffixes=("", "_ref"))
        for n, p in pairs.groupby("n_agents", sort=True):
            row = {"study": study, "run": run, "reference": f"{ref_study}/{reference_run}", "pattern": pattern,
                   "n_agents": int(n), "pairs": len(p)}
            for name, col in (("safety", "safety_rate"), ("cost_time_avg", cost)):
                a, b = p[col].to_numpy(dtype=float), p[f"{col}_ref"].to_numpy(dtype=float)
                both = np.isfinite(a) & np.isfinite(b)   # paired: scenarios where both sides have the figure
                a, b = a[both], b[both]
                row[f"d_{name}"] = float(np.mean(a - b)) if both.any() else float("nan")
                row[f"d_{name}_lo"], row[f"d_{name}_hi"] = paired_bootstrap(a, b) if both.any() else (float("nan"),) * 2
                row[f"{name}_pairs"] = int(both.sum())
            out.append(row)
    return pd.DataFrame(out, columns=EFFECT_COLUMNS)   # the columns even when nothing pairs
