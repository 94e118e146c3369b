"""One full MAD-PINN control step (neighbour update + z* search + control) for all agents.

For N ∈ {16, 64, 256, 1024} at the density of 256 agents in the large arena ([-4, 4]², 4 agents/m²;
64 and 128 agents there are 1 and 2/m²; half width 4·√(N/256) m), one scenario, mid-episode velocities uniform in [-2, 2] m/s:

- ``batched``: :class:`madpinn.policies.madpinn.MadPinnPolicy` — all agents in one batch, V_s only
  on the in-domain pairs the bounds cannot exclude (issue 37; before it: all in-domain pairs, as in
  the tables of docs/reference/performance.md dated before 2026-11-26), warm-started bisection (a step right after a warm-up step, with the
  neighbour update included);
- ``batched_plain``: the same batch without pruning and without warm start (cold bisection);
- ``look_ahead``: the overhead (%) of the actuator-lag compensation (``look_ahead: 0.075``, the
  config default; :mod:`madpinn.policies.look_ahead`) over ``batched``, per step of a 20-step
  double-integrator rollout (the state must move: on a frozen state the own prediction flips with
  each bang-bang command and the warm start misses, which no episode does);
- ``per_agent``: what the paper describes, agent by agent: V_s on its N−1 pairs in one batch, the 2
  lowest, its 3-agent observation, 10-halving bisection on V̂ (batch of 1), ∇V̂, bang-bang control.
  Timed on ``min(N, 64)`` agents (the per-agent cost does not depend on which agent) and
  reported per agent.

Prints per-agent times per N, the growth exponent of the batched step time from 64 to 1024
agents and, last, ``speedup_vs_per_agent_at_256: X`` (per-agent loop time / batched time).

    PYTHONPATH=$PWD python benchmarks/bench_policy.py [--vhat results/models/vhat.pt --vs results/models/vs.pt]

Without model files, freshly initialised networks of the paper architecture (3×256 SIREN) are
timed (the cost does not depend on the weights, only the warm-start hit rate does).
"""

from __future__ import annotations

from dataclasses import replace

import argparse
import math
import tempfile
import time
from pathlib import Path

import torch

from madpinn.config import REPO_ROOT, load_config
from madpinn.observation import ObservationSettings, build_observation
from madpinn.policies.madpinn import MadPinnPolicy, MadPinnSettings
from madpinn.policies.neighbours import in_domain, make_selector, pair_scores_brute_force, select_lowest
from madpinn.scenarios import Arena, generate_scenarios
from madpinn.value_functions import load_vhat, load_vs
from madpinn.value_functions.z_search import bisection_steps
from newton_search import cold_budget_search  # benchmarks/newton_search.py
from timing import best_of  # benchmarks/timing.py

PAPER = load_config([REPO_ROOT / "config.yaml"])   # settings of the paper config (no code defaults)
SPEC = ObservationSettings.from_config(PAPER).base_mapping()
BASE_SETTINGS = MadPinnSettings.from_config(PAPER["methods"]["madpinn"])
NET = {"hidden": 256, "layers": 3, "first_omega": 30.0, "hidden_omega": 30.0}


def models(vhat_path: str | None, vs_path: str | None, tmp: Path):
    if vhat_path and vs_path and Path(vhat_path).is_file() and Path(vs_path).is_file():
        return load_vhat(vhat_path), load_vs(vs_path), "trained"
    from madpinn.value_functions.epigraph import EpigraphSystem
    from madpinn.dynamics.pair import PairSystem
    from madpinn.value_functions.model import build_network, model_payload, save_atomic
    from madpinn.value_functions.problems import EpigraphProblem, PairProblem

    torch.manual_seed(0)
    sysv = EpigraphSystem.from_config(PAPER)
    for name, problem in (("vhat", EpigraphProblem(sysv)), ("vs", PairProblem(PairSystem.from_config(PAPER)))):
        save_atomic(model_payload(problem, build_network(problem, NET), 1.0, {}), tmp / f"{name}.pt")
    return load_vhat(tmp / "vhat.pt"), load_vs(tmp / "vs.pt"), "untrained (paper architecture)"


def layout(N: int, seed: int = 0):
    hw = 4.0 * math.sqrt(N / 256.0)
    starts, goals = generate_scenarios(Arena("bench", hw, 1.0), N, seed, 1, 0.2, torch.device("cpu"), torch.float32)
    vel = 4.0 * torch.rand(1, N, 2, generator=torch.Generator().manual_seed(seed)) - 2.0
    return torch.cat([starts, vel], -1), goals, hw



