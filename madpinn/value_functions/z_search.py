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
bisection; 1 + steps value rows + 1 gradient row per agent, the halvings only where the agent is
feasible). Where ``V̂(z_max) > 0`` (unsafe): ``z* = z_max``, ``feasible = False``. Its answers,
budgets and gradients are bitwise those of the search it replaced in issue 48, which ran every
halving on every agent (``benchmarks/zsearch_reference.py``, ``tests/test_zsearch_exact.py``). Every feasible answer ``i`` is a crossing of the grid,
``V̂(z_i) ≤ 0`` and ``V̂(z_{i−1}) > 0`` (``i = 1``: ``z_0 = 0`` is never evaluated). It also
returns the control gradient, V̂'s gradient with respect to the observed velocities at
``(t = 0, o, z*)`` (:func:`velocity_grad`: for a :class:`VHat` the network's input gradient alone,
bitwise the velocity block of ``value_and_grad``), so a search's cost is counted in network rows:
``value_rows`` (V̂ only) and ``grad_rows`` (V̂ or its gradient).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import torch

from madpinn.value_functions.model import VHat


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
    ``velocity_grad [B, n+1, d]`` = ∂V̂/∂v_a at z*, what the control reads (None where the caller
    asked for none), ``hit [B]`` (warm:
    answer = prediction, 2 rows or fewer), network rows evaluated: ``value_rows``, ``grad_rows``."""

    index: torch.Tensor
    z: torch.Tensor
    feasible: torch.Tensor
    velocity_grad: torch.Tensor | None
    hit: torch.Tensor
    value_rows: int
    grad_rows: int


def grid_value(vhat, obs: torch.Tensor, grid: ZGrid, idx: torch.Tensor) -> torch.Tensor:
    """``V̂(0, o, z_idx)`` ``[B]`` for observations ``[B, D]`` and grid indices ``[B]``."""
    return vhat.value(obs, grid.z(idx, obs.dtype), 0.0)


def search_result(vhat, obs, grid: ZGrid, idx, feasible, hit, value_rows, grad_rows, grad=None, todo=None):
    """The :class:`ZSearchResult` of answers ``idx``: fills the gradient ``grad [B, D]`` (∂V̂/∂o)
    at ``z_idx`` for rows ``todo`` (all rows when ``grad`` is None) and keeps its velocity block."""
    if grad is None:
        _, grad, _ = vhat.value_and_grad(obs, grid.z(idx, obs.dtype), 0.0)
        grad_rows += obs.shape[0]
    elif todo is not None and todo.numel():
        _, g, _ = vhat.value_and_grad(obs[todo], grid.z(idx[todo], obs.dtype), 0.0)
        grad = grad.clone()
        grad[todo] = g
        grad_rows += int(todo.numel())
    return ZSearchResult(idx, grid.z(idx, obs.dtype), feasible, vhat.system.velocity_grad(grad), hit, value_rows, grad_rows)


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


ROW_BLOCK = 16
"""Row granularity of :func:`padded_rows`: a multiple of the BLAS kernels' row blocks (4 measured)."""


def padded_rows(keep: torch.Tensor) -> torch.Tensor:
    """Sorted indices ``[M]`` of the rows ``keep [B]`` (bool), laid out so that each row's network
    value in a batch of these rows alone is bitwise its value in the batch of all ``B`` rows.

    A matrix product computes a row the same way wherever it sits in the batch, except the batch's
    last ``M mod r`` rows (``r``: the kernel's row block; the output layer ``[M, 256]·[256, 1]``
    sums those in another order, measured with MKL, ``r = 4``). So the last ``B mod``
    :data:`ROW_BLOCK` rows are always kept and stay last, and the first rows not kept are added
    until ``M ≡ B (mod ROW_BLOCK)``: then every kept row is in the remainder of both batches or of
    neither, for every ``r`` dividing :data:`ROW_BLOCK`."""
    B = keep.shape[0]
    keep = keep.clone()
    keep[B - B % ROW_BLOCK :] = True
    free = (~keep).nonzero(as_tuple=True)[0]
    keep[free[: free.numel() % ROW_BLOCK]] = True
    return keep.nonzero(as_tuple=True)[0]


