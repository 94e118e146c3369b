"""DEF-MARL: how the team agrees on z at deployment — the three schemes of
``madpinn.marl.defmarl.root.agree`` on a validation seed, through the evaluation cells' own loop
(``cell_batches``; the policy's ``consensus`` and root-search ``safe_level`` switched by ``wrap``).
Prints one line per (model, N, level, consensus): safety rate (%), safe scenarios (%), cost, mean
agreed z, share of agent searches whose agreed z is below the scenario maximum (a split
communication graph). ``--levels`` (default: the config's ``safe_level``), ``--consensus``
(default: all three).

    PYTHONPATH=$PWD python scripts/defmarl_consensus.py --config config.yaml --model n8=models/defmarl_n8.pt \
        --agents 8 16 --seed 100 --scenarios 50
"""

from __future__ import annotations

import argparse
from dataclasses import replace

import pandas as pd

from madpinn.config import load_config
from madpinn.device import resolve_device, resolve_dtype, seed_everything
from madpinn.evaluation.cell import CellSettings, cell_batches
from madpinn.evaluation.metrics import scenario_metrics, seed_summary
from madpinn.marl.defmarl.root import CONSENSUS


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--config", nargs="+", required=True)
    ap.add_argument("--model", nargs="+", required=True, help="VARIANT=PATH, e.g. n8=models/defmarl_n8.pt")
    ap.add_argument("--agents", type=int, nargs="+", default=[8, 16])
    ap.add_argument("--seed", type=int, default=100)
    ap.add_argument("--scenarios", type=int, default=50)
    ap.add_argument("--backend", default="double_integrator")
    ap.add_argument("--levels", type=float, nargs="+", default=None, help="root-search safe levels (default: the config's)")
    ap.add_argument("--consensus", nargs="+", choices=CONSENSUS, default=list(CONSENSUS))
    args = ap.parse_args()
    if args.seed < 100:
        raise SystemExit("validation seeds only (>= 100)")
    cfg = load_config(args.config)
    for item in args.model:
        variant, _, path = item.partition("=")
        cs = replace(CellSettings.from_config(cfg, "main", f"defmarl-{variant}"), scenarios=args.scenarios)
        device, dtype = resolve_device(cs.device), resolve_dtype(cs.dtype)
        levels = args.levels or [cs.method_settings.safe_level]
        for n, level, consensus in ((n, lv, c) for n in args.agents for lv in levels for c in args.consensus):
            seed_everything(args.seed, 1)
            policies = []

            def wrap(policy, first):
                policy.consensus = consensus
                policy.level = level
                policies.append(policy)
                return policy

            frames = [scenario_metrics(res, first_index=first) for first, _, res, _ in
                      cell_batches(cs, n, args.seed, args.backend, device, dtype, {"policy": path}, wrap=wrap,
                                   progress=False)]
            s = seed_summary(pd.concat(frames, ignore_index=True))
            steps = sum(p.stats.steps for p in policies)
            z = sum(p.stats.z_sum for p in policies) / steps
            below = sum(p.stats.below_team_max for p in policies) / steps
            print(f"defmarl-{variant} N={n} level={level:g} consensus={consensus}: safety {100 * s['safety_rate']:.1f} % "
                  f"safe scenarios {100 * s['safe_scenarios']:.0f} % cost {s['cost']:.3f} mean z {z:.2f} "
                  f"below team max {100 * below:.1f} %", flush=True)


if __name__ == "__main__":
    main()
