"""The safety level δ the deployed z* search uses (issue 62, not in the paper): a state is
feasible when ``V̂(0, o, z_max) ≤ −δ`` and its budget is the least grid z with ``V̂(0, o, z) ≤ −δ``.
δ = 0 is the paper's rule.

The search is the one z* search (:mod:`madpinn.value_functions.z_search`, cold and warm) run on
:class:`LeveledVHat`, V̂ + δ: its every test ``V̂ + δ ≤ 0`` decides exactly ``V̂ ≤ −δ`` (a rounded
IEEE sum has the sign of the exact sum, and −δ is exact), so the budget is the least grid z with
``V̂ ≤ −δ`` and a state is infeasible where ``V̂(0, o, z_max) > −δ``; the control gradient is V̂'s
own (δ is constant in z and piecewise constant in o). :func:`at_level` returns V̂ itself where
every δ is 0, so a level-0 deployment is today's, bit for bit. Keeping the search's module as it
is keeps the code hash of every job that does not deploy a level (verify-vhat, the trainings,
SafeMARL's cells) unchanged.

A level is one δ for every state, or one per *closing-speed bin* (a Mondrian split): the closing
speed of a 3-agent observation is the largest rate at which any of its pairs approach,
``max_{i<j} −d/dt ‖p_i − p_j‖ = max −(p_ij · v_ij)/‖p_ij‖`` (m/s; negative when every pair
separates), the quantity :mod:`madpinn.evaluation.collisions` reports at collision onsets. The
levels come from a calibration report (:mod:`.calibration`); a bin without a certified level gets
δ = +∞ (no state of it is accepted: the policy's infeasible branch).
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path

import torch

from madpinn.observation import split_observation

ALL_SPEEDS = "all"
"""bin label of an unbinned level (one δ for every closing speed)"""


def closing_speed(obs: torch.Tensor, n_neighbours: int) -> torch.Tensor:
    """Closing speed ``[B]`` (m/s) of observations ``[B, D]``: the largest approach rate over the
    ``(n+1)n/2`` observed pairs (module docstring)."""
    pos, vel, _ = split_observation(obs, n_neighbours)
    iu, ju = torch.triu_indices(n_neighbours + 1, n_neighbours + 1, offset=1, device=obs.device)
    p, v = pos[:, iu] - pos[:, ju], vel[:, iu] - vel[:, ju]                  # [B, P, 2]
    rate = -(p * v).sum(-1) / torch.linalg.vector_norm(p, dim=-1).clamp_min(1e-9)
    return rate.amax(-1)


def speed_bin(speed: torch.Tensor, edges: tuple[float, ...]) -> torch.Tensor:
    """Bin index ``[B]`` (long) of closing speeds ``[B]`` for interior ``edges`` (m/s, ascending):
    bin ``b`` holds ``edges[b−1] ≤ s < edges[b]`` (bin 0 from −∞, the last to +∞)."""
    e = torch.tensor(edges, dtype=speed.dtype, device=speed.device)
    return torch.bucketize(speed, e, right=True)


def bin_labels(edges: tuple[float, ...]) -> list[str]:
    """Readable bins of ``edges``: ``"< 2 m/s"``, ``"2–4 m/s"``, …, ``"≥ 6 m/s"``."""
    if not edges:
        return [ALL_SPEEDS]
    e = [f"{x:g}" for x in edges]
    return [f"< {e[0]} m/s", *(f"{a}–{b} m/s" for a, b in zip(e, e[1:])), f"≥ {e[-1]} m/s"]


def check_edges(edges) -> tuple[float, ...]:
    """Interior closing-speed edges (m/s): finite and strictly ascending (empty: one bin)."""
    e = tuple(float(x) for x in edges)
    if not all(math.isfinite(x) for x in e) or any(b <= a for a, b in zip(e, e[1:])):
        raise ValueError(f"closing-speed edges must be finite and ascend strictly (m/s), got {list(edges)}")
    return e


@dataclass(frozen=True)
class SafetyLevel:
    """δ per closing-speed bin: ``edges`` (m/s, interior, ascending; empty: one δ) and ``deltas``
    (``len(edges) + 1`` values ≥ 0, +∞ where no level is certified), ``n_neighbours`` of the
    observations it reads."""

    edges: tuple[float, ...]
    deltas: tuple[float, ...]
    n_neighbours: int

    def __post_init__(self):
        check_edges(self.edges)
        if len(self.deltas) != len(self.edges) + 1 or not all(d >= 0.0 for d in self.deltas):
            raise ValueError(f"a safety level needs {len(self.edges) + 1} levels δ ≥ 0 (one per bin), got {self.deltas}")

    @property
    def is_zero(self) -> bool:
        """Every δ is 0: the paper's rule."""
        return all(d == 0.0 for d in self.deltas)

    def of(self, obs: torch.Tensor) -> torch.Tensor | float:
        """δ of each observation ``[B, D]``: a float when there is one bin, else ``[B]``."""
        if not self.edges:
            return float(self.deltas[0])
        b = speed_bin(closing_speed(obs, self.n_neighbours), self.edges)
        return torch.tensor(self.deltas, dtype=obs.dtype, device=obs.device)[b]


