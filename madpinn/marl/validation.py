"""Validation learning curve of a MARL training run and its plateau rule.

Every ``every`` iterations the current policy is evaluated on a validation seed (≥ 100, never a
protocol seed) through the package's own evaluation cells (the command layer runs them:
``madpinn.commands.defmarl``); the agents' safety rate (%) at the training agent count is the
curve the plateau rule reads.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping, Sequence

MIN_VALIDATION_SEED = 100
"""validation seeds start here; protocol seeds 0-4 are never used for choices"""


@dataclass(frozen=True)
class ValidationSettings:
    """``methods.defmarl.validation``."""

    every: int
    """iterations between evaluations (0: none)"""
    seed: int
    """scenario seed of the evaluation cells (≥ 100)"""
    scenarios: int
    """scenarios per cell"""
    agent_counts: tuple[int, ...]
    """agent counts evaluated besides the run's training agent counts"""
    backend: str
    """simulation backend of the cells"""
    study: str
    """study whose cell settings (arena, pattern, sim) the cells use"""
    window: int
    """plateau rule: evaluations per window"""
    min_gain: float
    """plateau rule: points (%) the last window's mean safety must gain over the window before it"""
    stop: bool
    """end training at the plateau (otherwise only report it)"""

    @classmethod
    def from_config(cls, d: Mapping) -> "ValidationSettings":
        seed = int(d["seed"])
        if seed < MIN_VALIDATION_SEED:
            raise ValueError(f"validation seed must be ≥ {MIN_VALIDATION_SEED} (protocol seeds are for the tables), got {seed}")
        p = d["plateau"]
        return cls(every=int(d["every"]), seed=seed, scenarios=int(d["scenarios"]),
                   agent_counts=tuple(int(n) for n in d["agent_counts"]), backend=str(d["backend"]), study=str(d["study"]),
                   window=int(p["window"]), min_gain=float(p["min_gain"]), stop=bool(p["stop"]))

    def counts(self, training_counts: Sequence[int]) -> list[int]:
        """Agent counts of one evaluation: the training counts, then the extra ones."""
        return list(dict.fromkeys([*map(int, training_counts), *self.agent_counts]))


def plateau(safety: Sequence[float], window: int, min_gain: float) -> bool:
    """True when the mean of the last ``window`` values (safety, %) is at most ``min_gain``
    points above the mean of the ``window`` values before them (needs ``2·window`` values)."""
    if window < 1 or len(safety) < 2 * window:
        return False
    last = sum(safety[-window:]) / window
    before = sum(safety[-2 * window : -window]) / window
    return last <= before + min_gain
