"""Time DEF-MARL: one training iteration per variant (paper config of ``methods.defmarl``) and
the deployment step with and without the z search.

    python benchmarks/bench_defmarl.py [--threads 1] [--repeats 3] [--iterations 2]

Prints, best of ``--repeats``: a training iteration (rollout, epigraph targets, PPO update of
actor and V_h, cost-critic fit) after ``--iterations`` warm-up iterations, per variant; the
deployment step on 100 scenarios × 16 agents: z search (20 bisections on V_h + team max),
actor step with the z held, and the mean per policy step with ``root_period_steps``.
"""

from __future__ import annotations

import argparse

import torch

from madpinn.config import REPO_ROOT, load_config
from madpinn.marl.defmarl.deploy import DefMarlPolicy
from madpinn.marl.defmarl.build import build_defmarl_trainer
from madpinn.observation import ObservationSettings
from timing import best_of  # benchmarks/timing.py



def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--iterations", type=int, default=1, help="warm-up iterations before timing")
    args = ap.parse_args()
    torch.set_num_threads(args.threads)
    cfg = load_config([REPO_ROOT / "config.yaml"])
    m = cfg["methods"]["defmarl"]
    trainer = None
    for variant in sorted(m["variants"]):
        trainer, mcfg = build_defmarl_trainer(cfg, f"defmarl-{variant}")
        for _ in range(args.iterations):
            trainer.step()
        t = best_of(trainer.step, args.repeats)
        ppo = mcfg["training"]["ppo"]
        print(f"train {variant}: N={mcfg['training']['agent_counts']} samples={trainer.history[-1]['samples']} "
              f"iteration_s={t:.2f} paper_budget_min={t * ppo['iterations'] / 60:.1f} ({ppo['iterations']} iterations)")

    S, N = 100, 16
    gen = torch.Generator().manual_seed(0)
    spec = ObservationSettings.from_config(cfg)
    epi = m["epigraph"]
    policy = DefMarlPolicy(trainer.actor.eval(), trainer.critic.eval(), trainer.obs_norm, spec, trainer.env.cfg.neighbours,
                           4.0, epi["z_min"], epi["z_max"], m["root_iterations"], m["safe_level"], m["root_period_steps"])
    state = torch.cat([torch.rand(S, N, 2, generator=gen) * 2 - 1, torch.rand(S, N, 2, generator=gen) * 4 - 2], -1)
    goals = torch.rand(S, N, 2, generator=gen) * 2 - 1
    B = S * N
    with torch.no_grad():
        t_search = best_of(lambda: policy.budgets(state, goals), args.repeats * 3)
        policy.reset(state, goals)
        policy.act(state, goals, 0.0)
        policy.root_period = 10**9  # z held: the actor step alone
        t_held = best_of(lambda: policy.act(state, goals, 0.0), args.repeats * 3)
    p = m["root_period_steps"]
    mean = (t_search + p * t_held) / p
    print(f"deploy: agents={B} z_search_ms={1e3 * t_search:.1f} held_step_ms={1e3 * t_held:.1f} "
          f"mean_step_ms(root_period_steps={p})={1e3 * mean:.1f} us_per_agent_step={1e6 * mean / B:.2f}")


if __name__ == "__main__":
    main()
