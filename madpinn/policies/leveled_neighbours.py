"""Deploying a calibrated safety level δ in the MAD-PINN policy (issue 62, not in the paper): V̂ at
the level (:func:`madpinn.value_functions.safety_level.at_level`) and the ``value`` neighbour
ranking at the same level.

Ranking. The ``value`` strategy picks the n sensed partners with the lowest ``V_s`` (m)
(:mod:`madpinn.policies.neighbours`). At a level, a pair is ranked by ``V_s − δ``, the clearance
left beyond the margin δ the calibration asks of encounters at the pair's closing speed
(``−d/dt ‖p_i − p_j‖``, m/s, the quantity the bins of :mod:`madpinn.value_functions.safety_level`
split). With one δ for every speed this is the order of ``V_s`` itself, so the plain selector is
kept (same selections, exactly); with bins each pair is shifted by its own bin's δ, scored on every
sensed in-domain pair (:func:`madpinn.policies.neighbours.pair_scores`, no bound pruning: the
bounds of the plain ranking assume unshifted scores), ties broken by the lower index as there. A
bin without a certified level (δ = +∞) shifts by :data:`UNCERTIFIED_SHIFT` instead, so its pairs
rank first while staying finite (``+∞`` marks an absent partner).
"""

from __future__ import annotations

import json
from pathlib import Path

import torch

from madpinn.policies.neighbours import Selector, pair_scores, relative_states, select_lowest
from madpinn.value_functions.safety_level import SafetyLevel, at_level, read_level, speed_bin

UNCERTIFIED_SHIFT = 1.0e3
"""m: the ranking's stand-in for δ = +∞ (far above any V_s of the trained box, 2·√2·2 m)"""


def pair_closing_speed(state: torch.Tensor, agent) -> torch.Tensor:
    """``−d/dt ‖p_i − p_j‖`` ``[S, N, N]`` (m/s) of every ordered pair of ``state [S, N, 2d]`` of
    agents of model ``agent`` (0 on the diagonal)."""
    x = relative_states(state)
    p, v = agent.position(x), agent.velocity(x)
    return -(p * v).sum(-1) / torch.linalg.vector_norm(p, dim=-1).clamp_min(1e-9)


def pair_shift(state: torch.Tensor, level: SafetyLevel, agent) -> torch.Tensor:
    """δ of each ordered pair's closing-speed bin ``[S, N, N]`` (+∞ -> :data:`UNCERTIFIED_SHIFT`)."""
    deltas = torch.tensor(level.deltas, dtype=state.dtype, device=state.device).clamp(max=UNCERTIFIED_SHIFT)
    return deltas[speed_bin(pair_closing_speed(state, agent), level.edges)]


def leveled_value_selector(vs, n: int, level: SafetyLevel, chunk: int = 65536, radius: float | None = None) -> Selector:
    """``value`` ranking at a per-bin level: the n sensed partners with the lowest ``V_s − δ(bin)``
    (module docstring)."""
    if not level.edges:
        raise ValueError("one δ for every speed ranks as V_s itself: use the plain value selector")

    def select(state: torch.Tensor) -> torch.Tensor:
        scores = pair_scores(state, vs, chunk, radius=radius)
        return select_lowest(scores - pair_shift(state, level, vs.system.agent), n, exact_ties=True)

    return select


def deploy_level(vhat, selector: Selector, strategy: str, vs, report: str | Path, conformal: dict, spec,
                 chunk: int) -> tuple:
    """``(V̂ at the level, selector)`` of a run's ``conformal`` setting ``{distribution, epsilon,
    beta, binned}``, δ read from the ``calibrate-vhat`` ``report`` of this V̂ (a clear error when
    the report calibrated another V̂ or lacks the setting)."""
    meta = json.loads(Path(report).read_text()).get("model_config_hash")
    if meta != vhat.meta.get("config_hash"):
        raise ValueError(f"{report} calibrates the V̂ of training hash {meta}, but this run loads "
                         f"{vhat.meta.get('config_hash')}: calibrate the run's own V̂")
    level = read_level(report, str(conformal["distribution"]), float(conformal["epsilon"]), float(conformal["beta"]),
                       bool(conformal["binned"]), spec.n_neighbours)
    if strategy == "value" and level.edges and not level.is_zero:
        selector = leveled_value_selector(vs, spec.n_neighbours, level, chunk, spec.sensing_radius)
    return at_level(vhat, level), selector
