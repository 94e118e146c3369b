"""Build the DEF-MARL trainer of run ``defmarl-<variant>`` (``methods.defmarl`` merged with the variant)."""

from __future__ import annotations

from functools import partial

from madpinn.config import method_config
from madpinn.marl.build import CURVES, build_trainer
from madpinn.marl.defmarl.epigraph import EpigraphSettings
from madpinn.marl.defmarl.trainer import DefMarlTrainer

DEFMARL_CURVES = CURVES + ("violation_rate", "team_cost", "epigraph_objective", "z_start_mean", "z_end_mean",
                           "z_end_at_min", "loss_cost", "vh_mean", "vl_mean")
SUMMARY_KEYS = ("episode_return", "final_distance", "reached_rate", "collision_rate", "violation_rate", "team_cost",
                "epigraph_objective")


def build_defmarl_trainer(cfg: dict, run: str) -> tuple[DefMarlTrainer, dict]:
    """The trainer of run ``defmarl-<variant>`` and its merged method config."""
    _, mcfg = method_config(cfg, run)
    epi = EpigraphSettings.from_config(mcfg["epigraph"])
    return build_trainer(cfg, mcfg["training"], trainer_cls=partial(DefMarlTrainer, epigraph=epi)), mcfg
