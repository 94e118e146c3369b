"""V̂ evaluations per agent-step of the MAD-PINN z* search, warm vs cold, in closed-loop episodes.

Real episodes on the double integrator (``sim.dt`` 2.5 ms, policy every step, value-based
neighbours updated every 5 steps, ``z_tolerance`` 1e-3 as in config.yaml) for two cells:
12 agents in the small arena (3 s) and 64 agents in the large arena (6 s), scenarios of a
validation seed (default 100, never the protocol seeds 0–4).

For each cell the episode runs twice, warm-started (:func:`madpinn.policies.z_search.warm_search`)
and cold (the paper's bisection), and prints per agent-step: V̂ network rows (all, and with
gradient; the cold search needs 1 + steps + 1 = 12), the warm hit rate, policy CPU time
(process time, so other jobs on the machine do not count), and the episode outcomes of both
runs (collided agents, mean cost). With ``--verify`` every warm step also runs the cold search on
the same observations and counts answers that differ (index, feasibility), and how many of
those rows have a V̂ that is not monotone in z between the two answers. With ``--newton`` a third
run uses the Newton-stepped search (:func:`newton_search.newton_policy`,
:func:`newton_search.newton_search`, benchmarks/newton_search.py), and every step of the warm run also runs the
Newton search on the same observations and prediction, counting its rows and the answers that
differ from the warm search's (index, feasibility; V̂ not monotone in between).

    PYTHONPATH=$PWD python benchmarks/bench_zsearch.py --vhat results/models/vhat.pt --vs results/models/vs.pt --verify

Last line: ``warm_vhat_evals_per_agent_step: X`` (mean over the cells); with ``--newton`` also
``newton_vhat_evals_per_agent_step: Y``.
"""

from __future__ import annotations

from contextlib import nullcontext
from dataclasses import replace

import argparse
import time

import torch

from madpinn.dynamics import DoubleIntegrator
from madpinn.config import REPO_ROOT, load_config
from madpinn.observation import ObservationSettings, build_observation
from madpinn.policies.madpinn import MadPinnPolicy, MadPinnSettings
from madpinn.policies.neighbours import make_selector
from madpinn.policies.z_search import predict_index
from madpinn.scenarios import Arena, generate_scenarios
from madpinn.simulation import run_episode
from madpinn.simulation.backend import DoubleIntegratorBackend
from madpinn.value_functions import load_vhat, load_vs
from madpinn.value_functions.z_search import ZGrid, cold_search
from newton_search import newton_policy, newton_search   # benchmarks/newton_search.py

PAPER = load_config([REPO_ROOT / "config.yaml"])   # settings of the paper config (no code defaults)
SPEC = ObservationSettings.from_config(PAPER).base_mapping()
BASE_SETTINGS = MadPinnSettings.from_config(PAPER["methods"]["madpinn"])
DT = 0.0025
CELLS = {"small": (12, Arena("small", 1.0, 3.0)), "large": (64, Arena("large", 4.0, 6.0))}


class VerifiedPolicy(MadPinnPolicy):
    """Warm-started policy that also runs the cold search on every step's observations."""

    def reset(self, state, goals):
        super().reset(state, goals)
        self.check = {"rows": 0, "index_diff": 0, "feasible_diff": 0, "diff_not_monotone": 0}

    def act(self, state, goals, t):
        u = super().act(state, goals, t)
        S, N, _ = state.shape
        obs = build_observation(state, goals, self.neighbours, self.spec).reshape(S * N, -1)
        grid = ZGrid.of(self.vhat.z_max, self.settings.z_tolerance)
        cold, warm = cold_search(self.vhat, obs, grid), self.last_search
        diff = (cold.index != warm.index).nonzero(as_tuple=True)[0]
        self.check["rows"] += obs.shape[0]
        self.check["index_diff"] += int(diff.numel())
        self.check["feasible_diff"] += int((cold.feasible != warm.feasible).sum())
        for i in diff.tolist():  # V̂ on the grid between the two answers: not non-increasing?
            a, b = sorted((int(cold.index[i]), int(warm.index[i])))
            idx = torch.arange(max(a - 1, 1), b + 1)
            v = self.vhat.value(obs[i].expand(idx.numel(), -1), grid.z(idx, obs.dtype), 0.0)
            self.check["diff_not_monotone"] += int(bool((v[1:] > v[:-1]).any()))
        return u


