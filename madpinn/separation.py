"""Who is safe at a radius, from the minimum separations an episode recorded (numpy only, no torch:
the simulation's recorder and the tables both use it)."""

from __future__ import annotations

import numpy as np


def safe_at(min_separation: np.ndarray, radius: float) -> np.ndarray:
    """Agents whose minimum separation ``[..., N]`` (m) stayed above ``radius`` (m), compared in the
    separations' own dtype, as the recorder compares them during the episode (``d ≤ radius`` is a
    collision)."""
    sep = np.asarray(min_separation)
    return ~(sep <= np.asarray(radius, dtype=sep.dtype))
