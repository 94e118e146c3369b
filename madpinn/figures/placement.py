"""Marker placement on a finished axes: deterministic sideways dodging (no random jitter) so that no
two markers overlap, every marker inside the frame."""

from __future__ import annotations

from typing import Sequence

import numpy as np

MAX_STEPS = 40   # sideways steps tried on each side before a marker keeps its overlap
SPACING = 1.2    # centre-to-centre distance of neighbouring markers, in marker widths (room for their edges)


def _inside(box, px: float, py: float, half: float) -> bool:
    return box.x0 + half <= px <= box.x1 - half and box.y0 + half <= py <= box.y1 - half


def dodge(ax, points: Sequence[tuple[float, float]], size_pt: float,
          x_max: float | None = None) -> list[tuple[float, float]]:
    """Positions (data coordinates) for markers of ``size_pt`` points at ``points`` (data
    coordinates) in ``ax``, in the given order: each stays where it is unless that overlaps an
    earlier marker or the frame, else moves sideways (screen x only: its y value stays exact) in
    steps of ``SPACING`` marker widths, trying +1, −1, +2, −2, … steps, the first free place wins;
    ``x_max``: no centre moves past this x (data), e.g. 100 % safety. Call after the axes'
    limits, scales and the figure layout are final (the shift is computed on screen)."""
    fig = ax.figure
    size = SPACING * size_pt * fig.dpi / 72.0  # centre-to-centre distance in pixels
    box = ax.get_window_extent()
    to_px, to_data = ax.transData, ax.transData.inverted()
    placed: list[tuple[float, float]] = []
    out = []
    for x, y in points:
        px, py = to_px.transform((x, y))
        steps = [0] + [s * k for k in range(1, MAX_STEPS + 1) for s in (1, -1)]
        best = (px, py)
        for k in steps:
            cx = px + k * size
            free = all(abs(cx - qx) >= size or abs(py - qy) >= size for qx, qy in placed)
            beyond = x_max is not None and k != 0 and to_data.transform((cx, py))[0] > x_max
            if free and not beyond and _inside(box, cx, py, size / 2 / SPACING):
                best = (cx, py)
                break
        placed.append(best)
        out.append(tuple(float(v) for v in to_data.transform(best)))
    return out


def overlapping_pairs(ax, size_pt: float, labels: Sequence[str], xy: np.ndarray) -> list[tuple[str, str]]:
    """Pairs of ``labels`` whose markers (centres ``xy`` [M, 2], data coordinates) of ``size_pt``
    points overlap on screen in ``ax`` (a check for tests and callers)."""
    size = size_pt * ax.figure.dpi / 72.0
    px = ax.transData.transform(np.asarray(xy, dtype=float))
    return [(labels[i], labels[j]) for i in range(len(px)) for j in range(i + 1, len(px))
            if abs(px[i, 0] - px[j, 0]) < size - 1e-6 and abs(px[i, 1] - px[j, 1]) < size - 1e-6]
