"""Workflow job: train one DEF-MARL model (``methods.defmarl`` merged with a variant).

One live MLflow run: learning curves, constraint-violation rates and z statistics logged per
iteration as they happen; files first — checkpoint, learning-curve CSV, JSON summary — then the
files and the actor (``mlflow.pytorch``).
"""

from __future__ import annotations

import time
from dataclasses import asdict
from functools import partial
from pathlib import Path

from madpinn.config import method_config
from madpinn.device import seed_everything
from madpinn.marl.checkpoint import save_checkpoint
from madpinn.marl.defmarl.epigraph import EpigraphConfig
from madpinn.marl.defmarl.trainer import DefMarlTrainer
from madpinn.marl.jobs import CURVES, build_trainer, live_curves, write_training_record

DEFMARL_CURVES = CURVES + ("violation_rate", "team_cost", "epigraph_objective", "z_start_mean", "z_end_mean",
                           "z_end_at_min", "loss_cost", "vh_mean", "vl_mean")
SUMMARY_KEYS = ("episode_return", "final_distance", "reached_rate", "collision_rate", "violation_rate", "team_cost",
                "epigraph_objective")


def build_defmarl_trainer(cfg: dict, run: str) -> tuple[DefMarlTrainer, dict]:
    """The trainer of run ``defmarl-<variant>`` and its merged method config."""
    _, mcfg = method_config(cfg, run)
    epi = EpigraphConfig.from_dict(mcfg["epigraph"])
    return build_trainer(cfg, mcfg["training"], trainer_cls=partial(DefMarlTrainer, epigraph=epi)), mcfg


def train_defmarl(cfg: dict, variant: str, out: str | Path, threads: int = 1, progress: bool = True, track: bool = True) -> dict:
    from madpinn.tracking import job_run

    out = Path(out)
    if "defmarl" not in cfg["methods"]:
        raise ValueError("methods.defmarl is not configured")
    run = f"defmarl-{variant}"
    _, mcfg = method_config(cfg, run)
    tcfg = mcfg["training"]
    with job_run(cfg, job_key=f"train/defmarl_{variant}", rule="train_defmarl", wildcards={"variant": variant},
                 params={"training": tcfg, "epigraph": mcfg["epigraph"], "agents": cfg["agents"],
                         "observation": cfg["observation"]}, track=track) as tracker:
        seed_everything(int(tcfg["seed"]), threads)
        t0 = time.perf_counter()
        trainer, mcfg = build_defmarl_trainer(cfg, run)
        history = trainer.train(progress=progress, desc=f"DEF-MARL ({variant})",
                                on_iteration=live_curves(tracker, DEFMARL_CURVES))
        wall = time.perf_counter() - t0
        save_checkpoint(out, trainer, meta={"method": "defmarl", "variant": variant, "epigraph": asdict(trainer.epi),
                                            "wall_s": wall, "arena": tcfg["arena"], "agent_counts": list(tcfg["agent_counts"])})
        summary, curve_path, json_path = write_training_record(
            out, history, wall, first_keys=SUMMARY_KEYS, last_keys=SUMMARY_KEYS, extra={"run": run}
        )
        tracker.finish(metrics={k: v for k, v in summary.items() if k != "run"}, step=len(history),
                       artifacts=[out, curve_path, json_path], models={"actor": trainer.actor})
    return summary
