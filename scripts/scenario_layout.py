"""What our scenario generator puts in the large arena, against plausible alternatives (issue 33 item 2).

    python scripts/scenario_layout.py [--seed 100] [--scenarios 20] [--counts 64 128 256]

The paper says only "20 distinct initial conditions" in [−4, 4]². Our generator (SPEC §2,
``madpinn/scenarios.py``) draws starts and goals uniformly with pairwise separation ≥ 2r among
starts and among goals. For each agent count this prints, over the scenarios of a validation seed:
density, the straight-line trip length (goal distance), the nearest start neighbour, and the
number of *straight-line encounters* per agent — pairs whose constant-speed straight paths (both
at the same speed, leaving together) come within 2r, the conflicts the policy must resolve — for
our layout and three alternatives a reader might assume:

- ``ours``: uniform starts and goals, separation ≥ 2r (0.2 m);
- ``sep0.5``: the same with separation ≥ 0.5 m (a sparser, "drone-sized" spacing);
- ``swap``: goals are a random permutation of the starts (every goal is another agent's start);
- ``short``: goals uniform within 2 m of the start (clipped to the arena; trips the small arena's length).
"""

from __future__ import annotations

import argparse

import numpy as np

from madpinn.config import REPO_ROOT, load_config
from madpinn.encounters import straight_line_encounters as encounters
from madpinn.scenarios import Arena, ScenarioInfeasibleError, _sample_separated, generate_scenario, scenario_rng

LAYOUTS = ("ours", "sep0.5", "swap", "short")


def layout(name: str, arena: Arena, n: int, seed: int, index: int, r: float) -> tuple[np.ndarray, np.ndarray]:
    """``(starts [N, 2], goals [N, 2])`` of scenario ``index`` under layout ``name`` (m)."""
    if name == "ours":
        return generate_scenario(arena, n, seed, index, 2 * r)
    rng = scenario_rng(arena.name + "/" + name, n, seed, index)
    hw = arena.half_width
    if name == "sep0.5":
        return _sample_separated(rng, n, hw, 0.5), _sample_separated(rng, n, hw, 0.5)
    starts = _sample_separated(rng, n, hw, 2 * r)
    if name == "swap":
        return starts, starts[rng.permutation(n)]
    if name == "short":
        return starts, np.clip(starts + rng.uniform(-2.0, 2.0, size=(n, 2)), -hw, hw)
    raise ValueError(f"unknown layout '{name}' (have {LAYOUTS})")


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--seed", type=int, default=100)
    p.add_argument("--scenarios", type=int, default=20)
    p.add_argument("--counts", type=int, nargs="+", default=[64, 128, 256])
    args = p.parse_args()
    cfg = load_config([REPO_ROOT / "config.yaml"])
    arena = Arena.from_config(cfg, "large")
    r, vmax = cfg["agents"]["collision_radius"], cfg["agents"]["v_max"]
    print(f"large arena ±{arena.half_width} m, episode {arena.episode_s} s, r = {r} m, seed {args.seed}, "
          f"{args.scenarios} scenarios; encounters: straight lines at {vmax} m/s, within 2r")
    print("| N | layout | agents/m² | trip length mean (p10–p90) m | nearest start mean (min) m | encounters per agent mean (p90) |")
    print("|---|---|---|---|---|---|")
    for n in args.counts:
        for name in LAYOUTS:
            trips, near, enc = [], [], []
            try:
                drawn = [layout(name, arena, n, args.seed, i, r) for i in range(args.scenarios)]
            except ScenarioInfeasibleError as exc:   # e.g. 0.5 m spacing of 256 agents jams the sampler
                print(f"| {n} | {name} | {n / (2 * arena.half_width) ** 2:.1f} | infeasible: {exc} | | |")
                continue
            for s, g in drawn:
                trips.append(np.linalg.norm(g - s, axis=1))
                dist = np.linalg.norm(s[:, None] - s[None], axis=-1)
                np.fill_diagonal(dist, np.inf)
                near.append(dist.min(1))
                enc.append(encounters(s, g, vmax, 2 * r, arena.episode_s))
            trips, near, enc = np.concatenate(trips), np.concatenate(near), np.concatenate(enc)
            print(f"| {n} | {name} | {n / (2 * arena.half_width) ** 2:.1f} | {trips.mean():.2f} "
                  f"({np.quantile(trips, 0.1):.2f}–{np.quantile(trips, 0.9):.2f}) | {near.mean():.3f} ({near.min():.3f}) | "
                  f"{enc.mean():.2f} ({np.quantile(enc, 0.9):.0f}) |")


if __name__ == "__main__":
    main()
