"""Structured conflict scenarios: head-on pairs and lines, a group converging at once, crossing flows.

Uniform random scenarios (SPEC §2) rarely put many agents into one conflict at the same moment;
these patterns do so by construction, as a reviewer would test a multi-agent controller. Each
scenario is a pure function of ``(pattern, arena, N, seed, index)``: the pattern's geometry
(lengths scale with the arena's half width ``w``), rotated about the arena centre by a random
angle (head-on pairs: placed at random already) and jittered per coordinate by up to
``JITTER·w``, or less where the pattern's own spacing leaves less margin above 2r. Every point stays inside the arena,
starts are separated by ≥ 2r and so are goals (checked; a pattern too dense for the arena raises
:class:`~madpinn.scenarios.ScenarioInfeasibleError`). Zero initial velocity, as for uniform
scenarios.

- ``head_on_pairs``: ⌊N/2⌋ pairs at random places and headings, the two agents of a pair swapping
  places across its midpoint (0.6·w apart); an odd last agent flies a uniform random trip.
- ``head_on_lines``: two facing lines (x = ∓0.6·w, spread over |y| ≤ 0.75·w); each agent's goal
  is its counterpart's start on the other line, so every pair meets head-on at the same time.
- ``circle_swap``: N agents evenly on a circle of radius 0.8·w, goals antipodal: all converge on
  the centre at once.
- ``crossing_flows``: two blocks of ⌈N/2⌉ and ⌊N/2⌋ agents (square grids, spacing 0.22·w) on the
  −x and −y sides, each mirrored to the opposite side: two perpendicular streams that cross in
  the centre at the same time.
"""

from __future__ import annotations

import math

import numpy as np

PATTERNS = ("head_on_pairs", "head_on_lines", "circle_swap", "crossing_flows")
JITTER = 0.02
"""uniform jitter per coordinate, as a fraction of the arena half width"""


def _infeasible(msg: str):
    from madpinn.scenario_errors import ScenarioInfeasibleError

    return ScenarioInfeasibleError(msg)


def _line(count: int, half_span: float) -> np.ndarray:
    return np.zeros(1) if count == 1 else np.linspace(-half_span, half_span, count)


def _head_on_lines(n: int, w: float, rng) -> tuple[np.ndarray, np.ndarray]:
    a, b = (n + 1) // 2, n // 2
    ya, yb = _line(a, 0.75 * w), _line(b, 0.75 * w)
    starts = np.concatenate([np.stack([np.full(a, -0.6 * w), ya], 1), np.stack([np.full(b, 0.6 * w), yb], 1)])
    goals = starts * np.array([-1.0, 1.0])          # mirrored across the y axis: the facing position
    return starts, goals


def _circle_swap(n: int, w: float, rng) -> tuple[np.ndarray, np.ndarray]:
    ang = 2.0 * math.pi * np.arange(n) / n
    starts = 0.8 * w * np.stack([np.cos(ang), np.sin(ang)], 1)
    return starts, -starts


def _block(count: int, spacing: float, offset: float) -> np.ndarray:
    """A square grid of ``count`` points on the −x side: columns from x = −offset outwards, rows centred on y = 0."""
    side = math.ceil(math.sqrt(count))
    k = np.arange(count)
    col, row = k // side, k % side
    rows_here = np.minimum(side, count - col * side)
    return np.stack([-offset - col * spacing, (row - (rows_here - 1) / 2.0) * spacing], 1)


def _crossing_flows(n: int, w: float, rng) -> tuple[np.ndarray, np.ndarray]:
    a, b = (n + 1) // 2, n // 2
    side = math.ceil(math.sqrt(a))
    s = min(0.22 * w, 0.85 * w / (1.5 * (side - 1) + 1))       # the blocks stay within 0.85·w of the centre
    offset = (math.ceil(math.sqrt(a)) - 1) * s / 2.0 + s       # the blocks do not overlap
    east = _block(a, s, offset)                                # moving +x
    north = _block(b, s, offset)[:, ::-1]                      # moving +y (the block on the −y side)
    starts = np.concatenate([east, north])
    goals = np.concatenate([east * np.array([-1.0, 1.0]), north * np.array([1.0, -1.0])])
    return starts, goals


