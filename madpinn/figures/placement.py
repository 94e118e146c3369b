"""Marker placement on a finished axes: deterministic sideways dodging (no random jitter) so that no
two markers overlap, every marker inside the frame; :func:`draw_points` draws runs' markers so."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np

MAX_STEPS = 40   # sideways steps tried on each side before a marker keeps its overlap
SPACING = 1.2    # centre-to-centre distance of neighbouring markers, in marker widths (room for their edges)


def _inside(box, px: float, py: float, half: float) -> bool:
    return box.x0 + half <= px <= box.x1 - half and box.y0 + half <= py <= box.y1 - half


def dodge(ax, points: Sequence[tuple[float, float]], size_pt: float, x_max: float | None = None,
          fixed: Sequence[tuple[float, float]] = ()) -> list[tuple[float, float]]:
    """Positions (data coordinates) for markers of ``size_pt`` points at ``points`` (data
    coordinates) in ``ax``, in the given order: each stays where it is unless that overlaps an
    earlier marker or the frame, else moves sideways (screen x only: its y value stays exact) in
    steps of ``SPACING`` marker widths, trying +1, −1, +2, −2, … steps, the first free place wins;
    ``x_max``: no centre moves past this x (data), e.g. 100 % safety; ``fixed``: centres (data) of
    other glyphs of about this size that the markers must not cover. Call after the axes' limits,
    scales and the figure layout are final (the shift is computed on screen)."""
    fig = ax.figure
    size = SPACING * size_pt * fig.dpi / 72.0  # centre-to-centre distance in pixels
    box = ax.get_window_extent()
    to_px, to_data = ax.transData, ax.transData.inverted()
    placed = [tuple(to_px.transform(f)) for f in fixed]
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


@dataclass(frozen=True)
class Point:
    """One run's marker: centre (``x``, ``y``) in data units with bar lengths ``x_lo``, ``x_hi``,
    ``y_lo``, ``y_hi`` (≥ 0; 0: no bar), its legend ``label``, ``colour`` and ``marker`` shape."""

    label: str
    colour: tuple
    marker: str
    x: float
    x_lo: float
    x_hi: float
    y: float
    y_lo: float
    y_hi: float


def draw_points(ax, points: Sequence[Point], size_pt: float, off_scale: Sequence[bool] | None = None,
                fixed: Sequence[tuple[float, float]] = ()) -> None:
    """Hollow markers of ``size_pt`` points, moved sideways where they would overlap (:func:`dodge`,
    in the given order; a thin line joins a moved marker to a dot at its true position), the x bar
    around the true x, the y bar through the marker. ``off_scale``: points above the y range, drawn
    on the top edge with their y value and an upward arrow beside them (placed first); ``fixed``:
    centres of other glyphs the markers must not cover. Call once the axes' limits and the figure
    layout are final."""
    off = list(off_scale) if off_scale is not None else [False] * len(points)
    half_px = size_pt * ax.figure.dpi / 72.0 / 2
    box = ax.get_window_extent()
    top_y = float(ax.transData.inverted().transform((box.x0, box.y1 - half_px - 2))[1])
    wanted = [(p.x, top_y if o else p.y) for p, o in zip(points, off)]
    order = [i for i, o in enumerate(off) if o] + [i for i, o in enumerate(off) if not o]
    placed = dict(zip(order, dodge(ax, [wanted[i] for i in order], size_pt, fixed=fixed)))
    for i, p in enumerate(points):
        (x0, _), (x, y) = wanted[i], placed[i]
        if p.x_lo > 0 or p.x_hi > 0:
            ax.errorbar(x0, y, xerr=[[p.x_lo], [p.x_hi]], fmt="none", capsize=2.5, elinewidth=1.0, color=p.colour, zorder=2)
        if not off[i] and (p.y_lo > 0 or p.y_hi > 0):
            ax.errorbar(x, y, yerr=[[p.y_lo], [p.y_hi]], fmt="none", capsize=2.5, elinewidth=1.0, color=p.colour, zorder=2)
        if not np.isclose(x, x0):
            ax.plot([x0, x], [y, y], "-", color=p.colour, lw=0.8, zorder=2, label="_moved")
            ax.plot(x0, y, ".", color=p.colour, ms=4, zorder=3, label="_true")
        ax.plot(x, y, p.marker, ms=size_pt, mfc="white", mew=1.6, color=p.colour, label=p.label, zorder=4 + i)
    _label_off_scale(ax, points, [placed[i] for i in range(len(points))], off, size_pt)


def _label_off_scale(ax, points, placed, off, size_pt: float) -> None:
    """Each off-scale point's y value and an upward arrow, in its colour, beside the outermost
    off-scale marker (right of it in the axes' left half, else left), one line per point stacked
    downwards, so that labels of markers side by side on the top edge never cover each other."""
    idx = [i for i, o in enumerate(off) if o]
    if not idx:
        return
    box = ax.get_window_extent()
    px = {i: ax.transData.transform(placed[i])[0] for i in idx}
    right = sum(px.values()) / len(idx) < 0.5 * (box.x0 + box.x1)
    anchor = (max if right else min)(idx, key=px.get)
    for k, i in enumerate(sorted(idx, key=px.get, reverse=not right)):
        ax.annotate(f"{points[i].y:.2f} ↑", placed[anchor], xytext=(0.9 * size_pt if right else -0.9 * size_pt, -9.0 * k),
                    textcoords="offset points", ha="left" if right else "right", va="center",
                    fontsize=8, color=points[i].colour, zorder=60)
