"""CLI: ``python -m madpinn train-defmarl --config … --variant n3 --out …``."""

from __future__ import annotations

import json


def _train(args) -> int:
    from madpinn.config import load_config
    from madpinn.marl.defmarl.jobs import train_defmarl

    cfg = load_config(args.config)
    summary = train_defmarl(cfg, args.variant, args.out, threads=args.threads, progress=not args.no_progress,
                            track=not args.no_track)
    print(json.dumps(summary))
    return 0


def register(sub) -> None:
    from madpinn.cli import add_config_arg, add_job_args

    p = sub.add_parser("train-defmarl", help="train one DEF-MARL model (epigraph-form MARL)")
    add_config_arg(p)
    p.add_argument("--variant", required=True, help="variant of methods.defmarl (e.g. n3, n8)")
    p.add_argument("--out", required=True, help="checkpoint path (.pt)")
    add_job_args(p)
    p.set_defaults(func=_train)
