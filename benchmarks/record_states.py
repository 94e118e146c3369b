"""Record global states ``[N, 4]`` at neighbour updates of real MAD-PINN episodes (double integrator).

The states that :mod:`madpinn.policies.neighbours` scores in deployment: the selector is wrapped
and every ``keep_every``-th update's state is kept. Cells: 256 agents in the large arena and 16 in
the small arena (validation seeds ≥ 100 only), shipped models, ``config.yaml``'s deployment
(value neighbours every 5 steps, warm z search, ``z_tolerance`` 1e-3; no look-ahead).

    PYTHONPATH=$PWD python benchmarks/record_states.py --out /tmp/states.pt

Writes ``{"large": [K, 256, 4], "small": [K', 16, 4], "meta": {...}}`` (float32).
"""

from __future__ import annotations

import argparse
import time

import torch

from madpinn.dynamics import DoubleIntegrator
from madpinn.config import REPO_ROOT, load_config
from madpinn.observation import ObservationSettings
from madpinn.policies.madpinn import MadPinnPolicy, MadPinnSettings
from madpinn.policies.neighbours import make_selector
from madpinn.scenarios import Arena, generate_scenarios
from madpinn.simulation import run_episode
from madpinn.simulation.backend import DoubleIntegratorBackend
from madpinn.value_functions import load_vhat, load_vs

PAPER = load_config([REPO_ROOT / "config.yaml"])   # settings of the paper config (no code defaults)
SPEC = ObservationSettings.from_config(PAPER).base_mapping()
BASE_SETTINGS = MadPinnSettings.from_config(PAPER["methods"]["madpinn"])
DT = 0.0025


def record(vhat, vs, n_agents: int, arena: Arena, seed: int, scenarios: int, keep_every: int) -> torch.Tensor:
    """States ``[K, N, 4]`` at every ``keep_every``-th neighbour update of ``scenarios`` episodes."""
    if seed < 100:
        raise ValueError(f"record states on validation seeds (≥ 100), got {seed}")
    inner = make_selector("value", SPEC.n_neighbours, vs=vs)
    kept, calls = [], [0]

    def selector(state):
        if calls[0] % keep_every == 0:
            kept.append(state.detach().clone().to(torch.float32))
        calls[0] += 1
        return inner(state)

    starts, goals = generate_scenarios(arena, n_agents, seed, scenarios, 2 * SPEC.collision_radius)
    pol = MadPinnPolicy(vhat, selector, SPEC, BASE_SETTINGS, DT)
    backend = DoubleIntegratorBackend(DoubleIntegrator(u_max=4.0, v_max=4.0), DT)
    run_episode(backend, pol, starts, goals, int(round(arena.episode_s / DT)), SPEC.collision_radius, progress=False)
    return torch.cat(kept)  # each kept state is [S, N, 4]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--vhat", default="models/vhat.pt")
    ap.add_argument("--vs", default="models/vs.pt")
    ap.add_argument("--out", required=True)
    ap.add_argument("--seed", type=int, default=100)
    ap.add_argument("--large", type=int, nargs=3, default=[2, 800, 10], metavar=("SCENARIOS", "STEPS", "KEEP_EVERY"))
    ap.add_argument("--small", type=int, nargs=3, default=[20, 1200, 10], metavar=("SCENARIOS", "STEPS", "KEEP_EVERY"))
    args = ap.parse_args()
    torch.set_num_threads(1)
    vhat, vs = load_vhat(args.vhat), load_vs(args.vs)
    out = {"meta": {"seed": args.seed, "vhat": args.vhat, "vs": args.vs, "large": args.large, "small": args.small}}
    with torch.no_grad():
        for name, N, hw, (S, steps, keep) in (("large", 256, 4.0, args.large), ("small", 16, 1.0, args.small)):
            t = time.perf_counter()
            out[name] = record(vhat, vs, N, Arena(name, hw, steps * DT), args.seed, S, keep)
            print(f"{name}: {tuple(out[name].shape)} states in {time.perf_counter() - t:.1f} s", flush=True)
    torch.save(out, args.out)


if __name__ == "__main__":
    main()