def _head_on_pairs(n: int, w: float, rng, min_sep: float) -> tuple[np.ndarray, np.ndarray]:
    half = 0.3 * w
    starts, goals, placed = [], [], np.empty((0, 2))
    for _ in range(n // 2):
        for _try in range(20_000):
            m = rng.uniform(-(w - half), w - half, size=2)
            th = rng.uniform(0.0, 2.0 * math.pi)
            d = half * np.array([math.cos(th), math.sin(th)])
            p, q = m - d, m + d
            if np.all(np.abs(np.stack([p, q])) <= (1.0 - JITTER) * w) and (
                    placed.size == 0 or np.min(np.linalg.norm(placed[:, None] - np.stack([p, q])[None], axis=-1)) >= min_sep):
                break
        else:
            raise _infeasible(f"head_on_pairs: no room for pair {len(starts) // 2 + 1} of {n // 2} "
                              f"(arena half width {w} m, separation {min_sep} m)")
        starts += [p, q]
        goals += [q, p]
        placed = np.concatenate([placed, [p, q]])
    if n % 2:   # the odd agent: a uniform random trip, separated from the pairs' points
        for which in (starts, goals):
            for _try in range(20_000):
                c = rng.uniform(-(1.0 - JITTER) * w, (1.0 - JITTER) * w, size=2)
                if np.min(np.linalg.norm(np.asarray(which) - c, axis=-1)) >= min_sep:
                    which.append(c)
                    break
            else:
                raise _infeasible(f"head_on_pairs: no room for the odd agent (arena half width {w} m)")
    return np.asarray(starts), np.asarray(goals)


_SHAPES = {"head_on_lines": _head_on_lines, "circle_swap": _circle_swap, "crossing_flows": _crossing_flows}


def _min_distance(p: np.ndarray) -> float:
    if len(p) < 2:
        return math.inf
    d = np.linalg.norm(p[:, None] - p[None], axis=-1)
    return float(np.min(d[np.triu_indices(len(p), 1)]))


def conflict_scenario(pattern: str, n_agents: int, half_width: float, min_separation: float,
                      rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """``(starts [N, 2], goals [N, 2])`` float64 (m) of one scenario of ``pattern`` (module docstring)."""
    if pattern not in PATTERNS:
        raise ValueError(f"unknown scenario pattern '{pattern}' (have uniform, {', '.join(PATTERNS)})")
    w, min_sep = float(half_width), float(min_separation)
    if pattern == "head_on_pairs":
        starts, goals = _head_on_pairs(n_agents, w, rng, min_sep)
    else:
        starts, goals = _SHAPES[pattern](n_agents, w, rng)
        th = rng.uniform(0.0, 2.0 * math.pi)          # pairs already have random places and headings
        rot = np.array([[math.cos(th), -math.sin(th)], [math.sin(th), math.cos(th)]])
        starts, goals = starts @ rot.T, goals @ rot.T
    nominal = min(_min_distance(starts), _min_distance(goals))
    if nominal < min_sep:
        raise _infeasible(f"{pattern}: agents only {nominal:.3f} m apart (< separation {min_sep} m) with N = {n_agents} "
                          f"in an arena of half width {w} m; use fewer agents or a larger arena")
    amp = min(JITTER * w, (nominal - min_sep) / 3.0)   # |Δ| ≤ 2√2·amp < the margin: jitter keeps the separation
    if math.isfinite(amp):
        starts = starts + rng.uniform(-amp, amp, size=starts.shape)
        goals = goals + rng.uniform(-amp, amp, size=goals.shape)
    for name, pts in (("starts", starts), ("goals", goals)):
        if np.any(np.abs(pts) > w):
            raise _infeasible(f"{pattern}: {name} leave the arena (half width {w} m) for N = {n_agents}")
        sep = _min_distance(pts)
        if sep < min_sep:
            raise _infeasible(f"{pattern}: {name} only {sep:.3f} m apart (< separation {min_sep} m) with N = {n_agents} "
                              f"in an arena of half width {w} m; use fewer agents or a larger arena")
    return starts, goals
