"""Where do MAD-PINN's collisions come from? Classifies every collision onset of a job.

Runs the configured ``madpinn`` run on the double-integrator backend as
``python -m madpinn evaluate`` runs its first scenario batch (same scenarios, same policy
context; at most ``sim.scenario_batch`` scenarios), and at each collision onset
(pair distance first ≤ r) of agents i, j records:

- ``observed``: j was among i's selected neighbours and i among j's (``both``), one way
  (``one``), or neither (``none``) — ``none``/``one`` point to the n = 2 observation or the
  neighbour choice, ``both`` to V̂ and the control;
- ``crowd``: other agents within 0.3 m of i or j (more than n = 2 agents in play);
- ``infeasible_lead_s``: how long before the onset V̂ first declared i or j infeasible in the
  uninterrupted infeasible stretch ending at the onset (0 = feasible at the onset);
- ``closing_speed``: −d/dt of the pair distance at the onset (m/s).

    PYTHONPATH=$PWD python scripts/diagnose_collisions.py --config config.yaml [overlay.yaml]
        --n-agents 12 --seed 0 --scenarios 40 [--run madpinn] [--out diag.json]
"""

from __future__ import annotations

import argparse
import json
from collections import Counter
from pathlib import Path

import numpy as np
import torch

from madpinn.config import load_config
from madpinn.commands.args import parse_models
from madpinn.evaluation.cell import CellSettings, policy_context
from madpinn.policies.base import make_policy
from madpinn.scenarios import generate_scenarios
from madpinn.simulation import run_episode
from madpinn.simulation.backend import make_backend


class CollisionProbe:
    """Wraps a MAD-PINN policy; classifies collision onsets seen at its decision times."""

    def __init__(self, policy, r: float, dt: float, crowd_radius: float = 0.3):
        self.policy, self.r, self.dt, self.crowd_radius = policy, r, dt, crowd_radius
        self.events: list[dict] = []

    def reset(self, state, goals):
        self.policy.reset(state, goals)
        S, N, _ = state.shape
        self.touching = torch.zeros(S, N, N, dtype=torch.bool)
        self.infeasible_since = torch.full((S, N), -1.0)   # start of the current infeasible stretch (s), −1: feasible
        self.prev_d = None

    def act(self, state, goals, t):
        u = self.policy.act(state, goals, t)
        p, v = state[..., 0:2], state[..., 2:4]
        rel = p[:, :, None] - p[:, None]
        d = rel.norm(dim=-1)
        S, N, _ = d.shape
        eye = torch.eye(N, dtype=torch.bool)
        mad = getattr(self.policy, "nominal", self.policy)   # madpinn-filtered wraps the MAD-PINN policy
        infeasible = (mad._z_prev >= mad.vhat.z_max * (1 - 1e-9)).reshape(S, N)
        self.infeasible_since = torch.where(infeasible, torch.where(self.infeasible_since < 0, t, self.infeasible_since),
                                            torch.full_like(self.infeasible_since, -1.0))
        touch = (d <= self.r) & ~eye
        onset = touch & ~self.touching & torch.triu(torch.ones(N, N, dtype=torch.bool), 1)
        nb = mad.neighbours
        for s, i, j in onset.nonzero().tolist():
            i_sees_j = bool((nb[s, i] == j).any())
            j_sees_i = bool((nb[s, j] == i).any())
            crowd = int((((d[s, i] < self.crowd_radius) | (d[s, j] < self.crowd_radius)) & ~eye[i] & ~eye[j]).sum())
            starts = [float(self.infeasible_since[s, a]) for a in (i, j) if self.infeasible_since[s, a] >= 0]
            closing = float(-(rel[s, i, j] * (v[s, i] - v[s, j])).sum() / d[s, i, j].clamp_min(1e-9))
            self.events.append({
                "scenario": s, "i": i, "j": j, "t": float(t), "observed": "both" if i_sees_j and j_sees_i else ("one" if i_sees_j or j_sees_i else "none"),
                "crowd": crowd, "infeasible_lead_s": float(t - min(starts)) if starts else 0.0,
                "closing_speed": closing, "speed_i": float(v[s, i].norm()), "speed_j": float(v[s, j].norm()),
            })
        self.touching |= touch
        return u


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--config", nargs="+", default=["config.yaml"])
    ap.add_argument("--study", default="main")
    ap.add_argument("--run", default="madpinn")
    ap.add_argument("--n-agents", type=int, default=12)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--scenarios", type=int, default=40)
    ap.add_argument("--out")
    ap.add_argument("--model", action="append", default=[], metavar="NAME=PATH",
                    help="trained files, e.g. --model vhat=results/models/vhat.pt --model vs=results/models/vs.pt")
    args = ap.parse_args()
    torch.set_num_threads(1)
    cfg = load_config(args.config)
    cs = CellSettings.from_config(cfg, args.study, args.run)
    arena = cs.arena
    if args.scenarios > int(cfg["sim"]["scenario_batch"]):
        raise SystemExit(f"--scenarios must be ≤ sim.scenario_batch ({cfg['sim']['scenario_batch']}): one batch, as evaluate's first")
    r, dt = float(cfg["agents"]["collision_radius"]), float(cfg["sim"]["dt"])
    cpu, f32 = torch.device("cpu"), torch.float32
    starts, goals = generate_scenarios(arena, args.n_agents, args.seed, args.scenarios, r, cpu, f32)
    probe = CollisionProbe(make_policy(cs.method, policy_context(cs, args.seed, 0, cpu, f32, parse_models(args.model))), r, dt)
    result, _ = run_episode(make_backend("double_integrator", cs.sim, cs.limits, cpu, f32), probe, starts, goals,
                            cs.episode_steps, r, policy_period=cs.policy_period, progress=True)
    ev = probe.events
    lead = np.array([e["infeasible_lead_s"] for e in ev])
    summary = {
        "n_agents": args.n_agents, "seed": args.seed, "scenarios": args.scenarios,
        "safety_rate": float(1 - result.collided.mean()), "collision_onsets": len(ev),
        "observed": dict(Counter(e["observed"] for e in ev)),
        "crowd": dict(sorted(Counter(min(e["crowd"], 3) for e in ev).items())),
        "feasible_at_onset": int((lead == 0).sum()),
        "infeasible_lead_s_median": float(np.median(lead[lead > 0])) if (lead > 0).any() else None,
        "closing_speed_median": float(np.median([e["closing_speed"] for e in ev])) if ev else None,
        "closing_speed_quartiles": np.percentile([e["closing_speed"] for e in ev], [25, 75]).round(2).tolist() if ev else None,
    }
    print(json.dumps(summary, indent=1))
    if args.out:
        Path(args.out).write_text(json.dumps({"summary": summary, "events": ev}, indent=1))


if __name__ == "__main__":
    main()
