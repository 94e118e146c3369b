"""95 % intervals of the reported figures and paired differences between runs (issue 47).

**Cells with several seeds**: a Student-t interval over the per-seed figures,
mean ± t(0.975, k−1) · s / √k over k seeds. The seed is the protocol's independent replicate (the
paper reports mean ± std over 5 seeds): it draws the scenarios and seeds every stochastic policy
(MPPI's samples) of its cell, so the spread between seeds carries every source of variation and
the interval assumes nothing about the scenarios inside one seed. A bootstrap over seeds ×
scenarios would need a two-level resampling scheme, and a percentile bootstrap over 5 seeds
under-covers; the t-interval is the usual, slightly conservative choice for k = 5. Rates are
clipped to [0, 1]. k seeds that agree exactly give a zero-width interval.

**Cells with one seed** keep the percentile bootstrap over scenarios
(:func:`madpinn.evaluation.metrics.bootstrap_interval`).

**Paired differences** (run − reference, e.g. a baseline − Ours) use the same scenarios: result
rows are matched on (arena, N, seed, scenario index), scenarios being a pure function of those
(:mod:`madpinn.scenarios`). With ≥ 2 common seeds, the difference of the two runs' seed figures on
their common scenarios, then a t-interval over seeds; with one seed, a paired percentile bootstrap
over scenarios (the same resampled indices for both runs).
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

from madpinn.evaluation.metrics import CI_LEVEL, CI_RESAMPLES

SCENARIO_COLUMN = {"safety_rate": "safety_rate", "safe_scenarios": "safe", "cost_time_avg": "cost_safe_time_avg",
                   "cost": "cost_safe_mean", "cost_all_time_avg": "cost_all_time_avg",
                   "safety_rate_2r": "safety_rate_2r", "safe_scenarios_2r": "safe_2r",
                   "safety_rate_contact": "safety_rate_contact", "safe_scenarios_contact": "safe_contact"}
"""seed figure -> the per-scenario column it is the (NaN-aware) mean of"""
INTERVAL_METRICS = ("safety_rate", "safe_scenarios", "cost_time_avg", "safety_rate_2r", "safety_rate_contact")
"""seed figures that get a 95 % interval in every table and in the report"""
DIFF_METRICS = INTERVAL_METRICS
"""seed figures whose paired difference (run − reference) the report gives"""
PAIR_KEYS = ("arena", "n_agents", "seed", "scenario")
"""what makes two result rows the same scenario"""
T_METHOD, BOOTSTRAP_METHOD = "t over seeds", "bootstrap over scenarios"


def is_rate(metric: str) -> bool:
    return metric.startswith(("safety_rate", "safe_scenarios"))


def t_interval(values, level: float = CI_LEVEL) -> tuple[float, float]:
    """Student-t interval of the mean of the finite ``values`` (NaN, NaN with fewer than two)."""
    from scipy.stats import t

    v = np.asarray(values, dtype=float)
    v = v[np.isfinite(v)]
    if v.size < 2:
        return float("nan"), float("nan")
    half = float(t.ppf(0.5 + level / 2.0, v.size - 1)) * float(v.std(ddof=1)) / math.sqrt(v.size)
    return float(v.mean()) - half, float(v.mean()) + half


def paired_bootstrap(a, b, level: float = CI_LEVEL, resamples: int = CI_RESAMPLES, seed: int = 0) -> tuple[float, float]:
    """Percentile bootstrap interval of nanmean(a) − nanmean(b) over paired scenarios ``a[S]``,
    ``b[S]`` (row s of both is scenario s): each resample draws the same S indices for both; a
    fixed generator, so the same rows give the same interval. Resamples where either side has no
    finite value are skipped."""
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    if a.shape != b.shape or a.size == 0:
        return float("nan"), float("nan")
    idx = np.random.default_rng(seed).integers(0, a.size, size=(resamples, a.size))

    def means(v):
        d = v[idx]
        fin = np.isfinite(d)
        n = fin.sum(1)
        return np.where(n > 0, np.where(fin, d, 0.0).sum(1) / np.maximum(n, 1), np.nan)

    diff = means(a) - means(b)
    diff = diff[np.isfinite(diff)]
    if diff.size == 0:
        return float("nan"), float("nan")
    q = (1.0 - level) / 2.0
    return float(np.quantile(diff, q)), float(np.quantile(diff, 1.0 - q))


def seed_figures(seeds: pd.DataFrame, keys: list[str], metrics=INTERVAL_METRICS) -> pd.DataFrame:
    """Per group of ``keys`` of per-seed rows (:func:`madpinn.evaluation.tables.per_seed`):
    ``{m}_mean``, ``{m}_std`` (ddof 1; 0 with one seed) and the 95 % interval ``{m}_ci_lo``,
    ``{m}_ci_hi`` of each metric: t over seeds with ≥ 2 seeds, else the seed's own bootstrap
    interval over scenarios (its ``{m}_ci_*`` columns), NaN where neither exists."""
    rows = []
    for group, g in seeds.groupby(keys, sort=False):
        group = group if isinstance(group, tuple) else (group,)
        row = dict(zip(keys, group))
        for m in metrics:
            vals = g[m].to_numpy(dtype=float) if m in g else np.full(len(g), np.nan)
            fin = np.isfinite(vals)
            row[f"{m}_mean"] = float(vals[fin].mean()) if fin.any() else float("nan")
            row[f"{m}_std"] = float(vals[fin].std(ddof=1)) if fin.sum() > 1 else 0.0
            if fin.sum() > 1:
                lo, hi = t_interval(vals)
                if is_rate(m):
                    lo, hi = max(lo, 0.0), min(hi, 1.0)
            elif len(g) == 1 and f"{m}_ci_lo" in g:
                lo, hi = float(g[f"{m}_ci_lo"].iloc[0]), float(g[f"{m}_ci_hi"].iloc[0])
            else:
                lo = hi = float("nan")
            row[f"{m}_ci_lo"], row[f"{m}_ci_hi"] = lo, hi
        rows.append(row)
    return pd.DataFrame(rows)


def interval_method(n_seeds: int) -> str:
    return T_METHOD if n_seeds >= 2 else BOOTSTRAP_METHOD


def paired_differences(df: pd.DataFrame, reference: str, metrics=DIFF_METRICS) -> pd.DataFrame:
    """Run − ``reference`` on the same scenarios, for every other run and agent count of the
    scenario rows ``df`` (result files, with the contact columns of
    :func:`madpinn.evaluation.contact.with_contact` for ``safety_rate_contact``). One row per
    (run, n_agents): ``{m}_diff``, ``{m}_diff_lo``, ``{m}_diff_hi``, ``n_seeds`` (common seeds),
    ``n_pairs`` (common scenarios), ``interval`` (:data:`T_METHOD` or :data:`BOOTSTRAP_METHOD`).
    Runs sharing no scenario with the reference are left out."""
    keys = [k for k in PAIR_KEYS if k in df]
    cols = {m: SCENARIO_COLUMN[m] for m in metrics if SCENARIO_COLUMN[m] in df}
    ref = df[df["run"] == reference]
    if ref.empty:
        return pd.DataFrame()
    ref = ref[keys + list(cols.values())].drop_duplicates(keys)
    rows = []
    for (run, n), g in df[df["run"] != reference].groupby(["run", "n_agents"], sort=False):
        both = g[keys + list(cols.values())].drop_duplicates(keys).merge(ref, on=keys, suffixes=("", "_ref"))
        if both.empty:
            continue
        seeds = sorted(both["seed"].unique())
        row = {"run": str(run), "n_agents": int(n), "reference": reference, "n_seeds": len(seeds),
               "n_pairs": int(len(both)), "interval": interval_method(len(seeds))}
        for m, col in cols.items():
            a, b = both[col].to_numpy(dtype=float), both[f"{col}_ref"].to_numpy(dtype=float)
            if len(seeds) >= 2:
                per = []
                for s in seeds:
                    sel = (both["seed"] == s).to_numpy()
                    per.append(_nanmean(a[sel]) - _nanmean(b[sel]))
                per = np.asarray(per)
                diff = float(np.nanmean(per)) if np.isfinite(per).any() else float("nan")
                lo, hi = t_interval(per)
            else:
                diff = _nanmean(a) - _nanmean(b)
                lo, hi = paired_bootstrap(a, b)
            row[f"{m}_diff"], row[f"{m}_diff_lo"], row[f"{m}_diff_hi"] = diff, lo, hi
        rows.append(row)
    return pd.DataFrame(rows)


def _nanmean(v: np.ndarray) -> float:
    return float(np.nanmean(v)) if np.isfinite(v).any() else float("nan")
