"""Time of the deployment's neighbour selection per agent and update, N = 3 … 256 (issue 61): the
paper's "The neighbor selection process takes 1.2 ms per agent" and its O(N) (tex 346, 467).

Per agent count of the protocol (Table I's in the small arena, Table II's in the large), states are
the starts of validation scenarios (seed :data:`SEED`) with every agent flying at :data:`SPEED`
towards its goal. Two selectors: the deployment's (``value``: lowest V_s within the sensing radius,
:func:`madpinn.policies.neighbours.make_selector`) and the paper's account, V_s on all N − 1
partners of every agent (``T_i = (N − 1) T_s``, tex 346). Torch on one thread, best of ``repeats``
of CPU time. The exponent is the least-squares slope of log(time per agent) on log N, with its 95 %
t-interval; the hardware is named in the output.
"""

from __future__ import annotations

import json
import math
import platform
import time
from pathlib import Path
from typing import Mapping

SEED = 100
"""validation scenario seed (never a protocol seed)"""
SPEED = 1.0
"""m/s: every agent's speed towards its goal in the timed states"""
STUDIES = ("main", "scaling")
"""the studies whose (arena, agent counts) are timed: Tables I and II"""


def cpu_name() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def states(cfg: Mapping, arena: str, n: int, count: int):
    """``[count, n, 4]`` states: scenario starts, velocity :data:`SPEED` towards the goal."""
    import torch

    from madpinn.scenarios import Arena, generate_scenarios

    starts, goals = generate_scenarios(Arena.from_config(cfg, arena), n, SEED, count, cfg["sim"]["start_separation"])
    heading = goals - starts
    v = SPEED * heading / heading.norm(dim=-1, keepdim=True).clamp_min(1e-9)
    return torch.cat([starts, v], dim=-1)


def fit_exponent(ns: list[int], ms: list[float]) -> dict:
    """Slope of log(ms) on log(n) with its 95 % t-interval (None with fewer than 3 points)."""
    from scipy.stats import linregress, t

    if len(ns) < 3:
        return {"exponent": None, "lo": None, "hi": None}
    fit = linregress([math.log(n) for n in ns], [math.log(m) for m in ms])
    half = float(t.ppf(0.975, len(ns) - 2)) * fit.stderr
    return {"exponent": fit.slope, "lo": fit.slope - half, "hi": fit.slope + half}


def measure(cfg: Mapping, vs, count: int = 2, repeats: int = 3) -> dict:
    """``{"rows": [{arena, n, <selector>: ms per agent}], "fit": {selector: {...}}, "hardware": str, ...}``."""
    import torch

    from madpinn.policies.neighbours import make_selector, value_selector

    torch.set_num_threads(1)
    n_nb = int(cfg["observation"]["n_neighbours"])
    selectors = {"deployment": make_selector("value", n_nb, vs=vs, radius=float(cfg["observation"]["sensing_radius"])),
                 "all pairs": value_selector(vs, n_nb, pruned=False)}
    rows = []
    with torch.no_grad():
        for study in STUDIES:
            st = cfg["studies"][study]
            for n in st["agent_counts"]:
                s = states(cfg, st["arena"], int(n), count)
                row = {"arena": st["arena"], "n": int(n)}
                for name, select in selectors.items():
                    select(s)   # warm-up
                    best = float("inf")
                    for _ in range(repeats):
                        t0 = time.process_time()
                        select(s)
                        best = min(best, time.process_time() - t0)
                    row[name] = 1e3 * best / (count * int(n))
                rows.append(row)
    return {"rows": rows, "unit": "ms per agent per neighbour update",
            "fit": {name: fit_exponent([r["n"] for r in rows], [r[name] for r in rows]) for name in selectors},
            "hardware": f"{cpu_name()}, torch {torch.__version__}, 1 thread (CPU time)",
            "states": f"{count} scenario starts per N, validation seed {SEED}, {SPEED:g} m/s towards the goals",
            "selectors": {"deployment": "lowest V_s within observation.sensing_radius (the protocol's)",
                          "all pairs": "V_s on all N − 1 partners of every agent (the paper's T_i = (N − 1) T_s)"}}


def write_timing(cfg: Mapping, vs_path: str | Path, out: str | Path, count: int = 2, repeats: int = 3) -> list[Path]:
    from madpinn.value_functions import load_vs

    band = bool(cfg["methods"]["madpinn"]["vs_band"])   # required in the schema
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(measure(cfg, load_vs(vs_path, band=band), count, repeats), indent=2))
    return [out]
