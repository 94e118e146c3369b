"""Workflow job: train one DEF-MARL model (``methods.defmarl`` merged with a variant).

Files first — checkpoint, learning-curve CSV, JSON summary — then one MLflow run with the
learning curves, constraint-violation rates and z statistics as step metrics.
"""

from __future__ import annotations

import json
import time
from dataclasses import asdict
from functools import partial
from pathlib import Path

import pandas as pd

from madpinn.config import method_config
from madpinn.device import seed_everything
from madpinn.marl.checkpoint import save_checkpoint
from madpinn.marl.defmarl.epigraph import EpigraphConfig
from madpinn.marl.defmarl.trainer import DefMarlTrainer
from madpinn.marl.jobs import CURVES, build_trainer

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
    out = Path(out)
    if "defmarl" not in cfg["methods"]:
        raise ValueError("methods.defmarl is not configured")
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
    curve_path = out.with_name(out.stem + "_history.csv")
    pd.DataFrame(history).to_csv(curve_path, index=False)
    tail = history[-min(10, len(history)):]
    summary = {
        "run": run,
        "iterations": len(history),
        "wall_s": wall,
        "samples": int(sum(h["samples"] for h in history)),
        **{f"first_{k}": history[0][k] for k in SUMMARY_KEYS},
        **{f"last10_{k}": sum(h[k] for h in tail) / len(tail) for k in SUMMARY_KEYS},
    }
    json_path = out.with_suffix(".json")
    json_path.write_text(json.dumps(summary, indent=2))
    if track:
        from madpinn.tracking import log_job

        log_job(
            cfg, job_key=f"train/defmarl_{variant}", rule="train_defmarl", wildcards={"variant": variant},
            params={"training": tcfg, "epigraph": mcfg["epigraph"], "agents": cfg["agents"], "observation": cfg["observation"]},
            metrics={k: v for k, v in summary.items() if k != "run"}, artifacts=[out, curve_path, json_path],
            step_metrics={k: [h[k] for h in history] for k in DEFMARL_CURVES},
        )
    return summary