def batched_step_time(vhat, vs, state, goals, pruned: bool, warm: bool, repeats: int) -> float:
    """Seconds for one control step that includes a neighbour update (after a warm-up step)."""
    settings = replace(BASE_SETTINGS, strategy="value", update_every=1, warm_start=warm)
    sel = make_selector("value", 2, vs=vs) if pruned else (lambda s: select_lowest(pair_scores_brute_force(s, vs), 2))
    pol = MadPinnPolicy(vhat, sel, SPEC, settings, sim_dt=0.0025)
    pol.reset(state, goals)
    with torch.no_grad():
        pol.act(state, goals, 0.0)
        return best_of(lambda: pol.act(state, goals, 0.0025), repeats)


def rollout_step_time(vhat, vs, state, goals, look_ahead: float, repeats: int, steps: int = 20) -> float:
    """Seconds per control step over a ``steps``-step double-integrator rollout (dt 2.5 ms, after
    three warm-up steps), best of ``repeats`` rollouts from the same state."""
    settings = replace(BASE_SETTINGS, strategy="value", update_every=5, warm_start=True, look_ahead=look_ahead)
    pol = MadPinnPolicy(vhat, make_selector("value", 2, vs=vs), SPEC, settings, sim_dt=0.0025)
    dt = 0.0025

    def run(k0: int, n: int, x: torch.Tensor) -> torch.Tensor:
        for k in range(k0, k0 + n):
            u = pol.act(x, goals, k * dt)
            x = torch.cat([x[..., :2] + x[..., 2:] * dt + 0.5 * u * dt**2, (x[..., 2:] + u * dt).clamp(-4, 4)], -1)
        return x

    def rollout():
        pol.reset(state, goals)
        x = run(0, 3, state)
        t0 = time.perf_counter()
        run(3, steps, x)
        return time.perf_counter() - t0

    with torch.no_grad():
        return min(rollout() for _ in range(repeats)) / steps


def per_agent_time(vhat, vs, state, goals, agents: int, repeats: int) -> float:
    """Seconds per agent of the paper's agent-by-agent step."""
    N = state.shape[1]
    steps = bisection_steps(1e-3)
    nbrs = torch.tensor([[[1, 2], [0, 2], [0, 1]]])

    def one(i: int):
        others = torch.cat([torch.arange(i), torch.arange(i + 1, N)])
        x = state[0, i] - state[0, others]
        v = vs.value(x, 0.0)
        pick = others[torch.topk(v, 2, largest=False).indices]
        local = torch.cat([state[0, i : i + 1], state[0, pick]])[None]
        lg = torch.cat([goals[0, i : i + 1], goals[0, pick]])[None]
        obs = build_observation(local, lg, nbrs, SPEC)[:, 0]
        z, _ = cold_budget_search(vhat, obs, steps)
        _, grad, _ = vhat.value_and_grad(obs, z, 0.0)
        return -vhat.system.u_max * torch.sign(grad[:, 0:2])

    with torch.no_grad():
        return best_of(lambda: [one(i) for i in range(agents)], repeats) / agents


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--vhat", default="results/models/vhat.pt")
    ap.add_argument("--vs", default="results/models/vs.pt")
    ap.add_argument("--counts", type=int, nargs="+", default=[16, 64, 256, 1024])
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--threads", type=int, default=1)
    args = ap.parse_args()
    torch.set_num_threads(args.threads)
    with tempfile.TemporaryDirectory() as tmp:
        vhat, vs, kind = models(args.vhat, args.vs, Path(tmp))
        print(f"models: {kind}; torch threads: {args.threads}; best of {args.repeats}")
        batched, speedup = {}, {}
        for N in args.counts:
            state, goals, hw = layout(N)
            cand = int(in_domain(state, vs.system.p_range, vs.system.v_range, vs.system.agent).sum()) / N
            tb = batched_step_time(vhat, vs, state, goals, True, True, args.repeats)
            tp = batched_step_time(vhat, vs, state, goals, False, False, args.repeats)
            la = rollout_step_time(vhat, vs, state, goals, 0.075, args.repeats) / rollout_step_time(vhat, vs, state, goals, 0.0, args.repeats)
            tl = per_agent_time(vhat, vs, state, goals, min(N, 64), max(1, args.repeats - 1))
            batched[N] = tb
            speedup[N] = tl * N / tb
            print(f"N={N:5d} half_width={hw:5.2f}m vs_pairs_per_agent={cand:6.1f}/{N - 1:<5d} "
                  f"batched={1e6 * tb / N:8.1f}us/agent ({1e3 * tb:8.2f}ms/step) "
                  f"look_ahead={100 * (la - 1):+5.1f}% "
                  f"batched_plain={1e6 * tp / N:8.1f}us/agent per_agent_loop={1e6 * tl:9.1f}us/agent "
                  f"speedup={speedup[N]:7.1f}x", flush=True)
        if 64 in batched and 1024 in batched:
            print(f"batched_step_growth_exponent_64_to_1024: {math.log(batched[1024] / batched[64]) / math.log(16):.3f}")
        if 256 in speedup:
            print(f"speedup_vs_per_agent_at_256: {speedup[256]:.1f}")


if __name__ == "__main__":
    main()
