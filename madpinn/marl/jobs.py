"""Workflow job: train the SafeMARL nominal policy (goal-reaching PPO in the small arena).

Config: ``methods.safemarl.nominal`` (arena, agent counts, seed, env, network, reward, ppo).
One live MLflow run: learning curves logged per iteration as they happen; files first —
checkpoint, learning curve CSV, JSON summary — then the files and the actor (``mlflow.pytorch``).
"""

from __future__ import annotations

import json
import time
from pathlib import Path

import pandas as pd

from madpinn.device import resolve_device, resolve_dtype, seed_everything
from madpinn.dynamics import DoubleIntegrator
from madpinn.marl.checkpoint import save_checkpoint
from madpinn.marl.env import EnvConfig, GoalReachingEnv, RewardConfig
from madpinn.marl.ppo import PPOConfig
from madpinn.marl.trainer import PPOTrainer
from madpinn.observation import ObservationSpec
from madpinn.scenarios import Arena

CURVES = ("episode_return", "final_distance", "reached_rate", "collision_rate", "loss_policy", "loss_value",
          "entropy", "approx_kl", "clip_frac")


def build_trainer(cfg: dict, tcfg: dict, trainer_cls=PPOTrainer, device=None, dtype=None) -> PPOTrainer:
    """A trainer from the global config and a training block (``methods.<m>.nominal`` layout)."""
    device = device or resolve_device(cfg["device"])
    dtype = dtype or resolve_dtype(cfg["dtype"])
    dynamics = DoubleIntegrator(u_max=cfg["agents"]["u_max"], v_max=cfg["agents"]["v_max"])
    env = GoalReachingEnv(
        dynamics, Arena.from_config(cfg, tcfg["arena"]), ObservationSpec.from_config(cfg),
        EnvConfig.from_dict(tcfg["env"]), seed=int(tcfg["seed"]), device=device, dtype=dtype,
    )
    return trainer_cls(
        env, PPOConfig.from_dict(tcfg["ppo"]), RewardConfig.from_dict(tcfg["reward"]),
        tcfg["agent_counts"], hidden=int(tcfg["network"]["hidden"]), seed=int(tcfg["seed"]),
    )


def write_training_record(out: Path, history: list[dict], wall: float, first_keys, last_keys, extra: dict | None = None):
    """Learning curve ``<out>_history.csv`` and summary ``<out>.json`` (first iteration and mean
    of the last 10); returns ``(summary, curve_path, json_path)``."""
    curve_path = out.with_name(out.stem + "_history.csv")
    pd.DataFrame(history).to_csv(curve_path, index=False)
    tail = history[-min(10, len(history)):]
    summary = {
        **(extra or {}),
        "iterations": len(history),
        "wall_s": wall,
        "samples": int(sum(h["samples"] for h in history)),
        **{f"first_{k}": history[0][k] for k in first_keys},
        **{f"last10_{k}": sum(h[k] for h in tail) / len(tail) for k in last_keys},
    }
    json_path = out.with_suffix(".json")
    json_path.write_text(json.dumps(summary, indent=2))
    return summary, curve_path, json_path


def train_safemarl_nominal(cfg: dict, out: str | Path, threads: int = 1, progress: bool = True, track: bool = True) -> dict:
    from madpinn.tracking import job_run

    out = Path(out)
    if "safemarl" not in cfg["methods"]:
        raise ValueError("methods.safemarl is not configured (its 'nominal' block holds the PPO training settings)")
    tcfg = cfg["methods"]["safemarl"]["nominal"]
    with job_run(cfg, job_key="train/safemarl_nominal", rule="train_safemarl_nominal",
                 params={"nominal": tcfg, "agents": cfg["agents"], "observation": cfg["observation"]}, track=track) as run:
        seed_everything(int(tcfg["seed"]), threads)
        t0 = time.perf_counter()
        trainer = build_trainer(cfg, tcfg)
        history = trainer.train(progress=progress, desc="SafeMARL nominal PPO", on_iteration=live_curves(run, CURVES))
        wall = time.perf_counter() - t0
        save_checkpoint(out, trainer, meta={"method": "safemarl-nominal", "wall_s": wall, "arena": tcfg["arena"]})
        summary, curve_path, json_path = write_training_record(
            out, history, wall, first_keys=("episode_return", "final_distance", "collision_rate"),
            last_keys=("episode_return", "final_distance", "reached_rate", "collision_rate"),
        )
        run.finish(metrics=summary, step=len(history), artifacts=[out, curve_path, json_path],
                   models={"actor": trainer.actor})
    return summary


def live_curves(run, keys):
    """``on_iteration`` callback of a PPO trainer: the iteration's ``keys`` as step metrics."""
    return lambda stats: run.log_metrics({k: stats[k] for k in keys if k in stats}, step=int(stats["iteration"]))
