"""The policy's cold z bisection as it was before issue 48 (main at daa844f), kept as the reference
that the package's :func:`madpinn.value_functions.z_search.cold_search` must reproduce bitwise.

Every halving evaluates ``V̂.value`` on every row, infeasible ones included, and the terminal
term ``max(φ_d − z, g_d)`` is recomputed from the observation at each one. The package's search
skips the halvings of rows infeasible at ``z_max`` and computes the z-independent parts once;
``tests/test_zsearch_exact.py`` and ``bench_policy_cell.py`` (its ``old`` variant runs this one)
check that the answers, the control gradients and the episodes are bitwise the same.
"""

from __future__ import annotations

import torch

from madpinn.value_functions.z_search import ZGrid, ZSearchResult, grid_value, search_result


def reference_cold_search(vhat, obs: torch.Tensor, grid: ZGrid, with_grad: bool = True) -> ZSearchResult:
    """``V̂(z_max)``, then ``grid.steps`` halvings of ``[0, z_max]`` on all ``B`` rows (1 + steps
    value rows and one gradient row per row); ``z* = z_max``, ``feasible = False`` where V̂(z_max) > 0."""
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
