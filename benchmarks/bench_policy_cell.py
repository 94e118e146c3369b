"""A 256-agent large-arena MAD-PINN cell, today's code paths vs issue 37's, back to back in one process.

Real episodes (scenarios of a validation seed, default 100; ``sim.dt`` 2.5 ms, policy every step,
value-based neighbours every 5 steps, ``z_tolerance`` 1e-3, shipped models, no look-ahead) on the
**double-integrator backend** (MuJoCo was 3 % of a 256-agent cell's time in the profile of
docs/reference/performance.md; the policy is the same), episodes shortened to ``--episode-s`` (the protocol's
are 6 s), torch one thread. Variants, each the same scenarios from the same starts:

- ``old``: V_s on every in-domain pair in unpadded chunks, ``torch.topk`` selection (the code
  before issue 37), the protocol's z search (``config.yaml``: the cold bisection since 2026-11-26)
  as it was before issue 48 (:func:`zsearch_reference.reference_cold_search`: every halving on
  every agent, the terminal term recomputed at each);
- ``neighbours``: bounded V_s scoring (:func:`pair_scores_bounded`, the ``value`` default now), the
  protocol's z search as the package runs it now (the halvings of agents infeasible at z_max
  skipped, the terminal term's z-independent parts once per step) — the protocol's cell, same
  answers as ``old`` (checked bitwise below);
- ``warm``: bounded scoring and the warm-started z search (``warm_start: true``, a speed option that
  changes answers where V̂ is not monotone in z);
- ``newton``: bounded scoring and the Newton-stepped warm search (:func:`newton_search.newton_policy`).

Prints policy time (wall, as the evaluation cells' ``policy_us_per_agent_step``) and CPU time
(of the episode's thread; torch runs on it) per agent-step, V̂ rows per agent-step and, per
scenario, collided agents, mean cost and minimum separation, and whether they are identical to
``old``'s. Last line: ``madpinn_cell_speedup_at_256: Z`` (old episode CPU time / ``neighbours`` —
the whole episode, simulation and collision checks included, and robust to other jobs on a shared
machine, unlike wall time, which is printed too; the selector's one-off margin calibration, ≈ 1–2 s
per job, is not in it). The variants run one after the other, or with ``--lockstep K`` K policy
steps each in turn (:mod:`lockstep`), so that a shared machine's drifting load weighs on all of them
alike.

The ceiling for identical answers: the z search's own time inside the ``neighbours`` episode is
timed too. Replacing it with the floor of :mod:`zsearch_floor` gives the time of a cell whose
search costs nothing beyond the V̂ rows the paper's bisection cannot skip: the network rows alone,
at the fastest measured speed of this core, with no boundary term, indexing or Python. The line
``madpinn_cell_speedup_ceiling_at_256: C`` prints ``old`` ÷ that time. No implementation with the
bisection's answers gets above C on this machine without making the network or the rest of the
cell faster. It also prints how many of those rows a bound on the network's output would certify
without evaluating them (:func:`zsearch_floor.certifiable_rows`, every 20th search of the episode).

``--arena small --agents 12`` runs the same comparison in Table I's arena (the last lines keep
their names).

    PYTHONPATH=$PWD python benchmarks/bench_policy_cell.py --scenarios 2 --episode-s 1.0 [--variants old neighbours] [--lockstep 20]
"""

from __future__ import annotations

from contextlib import nullcontext
from dataclasses import replace

import argparse
import threading
import time

import numpy as np
import torch

from madpinn.dynamics import DoubleIntegrator
from madpinn.config import REPO_ROOT, load_config
from madpinn.observation import ObservationSettings
from madpinn.policies.madpinn import MadPinnPolicy, MadPinnSettings
from madpinn.policies.neighbours import in_domain, make_selector, select_lowest
from madpinn.scenarios import Arena, generate_scenarios
from madpinn.simulation import run_episode
from madpinn.simulation.backend import DoubleIntegratorBackend
from madpinn.value_functions import load_vhat, load_vs
from madpinn.value_functions.z_search import bisection_steps
import madpinn.policies.madpinn as madpinn_policy
from lockstep import run_in_lockstep   # benchmarks/lockstep.py
from newton_search import newton_policy   # benchmarks/newton_search.py
from zsearch_floor import certifiable_rows, floor_us_per_agent_step, row_costs_us   # benchmarks/zsearch_floor.py
from zsearch_reference import reference_cold_search   # benchmarks/zsearch_reference.py

