"""Straight-line encounters of a scenario: how many conflicts its layout poses (issue 60).

Each agent flies straight from its start to its goal at a constant speed, all leaving together
and stopping at their goals; two agents *encounter* when these paths come within a radius of each
other during the horizon. The count per agent is the scenario's load, independent of any policy:
it puts the small and the large arena, and the start/goal laws, on one axis.
"""

from __future__ import annotations

import numpy as np


def straight_line_encounters(starts: np.ndarray, goals: np.ndarray, speed: float, radius: float,
                             horizon: float, dt: float = 0.01, chunk: int = 25) -> np.ndarray:
    """Per agent, the number of others whose straight, constant-``speed`` (m/s) trip comes within
    ``radius`` (m) of its own during ``[0, horizon]`` (s), sampled every ``dt`` (s).
    ``starts``, ``goals``: ``[..., N, 2]`` (m); returns ``[..., N]`` int."""
    starts, goals = np.asarray(starts, dtype=float), np.asarray(goals, dtype=float)
    t = np.arange(0.0, horizon + 1e-9, dt)
    d = goals - starts
    length = np.linalg.norm(d, axis=-1, keepdims=True)                          # [..., N, 1]
    unit = np.divide(d, length, out=np.zeros_like(d), where=length > 0)
    n = starts.shape[-2]
    close = np.zeros(starts.shape[:-2] + (n, n), dtype=bool)
    for k in range(0, len(t), chunk):
        travelled = np.minimum(speed * t[k:k + chunk, None], length[..., None, :, 0])   # [..., T, N]
        pos = starts[..., None, :, :] + travelled[..., None] * unit[..., None, :, :]   # [..., T, N, 2]
        gap = np.linalg.norm(pos[..., :, None, :] - pos[..., None, :, :], axis=-1).min(-3)
        close |= gap <= radius
    close &= ~np.eye(n, dtype=bool)
    return close.sum(-1)
