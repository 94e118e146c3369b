"""Warm-started z* searches of the deployed MAD-PINN policy, on the grid of the one z* search.

The grid, its feasibility rule and the cold bisection live in :mod:`madpinn.value_functions.z_search`
(``verify-vhat`` and the heatmap run that cold search; the policy runs it on its first step and
whenever the warm start has no previous answer). The variants here evaluate V̂ at the same grid
points and give the same feasibility flag:

- :func:`warm_search`: a bracketed search around a predicted index ``k`` (the policy passes the
  linear extrapolation of its last two answers). One gradient row at ``z_k``, then, in one value
  call, ``V̂(z_max)`` (the cold search's feasibility test; skipped when ``k`` is the top) and, if
  ``V̂(z_k) ≤ 0``, ``V̂(z_{k−1})``. ``V̂(z_max) > 0``: ``(z_max, infeasible)`` and one gradient row
  at ``z_max`` — the cold search's fallback, decided by the same evaluation. ``V̂(z_k) ≤ 0 <
  V̂(z_{k−1})`` (or ``k = 1``): a hit, z* = z_k, 3 rows (1 when the prediction is the top and it
  is still unsafe). Otherwise the row expands geometrically from the probe (offsets 1, 2, 4, …, up
  while ``V̂ > 0``, down while ``V̂ ≤ 0``) until the crossing is bracketed, bisects the bracket to
  one cell and takes one gradient row at the answer.

Equality with the cold search: the feasibility flag always (both evaluate the same ``V̂(z_max)``).
Every feasible answer ``i`` of either search is a verified crossing, ``V̂(z_i) ≤ 0`` and
``V̂(z_{i−1}) > 0`` (``i = 1``: ``z_0 = 0`` is never evaluated, as in the cold search). If V̂ is
non-increasing in z on the grid (the exact V̂ is) the crossing is unique, so both return the
same index, hence the same z* and the same control. Where a learned V̂ is not monotone in z the
warm search returns the crossing nearest its prediction, which may differ from the bisection's;
it is still a budget V̂ itself certifies. ``benchmarks/bench_zsearch.py --verify`` counts such
differences in closed-loop episodes. ``check_top=False`` drops the ``V̂(z_max)`` row (one row
less per step); then a row whose V̂ is positive at ``z_max`` but dips below 0 lower down returns
that feasible crossing where the cold search falls back to ``z_max`` (not used by the policy).
"""

from __future__ import annotations

import torch

from madpinn.value_functions.z_search import ZGrid, ZSearchResult, bisect, grid_value, search_result


