"""CLI: ``python -m madpinn train-safemarl-nominal --config … --out …``."""

from __future__ import annotations

import json


def _train(args) -> int:
    from madpinn.config import load_config
    from madpinn.marl.jobs import train_safemarl_nominal

    cfg = load_config(args.config)
    summary = train_safemarl_nominal(cfg, args.out, threads=args.threads, progress=not args.no_progress, track=not args.no_track)
    print(json.dumps(summary))
    return 0


def register(sub) -> None:
    from madpinn.cli import add_config_arg, add_job_args

    p = sub.add_parser("train-safemarl-nominal", help="train SafeMARL's nominal goal-reaching PPO policy")
    add_config_arg(p)
    p.add_argument("--out", required=True, help="checkpoint path (.pt)")
    add_job_args(p)
    p.set_defaults(func=_train)