class NewtonComparedPolicy(MadPinnPolicy):
    """Warm-started policy that also runs the Newton search on every warm step's observations and prediction."""

    def reset(self, state, goals):
        super().reset(state, goals)
        self.check = {"rows": 0, "warm_rows": 0, "newton_rows": 0, "index_diff": 0, "feasible_diff": 0,
                      "diff_not_monotone": 0}

    def act(self, state, goals, t):
        grid = ZGrid.of(self.vhat.z_max, self.settings.z_tolerance)
        pred = None if self._k_last is None else predict_index(self._k_last, self._k_before, grid.cells)
        u = super().act(state, goals, t)
        S, N, _ = state.shape
        if pred is None or pred.shape[0] != S * N:
            return u
        obs = build_observation(state, goals, self.neighbours, self.spec).reshape(S * N, -1)
        warm, new = self.last_search, newton_search(self.vhat, obs, grid, pred)
        c = self.check
        c["rows"] += obs.shape[0]
        c["warm_rows"] += warm.value_rows + warm.grad_rows
        c["newton_rows"] += new.value_rows + new.grad_rows
        diff = (new.index != warm.index).nonzero(as_tuple=True)[0]
        c["index_diff"] += int(diff.numel())
        c["feasible_diff"] += int((new.feasible != warm.feasible).sum())
        for i in diff.tolist():
            a, b = sorted((int(new.index[i]), int(warm.index[i])))
            idx = torch.arange(max(a - 1, 1), b + 1)
            v = self.vhat.value(obs[i].expand(idx.numel(), -1), grid.z(idx, obs.dtype), 0.0)
            c["diff_not_monotone"] += int(bool((v[1:] > v[:-1]).any()))
        return u