def warm_search(vhat, obs: torch.Tensor, grid: ZGrid, predicted: torch.Tensor, check_top: bool = True) -> ZSearchResult:
    """Bracketed search around ``predicted [B]`` (long grid indices; see module docstring).
    ``check_top``: also evaluate ``V̂(z_max)`` on every row predicted below ``z_max`` (one value
    row), so the feasibility flag and the ``z_max`` fallback are always the cold search's."""
    B, cells = obs.shape[0], grid.cells
    k = predicted.to(device=obs.device, dtype=torch.long).clamp(1, cells)
    v_k, grad, _ = vhat.value_and_grad(obs, grid.z(k, obs.dtype), 0.0)
    value_rows, grad_rows = 0, B
    ok_k = v_k <= 0
    below = torch.zeros(B, dtype=torch.bool, device=obs.device)  # V̂(z_{k−1}) ≤ 0: the crossing is lower
    top_ok = ok_k & (k == cells)                                    # V̂(z_max) ≤ 0 measured
    chk = (ok_k & (k > 1)).nonzero(as_tuple=True)[0]
    top = (k < cells).nonzero(as_tuple=True)[0] if check_top else chk[:0]
    if chk.numel() or top.numel():  # one network call: V̂(z_{k−1}) where V̂(z_k) ≤ 0, V̂(z_max) where k < cells
        rows = torch.cat([chk, top])
        ok = grid_value(vhat, obs[rows], grid, torch.cat([k[chk] - 1, torch.full_like(top, cells)])) <= 0
        below[chk] = ok[: chk.numel()]
        top_ok[top] = ok[chk.numel():]
        value_rows += int(rows.numel())
    if check_top:  # V̂(z_max) > 0: the cold search's answer, whatever V̂ does below z_max
        top_unsafe = ~top_ok
    else:
        top_unsafe = ~ok_k & (k == cells)
    hit = ok_k & ~below & ~top_unsafe
    idx, feasible = k.clone(), ~top_unsafe
    idx[top_unsafe] = cells
    miss = (~hit & ~top_unsafe).nonzero(as_tuple=True)[0]
    if miss.numel() == 0:
        todo = (top_unsafe & (k < cells)).nonzero(as_tuple=True)[0]
        return search_result(vhat, obs, grid, idx, feasible, hit, value_rows, grad_rows, grad=grad, todo=todo)
    o = obs[miss]
    up = ~ok_k[miss]
    # bracket (lo, hi]: up rows know V̂(z_k) > 0, down rows know V̂(z_{k−1}) ≤ 0
    lo = torch.where(up, k[miss], torch.full_like(k[miss], -1))          # -1: not found yet
    hi = torch.where(up, torch.full_like(k[miss], cells + 1), k[miss] - 1)  # cells+1: not found yet
    if check_top:  # V̂(z_max) ≤ 0 is known for these rows: the top closes the bracket
        top_known = up & top_ok[miss]
    step = torch.ones_like(lo)
    unsafe = torch.zeros_like(up)
    while True:
        up_open = (hi == cells + 1) & ~unsafe
        down_open = lo == -1
        down_open &= hi > 1
        lo = torch.where((lo == -1) & (hi <= 1), torch.zeros_like(lo), lo)  # hi = 1: the cold search's first cell
        act = (up_open | down_open).nonzero(as_tuple=True)[0]
        if act.numel() == 0:
            break
        u = up_open[act]
        probe = torch.where(u, (lo[act] + step[act]).clamp(max=cells), (hi[act] - step[act]).clamp(min=0))
        at_zero = probe == 0  # below the first cell: V̂(0) is never evaluated, treat as > 0
        known_top = (probe == cells) & top_known[act] if check_top else torch.zeros_like(u)
        ev = (~at_zero & ~known_top).nonzero(as_tuple=True)[0]
        ok = known_top.clone()
        if ev.numel():
            ok[ev] = grid_value(vhat, o[act[ev]], grid, probe[ev]) <= 0
            value_rows += int(ev.numel())
        # up rows: ok -> hi = probe (bracketed); else lo = probe, unsafe at the top
        # down rows: ok -> hi = probe (keep going down); else lo = probe (bracketed)
        new_hi = torch.where(ok, probe, hi[act])
        new_lo = torch.where(ok, lo[act], probe)
        unsafe[act] = u & ~ok & (probe == cells)
        hi[act], lo[act] = new_hi, new_lo
        step[act] = step[act] * 2
    bracketed = ~unsafe
    rows = bracketed.nonzero(as_tuple=True)[0]
    if rows.numel():
        h_ans, r = bisect(vhat, o[rows], grid, lo[rows].clone(), hi[rows].clone())
        value_rows += r
        idx[miss[rows]] = h_ans
    idx[miss[unsafe]] = cells
    feasible[miss[unsafe]] = False
    todo = torch.cat([miss, (top_unsafe & (k < cells)).nonzero(as_tuple=True)[0]])
    return search_result(vhat, obs, grid, idx, feasible, hit, value_rows, grad_rows, grad=grad, todo=todo)


def predict_index(last: torch.Tensor, before: torch.Tensor | None, cells: int) -> torch.Tensor:
    """Next step's predicted grid index: linear extrapolation ``2·last − before`` (``last`` alone
    on the second step), clamped to ``[1, cells]``."""
    pred = last if before is None else 2 * last - before
    return pred.clamp(1, cells)
