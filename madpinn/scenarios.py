"""Scenario generation (SPEC §2): starts and goals uniform in a square arena, pairwise
separation ≥ 2r among starts and among goals, zero initial velocity; or goals near the starts
(``goals_within_<R>m``: each goal uniform in the disc of radius R around its own start, issue 60);
or a structured conflict pattern (:mod:`madpinn.conflicts`: head-on pairs and lines, circle
swap, crossing flows).

A scenario is a pure function of ``(arena name, pattern, N, seed, index)``: every method sees
identical initial conditions.
"""

from __future__ import annotations

import math
import re
import zlib
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from madpinn.scenario_errors import ScenarioInfeasibleError  # noqa: F401 - raised here, imported from here by callers

if TYPE_CHECKING:
    import torch

# Random sequential addition of disks jams near 54.7 % coverage; refuse well before it.
_MAX_RSA_COVERAGE = 0.45
_MAX_TRIES_PER_POINT = 20_000


@dataclass(frozen=True)
class Arena:
    """Square arena ``[-half_width, half_width]²`` (m) and its episode length (s)."""

    name: str
    half_width: float
    episode_s: float

    @classmethod
    def from_config(cls, cfg: dict, name: str) -> "Arena":
        a = cfg["arenas"][name]
        return cls(name=name, half_width=float(a["half_width"]), episode_s=float(a["episode_s"]))


def horizon_steps(horizons_s, episode_s: float, dt: float) -> tuple[int, ...]:
    """Simulation steps ``(sorted)`` of the earlier horizons ``horizons_s`` (s) of an episode of
    ``episode_s`` at step ``dt`` (s); a horizon outside the episode or between steps is an error."""
    for h in horizons_s:
        problem = horizon_problem(float(h), episode_s, dt)
        if problem:
            raise ValueError(problem)
    return tuple(sorted(int(round(float(h) / dt)) for h in horizons_s))


def horizon_problem(horizon_s: float, episode_s: float, dt: float) -> str | None:
    """Why ``horizon_s`` cannot be read from an episode of ``episode_s`` at step ``dt`` (all s), or None."""
    if not 0.0 < horizon_s < episode_s:
        return f"cost horizon {horizon_s:g} s must lie inside the episode (0, {episode_s:g}) s"
    steps = horizon_s / dt
    if abs(steps - round(steps)) > 1e-6:
        return f"cost horizon {horizon_s:g} s is not a whole number of {dt:g} s steps"
    return None


def _coverage(n: int, half_width: float, min_sep: float) -> float:
    """Fraction of the (inflated) arena covered by n disks of diameter min_sep."""
    side = 2.0 * half_width + min_sep
    return n * math.pi * (min_sep / 2.0) ** 2 / side**2


def max_agents(half_width: float, min_separation: float) -> int:
    """Most agents the sampler places in ``[-half_width, half_width]²`` at least ``min_separation`` (m,
    = 2ρ) apart.

    Disks of radius ρ around the points lie in the square inflated by ρ (side ``2·half_width + 2ρ``).
    Any packing covers at most π/√12 ≈ 91 % of it (hexagonal); random sequential addition jams near
    54.7 %, so the sampler stops at ``_MAX_RSA_COVERAGE`` (45 %): about half the packing bound.
    Config validation rejects larger agent counts before any job runs.
    """
    min_sep = float(min_separation)
    return int(_MAX_RSA_COVERAGE * (2.0 * half_width + min_sep) ** 2 / (math.pi * (min_sep / 2.0) ** 2))


def _check_feasible(n: int, half_width: float, min_sep: float) -> None:
    max_n = max_agents(half_width, min_sep)
    if n > max_n:
        raise ScenarioInfeasibleError(
            f"cannot place {n} agents with separation {min_sep} m in [-{half_width}, {half_width}]²: "
            f"disk coverage {_coverage(n, half_width, min_sep):.0%} exceeds the {_MAX_RSA_COVERAGE:.0%} limit of "
            f"rejection sampling (at most {max_n} agents); use a larger arena or fewer agents"
        )


def _sample_separated(rng: np.random.Generator, n: int, half_width: float, min_sep: float) -> np.ndarray:
    pts = np.empty((n, 2))
    k, tries = 0, 0
    while k < n:
        cand = rng.uniform(-half_width, half_width, size=(64, 2))
        for c in cand:
            tries += 1
            if k == 0 or np.min(np.sum((pts[:k] - c) ** 2, axis=1)) >= min_sep**2:
                pts[k] = c
                k += 1
                tries = 0
                if k == n:
                    break
            elif tries > _MAX_TRIES_PER_POINT:
                raise ScenarioInfeasibleError(
                    f"rejection sampling found no free spot for agent {k + 1}/{n} after "
                    f"{_MAX_TRIES_PER_POINT} tries (arena half-width {half_width} m, separation {min_sep} m)"
                )
    return pts


