"""``train-safemarl-nominal``: SafeMARL's nominal goal-reaching PPO policy (small arena).

Config: ``methods.safemarl.nominal`` (arena, agent counts, seed, env, network, reward, ppo).
One live MLflow run: learning curves logged per iteration as they happen; files first —
checkpoint, learning curve CSV, JSON summary — then the files and the actor (``mlflow.pytorch``).
"""

from __future__ import annotations

from pathlib import Path

from madpinn.commands.args import config_of
from madpinn.commands.finish import JobRecord
from madpinn.commands.marl_training import add_training_parser, train_and_record
from madpinn.commands.reads import marl

FIRST = ("episode_return", "final_distance", "collision_rate")
LAST = ("episode_return", "final_distance", "reached_rate", "collision_rate")


def train_safemarl_nominal(cfg: dict, out: str | Path, threads: int = 1, progress: bool = True, track: bool = True) -> dict:
    from madpinn.config import ConfigError
    from madpinn.marl.build import CURVES, build_trainer
    from madpinn.marl.training_run import TrainingRun

    if "safemarl" not in cfg["methods"]:
        raise ConfigError("methods.safemarl is not configured (its 'nominal' block holds the PPO training settings)")
    tcfg = cfg["methods"]["safemarl"]["nominal"]
    training = TrainingRun(
        build=lambda: build_trainer(cfg, tcfg), seed=int(tcfg["seed"]), out=Path(out), desc="SafeMARL nominal PPO",
        meta=lambda trainer: {"method": "safemarl-nominal", "arena": tcfg["arena"]}, first=FIRST, last=LAST,
        threads=threads, progress=progress)
    return train_and_record(
        cfg, training, CURVES,
        JobRecord(job_key="train/safemarl_nominal", rule="train_safemarl_nominal",
                  params={"nominal": tcfg, "agents": cfg["agents"], "observation": cfg["observation"]}),
        track=track)


def _train(args) -> int:
    train_safemarl_nominal(config_of(args), args.out, threads=args.threads, progress=not args.no_progress,
                           track=not args.no_track)
    return 0


def register(sub) -> None:
    add_training_parser(sub, "train-safemarl-nominal", "train SafeMARL's nominal goal-reaching PPO policy", _train,
                        reads=lambda cfg: marl(cfg, "safemarl_nominal"))
