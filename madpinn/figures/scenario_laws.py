"""fig_scenario_laws (issue 60 item 1, not in the paper): does the large arena at Table I's load behave
like Table I? The paper's deployment only (the readings' protocol run), every start/goal law and
Table I's anchor. Left: safety against straight-line encounters per agent, one point per cell (per
N and seed, 95 % bootstrap interval over scenarios), both arenas on one axis, Table I's anchor
in open markers. Right: the collided share of agents against their encounter
speed (relative speed to the nearest agent at the first collision, else at the closest approach;
95 % Wilson intervals), per law and for the anchor."""

from __future__ import annotations

from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd

from madpinn.evaluation.encounter_hazard import hazard_by_speed
from madpinn.evaluation.metrics import bootstrap_interval
from madpinn.evaluation.table_ii_page import SPEED_EDGES
from madpinn.evaluation.table_ii_settings import ReadingsSettings
from madpinn.figures import style

N_MARKERS = ("o", "s", "D", "^", "v", "P")
ANCHOR = "Table I's setting (anchor)"
LOAD_TICKS = (0.25, 0.5, 1, 2, 4, 8, 16)
"""encounters per agent on the left panel's log axis"""


def law_cells(frame: pd.DataFrame) -> pd.DataFrame:
    """One row per (study, pattern, N, seed) of scenario rows ``frame``: mean encounters per agent and
    safety with its 95 % bootstrap interval over scenarios."""
    out = []
    for (study, pattern, n, seed), g in frame.groupby(["study", "pattern", "n_agents", "seed"], sort=False):
        lo, hi = bootstrap_interval(g["safety_rate"].to_numpy(dtype=float))
        out.append({"study": study, "pattern": pattern, "n_agents": int(n), "seed": int(seed),
                    "encounters_per_agent": float(g["encounters_per_agent"].mean()),
                    "safety": float(g["safety_rate"].mean()), "safety_lo": lo, "safety_hi": hi})
    return pd.DataFrame(out)


def draw_scenario_laws(anchor: pd.DataFrame, large: pd.DataFrame, settings: ReadingsSettings):
    """The figure from :func:`madpinn.evaluation.table_ii_page.load_frames`' anchor and large-arena rows."""
    style.setup()
    run = settings.protocol[1]
    groups = {ANCHOR: anchor[anchor["run"] == run]}
    groups.update({f"large arena, {p}": g for p, g in large[large["run"] == run].groupby("pattern", sort=False)})
    colours = dict(zip(groups, ["black", *style.palette([k for k in groups if k != ANCHOR]).values()]))
    counts = sorted({int(n) for g in groups.values() for n in g["n_agents"].unique()})
    markers = {n: N_MARKERS[i % len(N_MARKERS)] for i, n in enumerate(counts)}
    fig, (left, right) = plt.subplots(1, 2, figsize=(11.5, 4.4))
    for name, g in groups.items():
        if g.empty:
            continue
        cells = law_cells(g)
        for c in cells.itertuples():
            left.errorbar(c.encounters_per_agent, 100 * c.safety,
                          yerr=np.clip([[100 * (c.safety - c.safety_lo)], [100 * (c.safety_hi - c.safety)]], 0.0, None),
                          fmt=markers[c.n_agents], color=colours[name], ms=6, capsize=2, mfc="white" if name == ANCHOR else colours[name])
        h = hazard_by_speed(g, SPEED_EDGES, settings.collision_radius)
        h = h[h["agents"] > 0]
        mid = [(lo + (hi if np.isfinite(hi) else lo + 2.0)) / 2 for lo, hi in zip(h["speed_low"], h["speed_high"])]
        err = np.clip([h["hazard"] - h["low"], h["high"] - h["hazard"]], 0.0, None)   # Wilson bounds can sit a rounding below 0
        right.errorbar(mid, h["hazard"], yerr=err, fmt="o-", color=colours[name],
                       capsize=2, label=name)
    left.set_xscale("log")
    left.set_xticks(LOAD_TICKS, [f"{t:g}" for t in LOAD_TICKS])
    left.minorticks_off()
    left.set_xlabel("straight-line encounters per agent (log)")
    left.set_ylabel("safety (%)")
    left.set_title("safety against load, one point per cell")
    right.set_xlabel("encounter speed (m/s; bin midpoints, the last bin open)")
    right.set_ylabel("collided share of agents")
    right.set_title("collisions against encounter speed")
    from matplotlib.lines import Line2D

    handles = [Line2D([], [], color=c, lw=2, label=k) for k, c in colours.items() if not groups[k].empty]
    handles += [Line2D([], [], marker=m, ls="none", color="0.3", label=f"N = {n}") for n, m in markers.items()]
    fig.legend(handles=handles, loc="lower center", ncol=4, frameon=False, fontsize=8)
    seeds = ", ".join(str(int(x)) for x in sorted({*anchor["seed"].unique(), *large["seed"].unique()}))
    fig.suptitle(f"Start/goal laws at Table I's load ({settings.labels.get(run, run)}; seeds {seeds}; not in the paper)")
    fig.tight_layout(rect=(0, 0.14, 1, 1))
    return fig


def plot_scenario_laws(anchor: pd.DataFrame, large: pd.DataFrame, settings: ReadingsSettings, out_prefix: str | Path) -> list[Path]:
    """Write ``<out_prefix>.pdf`` and ``.png``; returns both paths."""
    return style.save(draw_scenario_laws(anchor, large, settings), out_prefix)
