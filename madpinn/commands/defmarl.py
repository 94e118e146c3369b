"""``train-defmarl``: one DEF-MARL model (``methods.defmarl`` merged with a variant).

Files first — checkpoint, learning-curve CSV, JSON summary — then one MLflow run with the
learning curves, constraint-violation rates and z statistics as step metrics.
"""

from __future__ import annotations

import time
from dataclasses import asdict
from pathlib import Path

from madpinn.commands.args import add_config_arg, add_job_args, config_of
from madpinn.commands.finish import JobRecord, finish
from madpinn.commands.safemarl import write_training_record


def train_defmarl(cfg: dict, variant: str, out: str | Path, threads: int = 1, progress: bool = True, track: bool = True) -> dict:
    from madpinn.config import ConfigError, method_config
    from madpinn.device import seed_everything
    from madpinn.marl.build import training_summary
    from madpinn.marl.checkpoint import save_checkpoint
    from madpinn.marl.defmarl.build import DEFMARL_CURVES, SUMMARY_KEYS, build_defmarl_trainer

    out = Path(out)
    if "defmarl" not in cfg["methods"]:
        raise ConfigError("methods.defmarl is not configured")
    run = f"defmarl-{variant}"
    _, mcfg = method_config(cfg, run)
    tcfg = mcfg["training"]
    seed_everything(int(tcfg["seed"]), threads)
    t0 = time.perf_counter()
    trainer, mcfg = build_defmarl_trainer(cfg, run)
    history = trainer.train(progress=progress, desc=f"DEF-MARL ({variant})")
    wall = time.perf_counter() - t0
    save_checkpoint(out, trainer, meta={"method": "defmarl", "variant": variant, "epigraph": asdict(trainer.epi),
                                        "wall_s": wall, "arena": tcfg["arena"], "agent_counts": list(tcfg["agent_counts"])})
    summary = training_summary(history, wall, SUMMARY_KEYS, SUMMARY_KEYS, extra={"run": run})
    files = [out, *write_training_record(out, history, summary)]
    finish(cfg, JobRecord(
        job_key=f"train/defmarl_{variant}", rule="train_defmarl", wildcards={"variant": variant}, artifacts=files,
        params={"training": tcfg, "epigraph": mcfg["epigraph"], "agents": cfg["agents"], "observation": cfg["observation"]},
        metrics={k: v for k, v in summary.items() if k != "run"},
        step_metrics={k: [h[k] for h in history] for k in DEFMARL_CURVES},
    ), track, echo=summary)
    return summary


def _train(args) -> int:
    train_defmarl(config_of(args), args.variant, args.out, threads=args.threads, progress=not args.no_progress,
                  track=not args.no_track)
    return 0


def register(sub) -> None:
    p = sub.add_parser("train-defmarl", help="train one DEF-MARL model (epigraph-form MARL)")
    add_config_arg(p)
    p.add_argument("--variant", required=True, help="variant of methods.defmarl (e.g. n3, n8)")
    p.add_argument("--out", required=True, help="checkpoint path (.pt)")
    add_job_args(p)
    p.set_defaults(func=_train)
