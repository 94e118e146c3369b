"""Physical-contact reading (issue 47): safety counted where the drones' bodies touch.

The protocol counts a collision at centre distance d ≤ r and the tables add the disc reading
d ≤ 2r (:mod:`madpinn.evaluation.metrics`). A referee also asks when two airframes physically
touch: the CF2X collision cylinders of the cited simulator (radius 0.06 m,
:data:`madpinn.simulation.mujoco.model.COLLISION_CYLINDER`) meet at d ≤ 0.12 m. Every cell already
stores each agent's minimum separation over the episode (``agent_min_separation``), so this reading
needs no new episodes: it is read from those separations with :func:`madpinn.separation.safe_at`,
the comparison the recorder makes. Result files without the separations give NaN.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from madpinn.evaluation.metrics import bootstrap_interval
from madpinn.separation import safe_at

SCENARIO_COLUMNS = ("safety_rate_contact", "safe_contact")
"""per-scenario columns :func:`with_contact` adds: fraction of agents and whether all agents stayed above the contact distance"""
SEED_METRICS = ("safety_rate_contact", "safe_scenarios_contact")
"""seed figures :func:`seed_contact` returns (means over scenarios)"""


def contact_distance() -> float:
    """Centre distance (m) at which two level Crazyflies' collision cylinders touch: twice the
    cylinder radius of the MuJoCo model (0.12 m)."""
    from madpinn.simulation.mujoco.model import COLLISION_CYLINDER

    return 2.0 * float(COLLISION_CYLINDER[0])


def with_contact(df: pd.DataFrame, distance: float | None = None) -> pd.DataFrame:
    """``df`` (scenario rows of result files) with :data:`SCENARIO_COLUMNS` added, read at centre
    distance ``distance`` (m; default :func:`contact_distance`); NaN where a row holds no
    per-agent separations."""
    out = df.copy()
    if "agent_min_separation" not in df:
        for col in SCENARIO_COLUMNS:
            out[col] = np.nan
        return out
    d = contact_distance() if distance is None else float(distance)
    rates, alls = [], []
    for sep in df["agent_min_separation"]:
        if sep is None or len(sep) == 0:
            rates.append(np.nan)
            alls.append(np.nan)
            continue
        safe = safe_at(np.asarray(sep), d)
        rates.append(float(safe.mean()))
        alls.append(float(safe.all()))
    out["safety_rate_contact"], out["safe_contact"] = rates, alls
    return out


def seed_contact(df: pd.DataFrame) -> dict:
    """One seed's contact figures from its scenario rows (with :data:`SCENARIO_COLUMNS`): means over
    scenarios, and the 95 % bootstrap interval of the safety rate over scenarios (as
    :func:`madpinn.evaluation.metrics.scenario_intervals` gives the other readings)."""
    rate = df["safety_rate_contact"].to_numpy(dtype=float)
    lo, hi = bootstrap_interval(rate)
    mean = lambda v: float(np.nanmean(v)) if np.isfinite(v).any() else float("nan")   # noqa: E731
    return {"safety_rate_contact": mean(rate), "safe_scenarios_contact": mean(df["safe_contact"].to_numpy(dtype=float)),
            "safety_rate_contact_ci_lo": lo, "safety_rate_contact_ci_hi": hi}
