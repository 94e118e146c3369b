"""Batched closed-loop simulation over ``[scenarios, agents]``."""

from madpinn.simulation.backend import DoubleIntegratorBackend, SimBackend, make_backend
from madpinn.simulation.recorder import EpisodeRecorder, EpisodeResult
from madpinn.simulation.simulator import run_episode

__all__ = ["SimBackend", "DoubleIntegratorBackend", "make_backend", "EpisodeRecorder", "EpisodeResult", "run_episode"]