PAPER = load_config([REPO_ROOT / "config.yaml"])   # settings of the paper config (no code defaults)
SPEC = ObservationSettings.from_config(PAPER).base_mapping()
BASE_SETTINGS = MadPinnSettings.from_config(PAPER["methods"]["madpinn"])
DT = 0.0025
ARENAS = {name: float(a["half_width"]) for name, a in PAPER["arenas"].items()}   # half widths (m)


def old_selector(vs, n: int, chunk: int = 65536):
    """The ``value`` selector before issue 37: every in-domain pair, unpadded chunks, ``topk``."""

    def select(state):
        S, N, _ = state.shape
        mask = in_domain(state, vs.system.p_range, vs.system.v_range, vs.system.agent)
        s_idx, i_idx, j_idx = mask.nonzero(as_tuple=True)
        x = state[s_idx, i_idx] - state[s_idx, j_idx]
        scores = torch.full((S, N, N), float("inf"), dtype=state.dtype, device=state.device)
        if x.shape[0]:
            scores[s_idx, i_idx, j_idx] = torch.cat([vs.value(x[i : i + chunk], 0.0).to(x.dtype)
                                                     for i in range(0, x.shape[0], chunk)])
        return select_lowest(scores, n)

    return select


VARIANTS = ("old", "neighbours", "warm", "newton")
# the policy's cold z searches in each thread's current episode (timed wrapper below): the search
# run (the package's, or the reference for ``old``), CPU seconds of the thread, calls, and (obs,
# grid) of every 20th call, for certifiable_rows
_cold_search = madpinn_policy.cold_search
SEARCHES: dict[int, dict] = {}


def _timed_cold_search(vhat, obs, grid, *args, **kwargs):
    log = SEARCHES[threading.get_ident()]
    t0 = time.thread_time()
    try:
        return log["search"](vhat, obs, grid, *args, **kwargs)
    finally:
        log["cpu"] += time.thread_time() - t0
        log["calls"] += 1
        if log["calls"] % 20 == 0:
            log["kept"].append((obs.clone(), grid))


madpinn_policy.cold_search = _timed_cold_search


