"""Print the oracle cost bounds of a scenario set and what a short receding horizon alone costs.

    python scripts/oracle_bounds.py --arena small --n-agents 12 --seed 0 --scenarios 10 --dt 0.05 0.025 --rh

For each grid step h: the mean over scenarios of the lower bound (the oracle row of the tables)
and of the feasible upper bound (their difference bounds the discretisation gap); with --rh the
closed-loop cost of a lone agent re-planning over 0.2 s every 0.025 s (madpinn.evaluation.oracle).
Arena sizes and episode lengths are read from --config (default config.yaml).
"""

from __future__ import annotations

import argparse
import time

import numpy as np
import yaml

from madpinn.evaluation.oracle import OracleSettings, lower_bound, receding_horizon_cost, upper_bound
from madpinn.scenarios import Arena, generate_scenario


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--config", default="config.yaml")
    p.add_argument("--arena", default="small")
    p.add_argument("--n-agents", type=int, default=12)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--scenarios", type=int, default=10)
    p.add_argument("--dt", type=float, nargs="+", default=[0.05, 0.025])
    p.add_argument("--rh", action="store_true", help="also the 0.2 s receding-horizon cost")
    a = p.parse_args()
    cfg = yaml.safe_load(open(a.config))
    arena = Arena.from_config(cfg, a.arena)
    r, u, v = cfg["agents"]["collision_radius"], cfg["agents"]["u_max"], cfg["agents"]["v_max"]
    off = np.concatenate([np.subtract(*generate_scenario(arena, a.n_agents, a.seed, i, cfg["sim"]["start_separation"])) for i in range(a.scenarios)])
    T = arena.episode_s
    print(f"{a.arena} arena, N={a.n_agents}, seed {a.seed}, scenarios 0..{a.scenarios - 1} ({len(off)} agents), T = {T} s")
    for h in a.dt:
        s = OracleSettings(horizon_s=T, u_max=u, v_max=v, dt=h)
        t0 = time.perf_counter()
        lb, ub = lower_bound(off, s).mean(), upper_bound(off, s).mean()
        print(f"  h = {h:g} s: lower bound {lb:.4f} (÷T {lb / T:.4f}), feasible upper bound {ub:.4f}, gap {ub - lb:.4f}"
              f"  [{time.perf_counter() - t0:.0f} s]")
    if a.rh:
        t0 = time.perf_counter()
        rh = receding_horizon_cost(off, T, horizon_s=0.2, dt=0.025, u_max=u, v_max=v)
        print(f"  0.2 s receding horizon (re-planned every 0.025 s), lone agents: {rh.mean():.4f} (÷T {rh.mean() / T:.4f})"
              f"  [{time.perf_counter() - t0:.0f} s]")


if __name__ == "__main__":
    main()
