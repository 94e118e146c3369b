"""Time the shared multi-agent PPO trainer (paper config of ``methods.safemarl.nominal``) and
the SafeMARL control step.

    python benchmarks/bench_marl.py [--threads 1] [--repeats 3] [--vs results/models/vs.pt]

Prints, best of ``--repeats``: one training iteration (rollout + PPO update) per training agent
count, split into rollout and update; the exact QP solver on 1600 problems (100 scenarios × 16
agents, k critical rows); the nominal actor's deployment step; and, when a learned V_s is given
(and ``madpinn.value_functions`` is available), the full filtered SafeMARL step.
"""

from __future__ import annotations

import argparse

import torch

from madpinn.config import REPO_ROOT, load_config
from madpinn.marl.deploy import ActorPolicy
from madpinn.marl.build import build_trainer
from madpinn.marl.ppo import PPOBatch, ppo_update
from madpinn.observation import ObservationSettings
from madpinn.policies.cbvf_qp import solve_box_qp
from madpinn.policies.safemarl import CBVFFilter
from timing import best_of  # benchmarks/timing.py



def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--vs", default=None, help="learned V_s checkpoint for the full filter step")
    args = ap.parse_args()
    torch.set_num_threads(args.threads)
    cfg = load_config([REPO_ROOT / "config.yaml"])
    m = cfg["methods"]["safemarl"]
    tcfg = m["nominal"]
    trainer = build_trainer(cfg, tcfg)
    print(f"threads={args.threads} agents_per_batch={tcfg['ppo']['agents_per_batch']} hidden={tcfg['network']['hidden']} "
          f"epochs={tcfg['ppo']['epochs']} minibatch={tcfg['ppo']['minibatch']} horizon={trainer.env.horizon}")
    for n in tcfg["agent_counts"]:
        state = {}

        def rollout():
            state["buf"], state["last"], _ = trainer.collect(n)

        t_roll = best_of(rollout, args.repeats)
        buf, last = state["buf"], state["last"]
        adv, ret = trainer.advantages(buf, last)
        batch = PPOBatch(buf.flat_obs(), buf.get("action").reshape(-1, 2), buf.get("logp").reshape(-1), adv.reshape(-1), ret.reshape(-1, 1))
        t_upd = best_of(lambda: ppo_update(trainer.actor, trainer.critic, trainer.optimizer, batch, trainer.ppo, trainer.generator), args.repeats)
        print(f"train N={n}: samples={len(batch)} rollout_s={t_roll:.2f} update_s={t_upd:.2f} iteration_s={t_roll + t_upd:.2f} "
              f"samples_per_s={len(batch) / (t_roll + t_upd):.0f}")
    print(f"paper budget: {tcfg['ppo']['iterations']} iterations")

    S, N, k = 100, 16, int(m["critical_neighbours"])
    gen = torch.Generator().manual_seed(0)
    B = S * N
    u_nom = torch.rand(B, 2, generator=gen) * 8 - 4
    a, b = torch.randn(B, k, 2, generator=gen), torch.randn(B, k, generator=gen) * 4
    t_qp = best_of(lambda: solve_box_qp(u_nom, a, b, 4.0), args.repeats * 5)
    print(f"qp: problems={B} rows={k} us_per_problem={1e6 * t_qp / B:.3f}")

    spec = ObservationSettings.from_config(cfg)
    policy = ActorPolicy(trainer.actor.eval(), trainer.obs_norm, spec, trainer.env.cfg.neighbours, 4.0)
    state = torch.cat([torch.rand(S, N, 2, generator=gen) * 2 - 1, torch.rand(S, N, 2, generator=gen) * 4 - 2], -1)
    goals = torch.rand(S, N, 2, generator=gen) * 2 - 1
    t_act = best_of(lambda: policy.act(state, goals, 0.0), args.repeats * 5)
    print(f"nominal actor step: agents={B} us_per_agent_step={1e6 * t_act / B:.3f}")
    if args.vs:
        from madpinn.value_functions import load_vs

        flt = CBVFFilter(load_vs(args.vs), 4.0, m["cbvf_gamma"], k, m["candidates"], m["threshold"], spec.sensing_radius)
        u = policy.act(state, goals, 0.0)
        with torch.no_grad():
            t_f = best_of(lambda: flt(state, u), args.repeats * 3)
        print(f"cbvf filter step (learned V_s): agents={B} us_per_agent_step={1e6 * t_f / B:.3f}")


if __name__ == "__main__":
    main()
