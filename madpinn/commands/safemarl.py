"""``train-safemarl-nominal``: SafeMARL's nominal goal-reaching PPO policy (small arena).

Config: ``methods.safemarl.nominal`` (arena, agent counts, seed, env, network, reward, ppo).
Files first — checkpoint, learning curve CSV, JSON summary — then one MLflow run with the
learning curves as step metrics.
"""

from __future__ import annotations

import time
from pathlib import Path

from madpinn.commands.args import add_config_arg, add_job_args, config_of
from madpinn.commands.finish import JobRecord, finish, write_json

FIRST = ("episode_return", "final_distance", "collision_rate")
LAST = ("episode_return", "final_distance", "reached_rate", "collision_rate")


def write_training_record(out: Path, history: list[dict], summary: dict) -> tuple[Path, Path]:
    """Learning curve ``<out>_history.csv`` and summary ``<out>.json``."""
    import pandas as pd

    curve_path = out.with_name(out.stem + "_history.csv")
    pd.DataFrame(history).to_csv(curve_path, index=False)
    return curve_path, write_json(out.with_suffix(".json"), summary)


def train_safemarl_nominal(cfg: dict, out: str | Path, threads: int = 1, progress: bool = True, track: bool = True) -> dict:
    from madpinn.config import ConfigError
    from madpinn.device import seed_everything
    from madpinn.marl.build import CURVES, build_trainer, training_summary
    from madpinn.marl.checkpoint import save_checkpoint

    out = Path(out)
    if "safemarl" not in cfg["methods"]:
        raise ConfigError("methods.safemarl is not configured (its 'nominal' block holds the PPO training settings)")
    tcfg = cfg["methods"]["safemarl"]["nominal"]
    seed_everything(int(tcfg["seed"]), threads)
    t0 = time.perf_counter()
    trainer = build_trainer(cfg, tcfg)
    history = trainer.train(progress=progress, desc="SafeMARL nominal PPO")
    wall = time.perf_counter() - t0
    save_checkpoint(out, trainer, meta={"method": "safemarl-nominal", "wall_s": wall, "arena": tcfg["arena"]})
    summary = training_summary(history, wall, FIRST, LAST)
    files = [out, *write_training_record(out, history, summary)]
    finish(cfg, JobRecord(
        job_key="train/safemarl_nominal", rule="train_safemarl_nominal", artifacts=files,
        params={"nominal": tcfg, "agents": cfg["agents"], "observation": cfg["observation"]},
        metrics=summary, step_metrics={k: [h[k] for h in history] for k in CURVES},
    ), track, echo=summary)
    return summary


def _train(args) -> int:
    train_safemarl_nominal(config_of(args), args.out, threads=args.threads, progress=not args.no_progress,
                           track=not args.no_track)
    return 0


def register(sub) -> None:
    p = sub.add_parser("train-safemarl-nominal", help="train SafeMARL's nominal goal-reaching PPO policy")
    add_config_arg(p)
    p.add_argument("--out", required=True, help="checkpoint path (.pt)")
    add_job_args(p)
    p.set_defaults(func=_train)
