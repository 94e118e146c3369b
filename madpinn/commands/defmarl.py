"""``train-defmarl``: one DEF-MARL model (``methods.defmarl`` merged with a variant).

One live MLflow run: learning curves, constraint-violation rates and z statistics logged per
iteration as they happen; files first — checkpoint, learning-curve CSV, JSON summary — then the
files and the actor (``mlflow.pytorch``).
"""

from __future__ import annotations

from dataclasses import asdict
from pathlib import Path

from madpinn.commands.args import config_of
from madpinn.commands.finish import JobRecord
from madpinn.commands.marl_training import add_training_parser, train_and_record


def train_defmarl(cfg: dict, variant: str, out: str | Path, threads: int = 1, progress: bool = True, track: bool = True) -> dict:
    from madpinn.config import ConfigError, method_config
    from madpinn.marl.defmarl.build import DEFMARL_CURVES, SUMMARY_KEYS, build_defmarl_trainer

    if "defmarl" not in cfg["methods"]:
        raise ConfigError("methods.defmarl is not configured")
    run = f"defmarl-{variant}"
    _, mcfg = method_config(cfg, run)
    tcfg = mcfg["training"]
    return train_and_record(
        cfg, lambda: build_defmarl_trainer(cfg, run)[0], tcfg, out, desc=f"DEF-MARL ({variant})",
        meta=lambda trainer, wall: {"method": "defmarl", "variant": variant, "epigraph": asdict(trainer.epi), "wall_s": wall,
                                    "arena": tcfg["arena"], "agent_counts": list(tcfg["agent_counts"])},
        first=SUMMARY_KEYS, last=SUMMARY_KEYS, curves=DEFMARL_CURVES, extra={"run": run},
        record=JobRecord(job_key=f"train/defmarl_{variant}", rule="train_defmarl", wildcards={"variant": variant},
                         params={"training": tcfg, "epigraph": mcfg["epigraph"], "agents": cfg["agents"],
                                 "observation": cfg["observation"]}),
        threads=threads, progress=progress, track=track,
    )


def _train(args) -> int:
    train_defmarl(config_of(args), args.variant, args.out, threads=args.threads, progress=not args.no_progress,
                  track=not args.no_track)
    return 0


def register(sub) -> None:
    add_training_parser(sub, "train-defmarl", "train one DEF-MARL model (epigraph-form MARL)", _train, variant=True)
