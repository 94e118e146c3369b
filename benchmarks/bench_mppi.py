"""Time one MPPI control step for 1 600 agents (100 scenarios × 16, small arena) with the
configured K and H, against a per-agent Python loop over the same planner.

    PYTHONPATH=$PWD python benchmarks/bench_mppi.py [--config config.yaml] [--repeats 5]

Prints best-of-N figures; the last line is ``ms_per_step_1600_agents: X``. The per-agent loop
plans agent by agent (batch of one, its own warm start) for ``--loop-agents`` agents and is
extrapolated linearly to 1 600 agents (it is too slow to time in full).
"""

from __future__ import annotations

import argparse
import time

import torch

from madpinn.config import load_config, method_config
from madpinn.device import resolve_device, resolve_dtype
from madpinn.observation import ObservationSettings, build_observation, nearest_neighbours, split_observation
from madpinn.policies import PolicyContext, make_policy, policy_settings
from madpinn.scenarios import Arena, generate_scenarios
from madpinn.settings import AgentSettings


def build(cfg, device, dtype, seed=0):
    _, mcfg = method_config(cfg, "mppi")
    ctx = PolicyContext(
        method=policy_settings("mppi", mcfg), dynamics=AgentSettings.from_config(cfg).dynamics(),
        obs_spec=ObservationSettings.from_config(cfg), device=device, dtype=dtype, seed=seed,
        sim_dt=cfg["sim"]["dt"], policy_period=int(mcfg.get("policy_period_steps", 1)),
    )
    return make_policy("mppi", ctx), mcfg


def best_time(fn, repeats: int, sync) -> float:
    fn()  # warm-up
    best = float("inf")
    for _ in range(repeats):
        sync()
        t0 = time.perf_counter()
        fn()
        sync()
        best = min(best, time.perf_counter() - t0)
    return best


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--config", nargs="+", default=["config.yaml"])
    ap.add_argument("--scenarios", type=int, default=100)
    ap.add_argument("--agents", type=int, default=16)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--loop-agents", type=int, default=32, help="agents timed in the per-agent loop")
    ap.add_argument("--threads", type=int, default=1)
    args = ap.parse_args(argv)
    torch.set_num_threads(args.threads)

    cfg = load_config(args.config)
    device, dtype = resolve_device(cfg["device"]), resolve_dtype(cfg["dtype"])
    sync = torch.cuda.synchronize if device.type == "cuda" else (lambda: None)
    arena = Arena.from_config(cfg, "small")
    starts, goals = generate_scenarios(arena, args.agents, 0, args.scenarios, cfg["sim"]["start_separation"], device, dtype)
    # mid-flight state: agents moving towards their goals at 1 m/s
    heading = torch.nn.functional.normalize(goals - starts, dim=-1)
    state = torch.cat([starts, heading], dim=-1)
    total = args.scenarios * args.agents

    policy, mcfg = build(cfg, device, dtype)
    policy.reset(state, goals)
    clock = {"t": 0.0}

    def batched():
        clock["t"] += cfg["sim"]["dt"]
        policy.act(state, goals, clock["t"])

    t_batch = best_time(batched, args.repeats, sync)

    # Per-agent loop: the same planner with a batch of one per agent (its own plan and warm
    # start); each agent builds its own observation from its scenario, then plans.
    spec = ObservationSettings.from_config(cfg)
    n = spec.n_neighbours
    m = min(args.loop_agents, total)
    rows = [(i // args.agents, i % args.agents) for i in range(m)]
    planners = []
    for i in range(m):
        p, _ = build(cfg, device, dtype, seed=i)
        p.planner.reset(1, device, dtype)
        planners.append(p.planner)
    loop_clock = {"t": 0.0}

    def per_agent():
        loop_clock["t"] += cfg["sim"]["dt"]
        for planner, (s, a) in zip(planners, rows):
            st, gl = state[s : s + 1], goals[s : s + 1]
            nbr = nearest_neighbours(spec.agent.position(st), n, radius=spec.sensing_radius)
            pos, vel, gr = split_observation(build_observation(st, gl, nbr, spec)[:, a], n)
            planner.plan(vel[:, 0], gr[:, 0], pos[:, 1:], vel[:, 1:], nbr[:, a] >= 0, loop_clock["t"])

    t_loop = best_time(per_agent, max(1, args.repeats // 2), sync) * total / m

    ms_batch, ms_loop = 1e3 * t_batch, 1e3 * t_loop
    print(f"device: {device}, threads: {args.threads}, dtype: {dtype}")
    print(f"K = {mcfg['samples']}, H = {mcfg['horizon']}, plan_dt = {mcfg['plan_dt']} s, agents = {total} "
          f"({args.scenarios} scenarios x {args.agents})")
    print(f"batched: {ms_batch:.1f} ms per control step ({1e6 * t_batch / total:.1f} us per agent)")
    print(f"per-agent loop: {ms_loop:.1f} ms per control step (timed on {m} agents, extrapolated)")
    print(f"speed-up of batching: {ms_loop / ms_batch:.1f}x")
    print(f"ms_per_step_1600_agents: {ms_batch:.1f}" if total == 1600 else f"ms_per_step_{total}_agents: {ms_batch:.1f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