def episode(vhat, vs, variant: str, starts, goals, steps: int):
    """``run(wrap)``: the variant's episode with the policy ``wrap(policy)`` (policy and selector
    built here, outside it), returning the figures :func:`main` prints."""
    if variant == "old":
        selector, settings = old_selector(vs, SPEC.n_neighbours), BASE_SETTINGS
    else:
        selector = make_selector("value", SPEC.n_neighbours, vs=vs)   # includes the margin calibration
        settings = BASE_SETTINGS if variant == "neighbours" else replace(BASE_SETTINGS, warm_start=True)
    pol = MadPinnPolicy(vhat, selector, SPEC, settings, DT)
    backend = DoubleIntegratorBackend(DoubleIntegrator(u_max=4.0, v_max=4.0), DT)

    def run(wrap) -> dict:
        log = SEARCHES[threading.get_ident()] = dict(search=reference_cold_search if variant == "old" else _cold_search,
                                                     cpu=0.0, calls=0, kept=[])
        cpu = time.thread_time()
        with newton_policy() if variant == "newton" else nullcontext():
            result, stats = run_episode(backend, wrap(pol), starts, goals, steps, SPEC.collision_radius, progress=False)
        cpu = time.thread_time() - cpu
        agent_steps = steps * starts.shape[0] * starts.shape[1]
        s = MadPinnPolicy.summarise_stats(pol.stats)
        return {"result": result, "policy_us": 1e6 * stats["policy_s"] / agent_steps, "cpu_us": 1e6 * cpu / agent_steps,
                "wall_s": stats["wall_s"],
                "rows": s["vhat_evals_per_agent_step"], "hit": s["warm_hit_rate"],
                "search_us": 1e6 * log["cpu"] / agent_steps, "infeasible": s["infeasible_fraction"],
                "searches": log["kept"]}

    return run


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--vhat", default="models/vhat.pt")
    ap.add_argument("--vs", default="models/vs.pt")
    ap.add_argument("--agents", type=int, default=256)
    ap.add_argument("--arena", choices=sorted(ARENAS), default="large",
                    help="large: half width 4 m (Table II); small: 1 m (Table I and the ablations)")
    ap.add_argument("--scenarios", type=int, default=2)
    ap.add_argument("--episode-s", type=float, default=1.0)
    ap.add_argument("--seed", type=int, default=100, help="scenario seed (validation seeds are ≥ 100)")
    ap.add_argument("--variants", nargs="+", choices=VARIANTS, default=list(VARIANTS),
                    help="variants to run (old and neighbours always run: the last lines compare them)")
    ap.add_argument("--lockstep", type=int, default=0, metavar="STEPS",
                    help="run the variants' episodes in lockstep, STEPS policy steps each in turn (benchmarks/lockstep.py): "
                         "the same machine load for every variant; wall times then include the waits")
    args = ap.parse_args()
    if args.lockstep and "newton" in args.variants:
        raise SystemExit("--lockstep cannot run the newton variant (it swaps the policy's search for every thread)")
    if args.seed < 100:
        raise SystemExit(f"use a validation seed (≥ 100), not {args.seed}")
    torch.set_num_threads(1)
    vhat, vs = load_vhat(args.vhat), load_vs(args.vs)
    arena = Arena(args.arena, ARENAS[args.arena], args.episode_s)
    starts, goals = generate_scenarios(arena, args.agents, args.seed, args.scenarios, 2 * SPEC.collision_radius)
    steps = int(round(args.episode_s / DT))
    print(f"{args.agents} agents, {args.arena} arena, {args.scenarios} scenarios of seed {args.seed}, {steps} steps "
          f"({args.episode_s} s), double integrator, torch 1 thread", flush=True)
    variants = [v for v in VARIANTS if v in {"old", "neighbours", *args.variants}]
    with torch.no_grad():
        runs = {v: episode(vhat, vs, v, starts, goals, steps) for v in variants}
        if args.lockstep:
            runs = dict(zip(variants, (r for r, _ in run_in_lockstep(list(runs.values()), args.lockstep))))
        else:
            runs = {v: run(lambda policy: policy) for v, run in runs.items()}
        for variant, r in runs.items():
            res = r["result"]
            print(f"{variant:10s}: episode wall {r['wall_s']:6.1f} s, policy {r['policy_us']:7.1f} us/agent-step "
                  f"(episode CPU {r['cpu_us']:7.1f}), "
                  f"V̂ rows/agent-step {r['rows']:.3f}, warm hits {r['hit']:.3f}", flush=True)
            for s in range(args.scenarios):
                print(f"    scenario {s}: collided agents {int(res.collided[s].sum())}, mean cost {res.cost[s].mean():.6f}, "
                      f"min separation {res.min_separation[s].min():.6f} m", flush=True)
    base = runs["old"]["result"]
    for variant in variants[1:]:
        res = runs[variant]["result"]
        same = all(np.array_equal(getattr(res, f), getattr(base, f))
                   for f in ("cost", "collided", "min_separation", "final_distance"))
        print(f"{variant} vs old: per-scenario metrics identical: {same}; max |cost difference| "
              f"{np.abs(res.cost - base.cost).max():.3e}, collided agents {int(res.collided.sum())} vs {int(base.collided.sum())}, "
              f"speedup: episode CPU {runs['old']['cpu_us'] / runs[variant]['cpu_us']:.2f}, episode wall "
              f"{runs['old']['wall_s'] / runs[variant]['wall_s']:.2f}, policy wall "
              f"{runs['old']['policy_us'] / runs[variant]['policy_us']:.2f}", flush=True)
    new = runs["neighbours"]
    value_us, grad_us = row_costs_us(vhat, args.agents * args.scenarios)
    floor = floor_us_per_agent_step(value_us, grad_us, bisection_steps(BASE_SETTINGS.z_tolerance), new["infeasible"])
    rest = new["cpu_us"] - new["search_us"]
    certified = [certifiable_rows(vhat, obs, grid) for obs, grid in new["searches"]]
    print(f"neighbours: value rows per agent-step whose sign the network's output bound certifies without a row: "
          f"{sum(certified) / max(1, len(certified)):.4f} (every 20th search of the episode, {len(certified)} searches)")
    print(f"neighbours: cold z search {new['search_us']:.1f} us/agent-step of {new['cpu_us']:.1f} (CPU; "
          f"infeasible share {new['infeasible']:.3f}); the rows it cannot skip: value row {value_us:.3f} us, "
          f"gradient row {grad_us:.3f} us at batch {args.agents * args.scenarios} -> floor {floor:.1f} us/agent-step; "
          f"rest of the episode {rest:.1f} us/agent-step")
    print(f"cold z search / its floor: neighbours {new['search_us'] / floor:.2f}, old {runs['old']['search_us'] / floor:.2f} "
          f"(old: {runs['old']['search_us']:.1f} us/agent-step)")
    print(f"madpinn_cell_speedup_at_256: {runs['old']['cpu_us'] / new['cpu_us']:.2f}")
    print(f"madpinn_cell_speedup_ceiling_at_256: {runs['old']['cpu_us'] / (rest + floor):.2f}")


if __name__ == "__main__":
    main()