class _Values:
    """``z ↦ V̂(0, o, z)`` of fixed observations for any V̂ with a ``value`` method (the generic
    form of :class:`~madpinn.value_functions.model.ObservationValues`)."""

    def __init__(self, vhat, obs: torch.Tensor):
        self.vhat, self.obs = vhat, obs

    def rows(self, idx: torch.Tensor) -> "_Values":
        return _Values(self.vhat, self.obs[idx])

    def z_input(self, z: torch.Tensor) -> torch.Tensor:
        return z

    def __call__(self, z: torch.Tensor, z_input: torch.Tensor | None = None) -> torch.Tensor:
        return self.vhat.value(self.obs, z, 0.0)


def observation_values(vhat, obs: torch.Tensor):
    """``z ↦ V̂(0, o, z)`` ``[B]`` for ``obs [B, D]``, with ``.rows(idx)``: :meth:`VHat.at_observations`
    (the terminal term's z-independent parts once) for a :class:`~madpinn.value_functions.model.VHat`,
    ``vhat.value`` for any other (a symmetrised V̂)."""
    return vhat.at_observations(obs, 0.0) if isinstance(vhat, VHat) else _Values(vhat, obs)


def velocity_grad(vhat, obs: torch.Tensor, z: torch.Tensor) -> torch.Tensor:
    """``∂V̂/∂v_a`` ``[B, n+1, d]`` at ``(0, o, z)`` for ``obs [B, D]``, ``z [B]``:
    :meth:`VHat.velocity_grad` (the network's gradient alone) for a
    :class:`~madpinn.value_functions.model.VHat`, the velocity block of ``value_and_grad`` for any
    other (a symmetrised or levelled V̂, whose ``velocity_grad`` attribute would be its base's)."""
    if isinstance(vhat, VHat):
        return vhat.velocity_grad(obs, z, 0.0)
    return vhat.system.velocity_grad(vhat.value_and_grad(obs, z, 0.0)[1])


def cold_search(vhat, obs: torch.Tensor, grid: ZGrid, with_grad: bool = True) -> ZSearchResult:
    """The paper's bisection (see module docstring); ``obs [B, D]``. ``V̂(z_max)`` on every row,
    then the ``steps`` halvings on the feasible rows only (:func:`padded_rows`): an infeasible
    row's answer is ``z_max`` whatever its halvings give. ``with_grad=False``: no gradient row
    (``grad`` is None; the budgets alone, as the verification and the heatmap need them)."""
    B = obs.shape[0]
    values = observation_values(vhat, obs)
    z_of = grid.z(torch.arange(grid.cells + 1, device=obs.device), obs.dtype)   # z of every grid index
    input_of = values.z_input(z_of)                                               # and its network input
    top = torch.full((B,), grid.cells, dtype=torch.long, device=obs.device)
    feasible = values(z_of[top], input_of[top]) <= 0
    rows = padded_rows(feasible)
    halve = values.rows(rows)
    lo = torch.zeros_like(rows)   # bracket (lo, lo + width], V̂(z_lo) > 0 or lo = 0
    width = grid.cells
    for _ in range(grid.steps):
        width //= 2
        mid = lo + width
        lo = torch.where(halve(z_of[mid], input_of[mid]) <= 0, lo, mid)
    idx = top.clone()
    idx[rows] = torch.where(feasible[rows], lo + 1, top[rows])
    value_rows = B + grid.steps * rows.numel()
    z = grid.z(idx, obs.dtype)
    grad = velocity_grad(vhat, obs, z) if with_grad else None
    return ZSearchResult(idx, z, feasible, grad, torch.zeros_like(feasible), value_rows, B if with_grad else 0)


def min_feasible_z(vhat, obs: torch.Tensor, z_tolerance: float):
    """``(z* [B], feasible [B] bool)`` of :func:`cold_search` on the grid of ``z_tolerance``
    (the deployed ``methods.madpinn.z_tolerance``); ``z* = z_max`` where ``V̂(0, o, z_max) > 0``."""
    r = cold_search(vhat, obs, ZGrid.of(vhat.z_max, z_tolerance), with_grad=False)
    return r.z, r.feasible
