"""A value-function training's settings and its length, without torch: the workflow reads them
while it plans (a training job's Slurm time limit), and a snakemake start then pays no ``import torch``."""

from __future__ import annotations

from dataclasses import dataclass

from madpinn.config.vf_variants import stop_at_problem


@dataclass(frozen=True)
class TrainSettings:
    iterations: int
    """length of the schedule (curriculum and learning rate)"""
    batch_size: int
    lr: float
    lr_final: float
    curriculum_fraction: float
    checkpoint_every: int
    loss: str
    output_scale: float
    network: dict
    seed: int
    init_from: str | None
    """fine-tune from this model (None: from scratch)"""
    obstacle_weight: float
    """Weight of the obstacle penalty ``mean(relu-violation)`` (same norm as the residual) added to
    the residual loss; 0 = the paper's loss. The VI's min passes its gradient to one branch only, so
    without it nothing pulls V_s down to ψ where the other branch is smaller (docs/reference/value_functions.md)."""
    stop_at: int | None
    """end the run at this iteration of the schedule (None: at ``iterations``); see :attr:`end_iteration`"""

    @classmethod
    def from_config(cls, vcfg: dict, seed: int) -> "TrainSettings":
        return cls(
            iterations=int(vcfg["iterations"]), batch_size=int(vcfg["batch_size"]), lr=float(vcfg["lr"]),
            lr_final=float(vcfg["lr_final"]), curriculum_fraction=float(vcfg["curriculum_fraction"]),
            checkpoint_every=int(vcfg["checkpoint_every"]), loss=str(vcfg["loss"]),
            output_scale=float(vcfg["output_scale"]), network=dict(vcfg["network"]), seed=int(seed),
            init_from=vcfg["init_from"], obstacle_weight=float(vcfg["obstacle_weight"]),
            stop_at=None if vcfg["stop_at"] is None else int(vcfg["stop_at"]),
        )

    def __post_init__(self):
        problem = stop_at_problem(self.stop_at, self.iterations)
        if problem:
            raise ValueError(problem)

    @property
    def end_iteration(self) -> int:
        """The iteration the run ends at: ``stop_at``, else the schedule's ``iterations``."""
        return self.iterations if self.stop_at is None else self.stop_at


def stage_iterations(settings: TrainSettings, fine_tune_settings: dict | None) -> int:
    """Iterations of every stage together: the training, then ``fine_tune``'s (when configured)."""
    return settings.end_iteration + (int(fine_tune_settings["iterations"]) if fine_tune_settings else 0)