def scenario_rng(arena: str, n_agents: int, seed: int, index: int) -> np.random.Generator:
    """Independent, reproducible stream for one scenario."""
    arena_code = zlib.crc32(arena.encode())
    return np.random.default_rng(np.random.SeedSequence([int(seed), int(n_agents), arena_code, int(index)]))


UNIFORM = "uniform"
"""the SPEC §2 scenarios; any other pattern is a local goal law (:func:`local_goal_radius`) or one
of :data:`madpinn.conflicts.PATTERNS`"""
LOCAL_GOALS = re.compile(r"goals_within_([1-9][0-9]*)m")
"""pattern of a local goal law: ``goals_within_<R>m``, R in whole metres"""


def local_goal_radius(pattern: str) -> float | None:
    """R (m) of a local goal law ``goals_within_<R>m``; None for any other pattern."""
    match = LOCAL_GOALS.fullmatch(pattern)
    return float(match.group(1)) if match else None


def _sample_local_goals(rng: np.random.Generator, starts: np.ndarray, radius: float, half_width: float,
                        min_sep: float) -> np.ndarray:
    """Goal k uniform in the disc of ``radius`` around ``starts[k]`` intersected with the arena, at
    least ``min_sep`` from goals 0..k-1: a draw outside the arena or too close is **resampled**
    (never clipped, which would pile goals on the walls)."""
    goals = np.empty_like(starts)
    for k, start in enumerate(starts):
        for tries in range(1, _MAX_TRIES_PER_POINT + 1):
            rho, theta = radius * math.sqrt(rng.uniform()), rng.uniform(0.0, 2.0 * math.pi)
            c = start + rho * np.array([math.cos(theta), math.sin(theta)])
            if np.all(np.abs(c) <= half_width) and (k == 0 or np.min(np.sum((goals[:k] - c) ** 2, axis=1)) >= min_sep**2):
                goals[k] = c
                break
        else:
            raise ScenarioInfeasibleError(
                f"no goal within {radius} m of agent {k + 1}/{len(starts)}'s start after {_MAX_TRIES_PER_POINT} "
                f"tries (arena half-width {half_width} m, separation {min_sep} m)")
    return goals


def generate_scenario(arena: Arena, n_agents: int, seed: int, index: int, min_separation: float,
                      pattern: str = UNIFORM):
    """Return ``(starts [N,2], goals [N,2])`` float64 numpy arrays (m); starts (and goals) are at
    least ``min_separation`` (m) apart (the evaluation passes ``sim.start_separation``). A local goal
    law keeps the uniform scenario's starts (the same stream) and draws its goals from its own."""
    if n_agents < 1:
        raise ScenarioInfeasibleError(f"need at least one agent, got {n_agents}")
    min_sep = float(min_separation)
    radius = local_goal_radius(pattern)
    if pattern != UNIFORM and radius is None:   # its own random stream (the uniform scenarios' streams are unchanged)
        from madpinn.conflicts import conflict_scenario

        rng = scenario_rng(f"{arena.name}/{pattern}", n_agents, seed, index)
        return conflict_scenario(pattern, n_agents, arena.half_width, min_sep, rng)
    _check_feasible(n_agents, arena.half_width, min_sep)
    rng = scenario_rng(arena.name, n_agents, seed, index)
    starts = _sample_separated(rng, n_agents, arena.half_width, min_sep)
    if radius is not None:
        rng = scenario_rng(f"{arena.name}/{pattern}", n_agents, seed, index)
        return starts, _sample_local_goals(rng, starts, radius, arena.half_width, min_sep)
    goals = _sample_separated(rng, n_agents, arena.half_width, min_sep)
    return starts, goals


def generate_scenarios(
    arena: Arena,
    n_agents: int,
    seed: int,
    count: int,
    min_separation: float,
    device: torch.device | str = "cpu",
    dtype: torch.dtype | None = None,
    first_index: int = 0,
    pattern: str = UNIFORM,
) -> tuple[torch.Tensor, torch.Tensor]:
    """Scenarios ``first_index … first_index+count-1`` of ``pattern``: ``(starts, goals)`` each
    ``[S, N, 2]`` (``dtype`` None: float32)."""
    import torch   # here, so that config validation (``max_agents``) does not import torch

    dtype = torch.float32 if dtype is None else dtype
    if count < 1:
        raise ValueError(f"scenario count must be ≥ 1, got {count}")
    pairs = [generate_scenario(arena, n_agents, seed, first_index + i, min_separation, pattern) for i in range(count)]
    starts = torch.as_tensor(np.stack([p[0] for p in pairs]), dtype=dtype, device=device)
    goals = torch.as_tensor(np.stack([p[1] for p in pairs]), dtype=dtype, device=device)
    return starts, goals