def run_cell(vhat, vs, N: int, arena: Arena, scenarios: int, seed: int, warm: bool, verify: bool,
             newton: bool = False, compare_newton: bool = False) -> dict:
    starts, goals = generate_scenarios(arena, N, seed, scenarios, 2 * SPEC.collision_radius)
    cls = VerifiedPolicy if (warm and verify) else MadPinnPolicy
    if warm and compare_newton and not newton:
        cls = NewtonComparedPolicy
    pol = cls(vhat, make_selector("value", SPEC.n_neighbours, vs=vs), SPEC,
              replace(BASE_SETTINGS, warm_start=warm), DT)
    t_search = time.process_time()
    backend = DoubleIntegratorBackend(DoubleIntegrator(u_max=4.0, v_max=4.0), DT)
    # policy CPU time: run_episode times the policy in wall time; we take process time around it
    steps = int(round(arena.episode_s / DT))
    with newton_policy() if newton else nullcontext():
        result, stats = run_episode(backend, pol, starts, goals, steps, SPEC.collision_radius, progress=False)
    cpu = time.process_time() - t_search
    s = MadPinnPolicy.summarise_stats(pol.stats)
    out = {"evals": s["vhat_evals_per_agent_step"], "grad_evals": s["vhat_grad_evals_per_agent_step"],
           "hit": s["warm_hit_rate"], "infeasible": s["infeasible_fraction"],
           "cpu_us_per_agent_step": 1e6 * cpu / (steps * scenarios * N),
           "policy_wall_share": stats["policy_s"] / stats["wall_s"],
           "collided_agents": int(result.collided.sum()), "cost": float(result.cost.mean()), "result": result}
    if hasattr(pol, "check"):
        out["check"] = pol.check
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--vhat", default="results/models/vhat.pt")
    ap.add_argument("--vs", default="results/models/vs.pt")
    ap.add_argument("--cells", nargs="+", default=["small", "large"], choices=sorted(CELLS))
    ap.add_argument("--scenarios", type=int, nargs=2, default=[20, 2], metavar=("SMALL", "LARGE"))
    ap.add_argument("--seed", type=int, default=100, help="scenario seed (validation seeds are ≥ 100)")
    ap.add_argument("--episode-s", type=float, default=None, help="shorter episodes than the arenas' (s)")
    ap.add_argument("--verify", action="store_true", help="also run the cold search at every warm step")
    ap.add_argument("--newton", action="store_true", help="also run the Newton-stepped search (and compare it per step)")
    ap.add_argument("--threads", type=int, default=1)
    args = ap.parse_args()
    torch.set_num_threads(args.threads)
    vhat, vs = load_vhat(args.vhat), load_vs(args.vs)
    print(f"models: {args.vhat} {args.vs}; torch threads {args.threads}; seed {args.seed}; CPU process time; "
          f"episodes {args.episode_s or 'of the arenas'} s")
    means: dict = {}
    with torch.no_grad():
        for name in args.cells:
            N, arena = CELLS[name]
            if args.episode_s:
                arena = Arena(arena.name, arena.half_width, args.episode_s)
            S = args.scenarios[0 if name == "small" else 1]
            runs = {}
            variants = [("warm", True, False), ("cold", False, False)] + ([("newton", True, True)] if args.newton else [])
            for label, warm, newton in variants:
                if args.verify and args.newton and label == "warm":
                    raise SystemExit("--verify and --newton: run them separately")
                r = runs[label] = run_cell(vhat, vs, N, arena, S, args.seed, warm, args.verify, newton, args.newton)
                print(f"{name:5s} N={N:3d} S={S:3d} {label}: vhat_evals/agent-step={r['evals']:6.3f} "
                      f"(with grad {r['grad_evals']:.3f}) hit={r['hit']:.3f} infeasible={r['infeasible']:.3f} "
                      f"episode_cpu={r['cpu_us_per_agent_step']:7.1f}us/agent-step policy_share={r['policy_wall_share']:.2f} "
                      f"collided_agents={r['collided_agents']} cost={r['cost']:.6f}", flush=True)
                if "check" in r and "newton_rows" in r["check"]:
                    c = r["check"]
                    print(f"      newton on the warm run's observations: {c['rows']} agent-steps, rows/agent-step "
                          f"warm {c['warm_rows'] / c['rows']:.3f} newton {c['newton_rows'] / c['rows']:.3f}; index differs "
                          f"{c['index_diff']} (V̂ not monotone in between: {c['diff_not_monotone']}), feasibility differs "
                          f"{c['feasible_diff']}", flush=True)
                elif "check" in r:
                    c = r["check"]
                    print(f"      verify: {c['rows']} agent-steps, index differs {c['index_diff']} "
                          f"(of which V̂ not monotone in between: {c['diff_not_monotone']}), "
                          f"feasibility differs {c['feasible_diff']}", flush=True)
                if label in ("warm", "newton"):
                    means.setdefault(label, []).append(r["evals"])
            for other in [v[0] for v in variants if v[0] != "warm"]:
                a, b = runs["warm"]["result"], runs[other]["result"]
                print(f"      warm vs {other} episodes: same collision flags {bool((a.collided == b.collided).all())}, "
                      f"max |cost difference| {abs(a.cost - b.cost).max():.2e} (mean cost {b.cost.mean():.4f})", flush=True)
    for label, vals in means.items():
        print(f"{label}_vhat_evals_per_agent_step: {sum(vals) / len(vals):.3f}")


if __name__ == "__main__":
    main()
