"""The epigraph budget search of SPEC §6 on a dyadic z grid: the one z* search of the package.

``z* = min{z ∈ [0, z_max] : V̂(0, o, z) ≤ 0}`` to a tolerance of one grid cell
``h = z_max / 2^steps``: every V̂ evaluation is at a grid point ``z_i = i·h``, ``i = 1 … 2^steps``
(indices are integers, so every search evaluates V̂ at bitwise identical z). The deployed policy
(:mod:`madpinn.policies.madpinn`), ``verify-vhat`` (:mod:`.verification`) and the V̂ heatmap
(:mod:`.validation`) all build their grid with :meth:`ZGrid.of` from ``methods.madpinn.z_tolerance``
and search it with :func:`cold_search` (the policy's warm-started variants,
:mod:`madpinn.policies.z_search`, reuse this grid, :func:`grid_value`, :func:`bisect` and
:func:`search_result`, and return the same feasibility flag and, where V̂ is monotone in z, the
same index). So the verification certifies the budgets the deployed search returns, at the
deployed tolerance.

:func:`cold_search`: ``V̂(z_max)``, then ``steps`` halvings of ``[0, z_max]`` (the paper's
bisection; 1 + steps value rows + 1 gradient row per agent). Where ``V̂(z_max) > 0`` (unsafe):
``z* = z_max``, ``feasible = False``. Every feasible answer ``i`` is a crossing of the grid,
``V̂(z_i) ≤ 0`` and ``V̂(z_{i−1}) > 0`` (``i = 1``: ``z_0 = 0`` is never evaluated). It also
returns the control gradient ``∂V̂/∂o`` at ``(t = 0, o, z*)``, so a search's cost is counted in
network rows: ``value_rows`` (V̂ only) and ``grad_rows`` (V̂ and its gradient).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import torch


def bisection_steps(z_tolerance: float) -> int:
    """Halvings of ``[0, z_max]`` that leave a bracket ≤ ``z_tolerance·z_max`` (10 for 1e-3)."""
    if not 0.0 < z_tolerance < 1.0:
        raise ValueError(f"z_tolerance must be in (0, 1), got {z_tolerance}")
    return max(1, math.ceil(math.log2(1.0 / z_tolerance)))


@dataclass(frozen=True)
class ZGrid:
    """Grid ``z_i = i·z_max/2^steps`` of the search (indices ``0 … cells``; 0 is never evaluated)."""

    z_max: float
    steps: int

    @classmethod
    def of(cls, z_max: float, z_tolerance: float) -> "ZGrid":
        """The deployed grid: cells of at most ``z_tolerance·z_max`` (``methods.madpinn.z_tolerance``)."""
        return cls(float(z_max), bisection_steps(z_tolerance))

    @property
    def cells(self) -> int:
        return 2**self.steps

    def z(self, idx: torch.Tensor, dtype: torch.dtype) -> torch.Tensor:
        """Budgets ``[B]`` (same units as V̂'s z) of integer indices ``[B]``."""
        return idx.to(torch.float64).mul(self.z_max / self.cells).to(dtype)


@dataclass
class ZSearchResult:
    """``index [B]`` (long), ``z [B]``, ``feasible [B]`` (False: ``V̂(z_max) > 0``, z* = z_max),
    ``grad [B, D]`` = ∂V̂/∂o at z* (None where the caller asked for none), ``hit [B]`` (warm:
    answer = prediction, 2 rows or fewer), network rows evaluated: ``value_rows``, ``grad_rows``."""

    index: torch.Tensor
    z: torch.Tensor
    feasible: torch.Tensor
    grad: torch.Tensor | None
    hit: torch.Tensor
    value_rows: int
    grad_rows: int


def grid_value(vhat, obs: torch.Tensor, grid: ZGrid, idx: torch.Tensor) -> torch.Tensor:
    """``V̂(0, o, z_idx)`` ``[B]`` for observations ``[B, D]`` and grid indices ``[B]``."""
    return vhat.value(obs, grid.z(idx, obs.dtype), 0.0)


def search_result(vhat, obs, grid: ZGrid, idx, feasible, hit, value_rows, grad_rows, grad=None, todo=None):
    """The :class:`ZSearchResult` of answers ``idx``: fills the gradient at ``z_idx`` for rows
    ``todo`` (all rows when ``grad`` is None)."""
    if grad is None:
        _, grad, _ = vhat.value_and_grad(obs, grid.z(idx, obs.dtype), 0.0)
        grad_rows += obs.shape[0]
    elif todo is not None and todo.numel():
        _, g, _ = vhat.value_and_grad(obs[todo], grid.z(idx[todo], obs.dtype), 0.0)
        grad = grad.clone()
        grad[todo] = g
        grad_rows += int(todo.numel())
    return ZSearchResult(idx, grid.z(idx, obs.dtype), feasible, grad, hit, value_rows, grad_rows)


def bisect(vhat, obs, grid: ZGrid, lo, hi):
    """Halve brackets ``(lo, hi]`` (V̂(lo) > 0 or lo = 0, V̂(hi) ≤ 0) to one cell; returns
    ``(hi, value rows)``; each round evaluates the rows whose bracket is still wider than a cell."""
    rows = 0
    while bool((hi - lo > 1).any()):
        act = (hi - lo > 1).nonzero(as_tuple=True)[0]
        mid = (lo[act] + hi[act]) // 2
        ok = grid_value(vhat, obs[act], grid, mid) <= 0
        rows += int(act.numel())
        hi[act] = torch.where(ok, mid, hi[act])
        lo[act] = torch.where(ok, lo[act], mid)
    return hi, rows


def cold_search(vhat, obs: torch.Tensor, grid: ZGrid, with_grad: bool = True) -> ZSearchResult:
    """The paper's bisection on all rows (see module docstring); ``obs [B, D]``.
    ``with_grad=False``: no gradient row (``grad`` is None; the budgets alone, as the
    verification and the heatmap need them)."""
    B = obs.shape[0]
    top = torch.full((B,), grid.cells, dtype=torch.long, device=obs.device)
    feasible = grid_value(vhat, obs, grid, top) <= 0
    lo, hi = torch.zeros_like(top), top.clone()
    rows = B
    for _ in range(grid.steps):
        mid = (lo + hi) // 2
        ok = grid_value(vhat, obs, grid, mid) <= 0
        rows += B
        hi = torch.where(ok, mid, hi)
        lo = torch.where(ok, lo, mid)
    idx = torch.where(feasible, hi, top)
    hit = torch.zeros_like(feasible)
    if not with_grad:
        return ZSearchResult(idx, grid.z(idx, obs.dtype), feasible, None, hit, rows, 0)
    return search_result(vhat, obs, grid, idx, feasible, hit, rows, 0)


def min_feasible_z(vhat, obs: torch.Tensor, z_tolerance: float):
    """``(z* [B], feasible [B] bool)`` of :func:`cold_search` on the grid of ``z_tolerance``
    (the deployed ``methods.madpinn.z_tolerance``); ``z* = z_max`` where ``V̂(0, o, z_max) > 0``."""
    r = cold_search(vhat, obs, ZGrid.of(vhat.z_max, z_tolerance), with_grad=False)
    return r.z, r.feasible
