"""Build a PPO trainer from the config's training block (``methods.<m>.nominal`` layout)."""

from __future__ import annotations

from madpinn.device import resolve_device, resolve_dtype
from madpinn.marl.env import EnvSettings, GoalReachingEnv, RewardSettings
from madpinn.marl.networks import DEFAULT_ENCODER
from madpinn.marl.ppo import PPOSettings
from madpinn.marl.trainer import PPOTrainer
from madpinn.observation import ObservationSettings
from madpinn.scenarios import Arena
from madpinn.settings import AgentSettings

CURVES = ("episode_return", "final_distance", "reached_rate", "collision_rate", "loss_policy", "loss_value",
          "entropy", "approx_kl", "clip_frac")
"""per-iteration learning curves logged as MLflow step metrics"""


def build_trainer(cfg: dict, tcfg: dict, trainer_cls=PPOTrainer, device=None, dtype=None) -> PPOTrainer:
    """A trainer from the global config and a training block (``methods.<m>.nominal`` layout)."""
    device = device or resolve_device(cfg["device"])
    dtype = dtype or resolve_dtype(cfg["dtype"])
    env = GoalReachingEnv(
        AgentSettings.from_config(cfg).dynamics(), Arena.from_config(cfg, tcfg["arena"]), ObservationSettings.from_config(cfg),
        EnvSettings.from_config(tcfg["env"]), seed=int(tcfg["seed"]), device=device, dtype=dtype,
    )
    return trainer_cls(
        env, PPOSettings.from_config(tcfg["ppo"]), RewardSettings.from_config(tcfg["reward"]),
        tcfg["agent_counts"], hidden=int(tcfg["network"]["hidden"]), seed=int(tcfg["seed"]),
        encoder=str(tcfg["network"]["encoder"]),
    )


def training_summary(history: list[dict], wall: float, first_keys, last_keys, extra: dict | None = None) -> dict:
    """Summary of a training history: first iteration and mean of the last 10 iterations."""
    tail = history[-min(10, len(history)):]
    return {
        **(extra or {}),
        "iterations": len(history),
        "wall_s": wall,
        "samples": int(sum(h["samples"] for h in history)),
        **{f"first_{k}": history[0][k] for k in first_keys},
        **{f"last10_{k}": sum(h[k] for h in tail) / len(tail) for k in last_keys},
    }