class LeveledVHat:
    """V̂ + δ(o) with V̂'s ``value`` / ``value_and_grad`` interface (δ from a :class:`SafetyLevel`);
    every other attribute (``system``, ``z_max``, ``net``, …) is the base model's."""

    def __init__(self, base, level: SafetyLevel):
        self.base = base
        self.level = level

    def __getattr__(self, name):
        return getattr(self.base, name)

    def _delta(self, obs: torch.Tensor, like: torch.Tensor):
        d = self.level.of(obs)
        return d.to(like.dtype) if isinstance(d, torch.Tensor) else d

    def value(self, obs: torch.Tensor, z: torch.Tensor, t=0.0) -> torch.Tensor:
        """``V̂(t, o, z) + δ(o)`` ``[B]``; obs ``[B, D]``, z ``[B]``."""
        v = self.base.value(obs, z, t)
        return v + self._delta(obs, v)

    def value_and_grad(self, obs: torch.Tensor, z: torch.Tensor, t=0.0):
        """``(V̂ + δ [B], ∂V̂/∂obs [B, D], ∂V̂/∂z [B])``."""
        v, go, gz = self.base.value_and_grad(obs, z, t)
        return v + self._delta(obs, v), go, gz


def at_level(vhat, level: SafetyLevel | None):
    """``vhat`` itself when ``level`` is None or every δ is 0 (the paper's rule), else
    :class:`LeveledVHat`."""
    return vhat if level is None or level.is_zero else LeveledVHat(vhat, level)


def read_level(path: str | Path, distribution: str, epsilon: float, beta: float, binned: bool,
               n_neighbours: int) -> SafetyLevel:
    """The calibrated level of ``(distribution, ε, β)`` from a calibration report (the JSON of
    ``calibrate-vhat``), with its closing-speed bins when ``binned``; a clear error when the report
    lacks that combination."""
    report = json.loads(Path(path).read_text())
    have = report["distributions"] if "distributions" in report else {}
    if distribution not in have:
        raise ValueError(f"{path}: no calibration on the '{distribution}' distribution (have {sorted(have)})")
    block = have[distribution]
    split = "binned" if binned else "pooled"
    rows = [r for r in block[split] if math.isclose(r["epsilon"], epsilon) and math.isclose(r["beta"], beta)]
    if not rows:
        have = sorted({(r["epsilon"], r["beta"]) for r in block[split]})
        raise ValueError(f"{path}: no {split} level for ε = {epsilon}, β = {beta} on '{distribution}' "
                         f"(have (ε, β) in {have}); add them to value_functions.vhat.validation.calibration")
    rows.sort(key=lambda r: r["bin"])
    edges = tuple(block["speed_edges"]) if binned else ()
    deltas = tuple(math.inf if r["delta"] is None else float(r["delta"]) for r in rows)
    return SafetyLevel(edges, deltas, n_neighbours)
