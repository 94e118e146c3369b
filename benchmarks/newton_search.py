"""The Newton-stepped warm z* search (issue 37), a benchmark's variant of the deployed
:func:`madpinn.policies.z_search.warm_search`, and the plain cold budget search; moved out of the
package (issue 48: benchmark-only searches live with the benchmarks).

- :func:`newton_search`: the warm search with a Newton step — the first gradient row at ``k``
  also gives ``∂V̂/∂z``; the tangent's zero is probed (one value row below it, one gradient row at
  it, which is the control's gradient when it is the answer), then the known values bracket the
  crossing for the bisection. ≈ 3.5 instead of ≈ 4.1 rows per agent-step in closed loop with the
  shipped V̂ (``benchmarks/bench_zsearch.py --newton``). It may return another verified crossing
  where V̂ is not monotone in z, so the policy does not run it; :func:`newton_policy` swaps it in
  for one benchmark run.
- :func:`cold_budget_search`: ``(z*, feasible)`` of the cold bisection.

Import with ``benchmarks/`` on ``sys.path`` (the benchmarks run from there; the tests add it).
"""

from __future__ import annotations

from contextlib import contextmanager

import torch

from madpinn.value_functions.z_search import ZGrid, ZSearchResult, bisect, cold_search, grid_value, search_result


def cold_budget_search(vhat, obs: torch.Tensor, steps: int):
    """``(z* [B], feasible [B])`` by ``steps`` halvings of ``[0, z_max]`` (SPEC §6; :func:`cold_search`)."""
    r = cold_search(vhat, obs, ZGrid(vhat.z_max, steps))
    return r.z, r.feasible


@contextmanager
def newton_policy():
    """Within the block, :class:`madpinn.policies.madpinn.MadPinnPolicy`'s warm-started steps run
    :func:`newton_search` instead of the deployed :func:`~madpinn.policies.z_search.warm_search`."""
    import madpinn.policies.madpinn as policy

    deployed = policy.warm_search
    policy.warm_search = newton_search
    try:
        yield
    finally:
        policy.warm_search = deployed


SECANT_ROUNDS = 2  # newton_search: secant / regula-falsi rounds on a bracket before plain bisection


def newton_search(vhat, obs: torch.Tensor, grid: ZGrid, predicted: torch.Tensor) -> ZSearchResult:
    """Warm search with a Newton step on ``∂V̂/∂z`` (issue 37); ``obs [B, D]``, ``predicted [B]``.

    1. One gradient row at the predicted index ``k`` gives ``V̂(z_k)`` and ``∂V̂/∂z`` (the same
       fused pass). The tangent's zero ``k − V̂(z_k)/(h·∂V̂/∂z)`` rounded up is the guess ``c``
       (``c > k`` where ``V̂(z_k) > 0``, ``c ≤ k`` otherwise; ``c = k ± 1`` where the slope is not
       negative).
    2. One value call: ``V̂(z_max)`` (the cold search's feasibility test, as :func:`warm_search`)
       and the row below the guess, ``V̂(z_{c−1})`` (none where ``c − 1`` is ``k`` or 0).
    3. Where ``c ≠ k`` and ``V̂(z_{c−1}) > 0``: one gradient row at ``c``; ``V̂(z_c) ≤ 0`` is a
       verified crossing and its gradient is the control's (no further row).
    4. Otherwise the known values give a bracket ``(lo, hi]`` with ``V̂(z_lo) > 0`` (or ``lo = 0``)
       and ``V̂(z_hi) ≤ 0`` — the bisection's invariant. Up to :data:`SECANT_ROUNDS` rounds probe
       the cell at the regula-falsi point (the secant through two known values where ``V̂(z_lo)``
       is unknown, the midpoint where neither applies) and its lower neighbour, each keeping the
       invariant; :func:`~madpinn.value_functions.z_search.bisect` halves what is left to one cell; one gradient row at the answer.

    Every feasible answer is a verified crossing and the feasibility flag is the cold search's, as
    for :func:`warm_search`; where V̂ is monotone in z the crossing is unique, so all three searches
    return the same index. Where it is not, this search may return another crossing (counted by
    ``benchmarks/bench_zsearch.py --newton``).
    """
    B, cells = obs.shape[0], grid.cells
    dev = obs.device
    h = grid.z_max / cells
    k = predicted.to(device=dev, dtype=torch.long).clamp(1, cells)
    v_k, grad, dz = vhat.value_and_grad(obs, grid.z(k, obs.dtype), 0.0)
    value_rows, grad_rows = 0, B
    up = v_k > 0
    step = (v_k.double() / (dz.double() * h)).neg()  # tangent's zero, in cells from k
    good = torch.isfinite(step) & (dz < 0)
    guess = torch.ceil(k.double() + torch.where(good, step, torch.zeros_like(step)).clamp(-cells, cells)).long()
    c = torch.where(up, torch.maximum(guess, k + 1).clamp(max=cells), torch.minimum(guess, k).clamp(min=1))
    c = torch.where(good, c, torch.where(up, (k + 1).clamp(max=cells), k))
    c = torch.where(up & (k == cells), k, c)        # unsafe at the top: nothing above
    # stage 2: V̂(z_max) where k < cells, V̂(z_{c−1}) where c − 1 ∉ {0, k}
    top = (k < cells).nonzero(as_tuple=True)[0]
    below = ((c - 1 != k) & (c > 1) & ~(up & (k == cells))).nonzero(as_tuple=True)[0]
    ev_rows = torch.cat([top, below])
    ev_idx = torch.cat([torch.full_like(top, cells), c[below] - 1])
    vals = grid_value(vhat, obs[ev_rows], grid, ev_idx) if ev_rows.numel() else obs.new_zeros(0)
    ok = vals <= 0
    value_rows += int(ev_rows.numel())
    v_top = torch.full((B,), float("nan"), dtype=obs.dtype, device=dev)
    v_top[top] = vals[: top.numel()]
    v_below = torch.full((B,), float("nan"), dtype=obs.dtype, device=dev)
    v_below[below] = vals[top.numel():]
    top_ok = ~up & (k == cells)
    top_ok[top] = ok[: top.numel()]
    below_pos = torch.ones(B, dtype=torch.bool, device=dev)        # V̂(z_{c−1}) > 0 (c − 1 = 0: never evaluated)
    below_pos[below] = ~ok[top.numel():]
    below_pos = torch.where((c - 1 == k) & (c > 1), up, below_pos)  # c − 1 = k: V̂(z_k) measured
    feasible = top_ok
    idx = torch.full_like(k, cells)
    hit = torch.zeros(B, dtype=torch.bool, device=dev)
    at_k = feasible & (c == k) & ~up & below_pos                     # V̂(z_k) ≤ 0 < V̂(z_{k−1})
    hit |= at_k
    idx[at_k] = k[at_k]
    # stage 3: gradient row at c where the row below is verified positive (c = cells: the top's value)
    at_top = feasible & (c != k) & below_pos & (c == cells)
    probe = (feasible & (c != k) & below_pos & (c < cells)).nonzero(as_tuple=True)[0]
    v_c = torch.zeros(B, dtype=obs.dtype, device=dev)
    grad = grad.clone()
    if probe.numel():
        vc, gc, _ = vhat.value_and_grad(obs[probe], grid.z(c[probe], obs.dtype), 0.0)
        grad_rows += int(probe.numel())
        v_c[probe] = vc
        good_c = vc <= 0
        rows = probe[good_c]
        grad[rows] = gc[good_c]
        idx[rows] = c[rows]
        hit[rows] = True
    at_c_pos = torch.zeros(B, dtype=torch.bool, device=dev)
    at_c_pos[probe] = v_c[probe] > 0
    idx[at_top] = cells
    # stage 4: the rest of the feasible rows, bracketed by the values known so far
    rest = (feasible & ~hit).nonzero(as_tuple=True)[0]
    todo = torch.cat([(~feasible & (k < cells)).nonzero(as_tuple=True)[0], at_top.nonzero(as_tuple=True)[0]])
    if rest.numel():
        kr, cr, upr = k[rest], c[rest], up[rest]
        bp, cp = below_pos[rest], at_c_pos[rest]
        # up rows: lo = max known positive index (k, c − 1, c), hi = c − 1 if V̂(z_{c−1}) ≤ 0 else the top
        lo_up = torch.where(cp, cr, torch.where(bp & (cr > 1), cr - 1, kr))
        hi_up = torch.where(~bp, cr - 1, torch.full_like(kr, cells))
        # down rows: hi = c − 1 if V̂(z_{c−1}) ≤ 0 (then lo = 0), else k with lo = c − 1 or c
        lo_dn = torch.where(bp, torch.where(cp, cr, cr - 1), torch.zeros_like(kr))
        hi_dn = torch.where(bp, kr, cr - 1)
        lo = torch.where(upr, lo_up, lo_dn).clamp(min=0)
        hi = torch.where(upr, hi_up, hi_dn)
        lo = torch.minimum(lo, hi - 1)
        # the values at the bracket's ends (NaN: lo = 0, never evaluated) and, for the extrapolation
        # where V̂(z_lo) is unknown, a second point above hi (k)
        vk, vb, vc_, vt = v_k[rest], v_below[rest], v_c[rest], v_top[rest]
        vlo = torch.where(upr, torch.where(cp, vc_, torch.where(bp & (cr - 1 != kr) & (cr > 1), vb, vk)),
                          torch.where(bp & (lo > 0), torch.where(cp, vc_, vb), torch.full_like(vk, float("nan"))))
        vhi = torch.where(upr, torch.where(~bp, vb, vt), torch.where(bp, vk, vb))
        a, va = kr.clone(), vk.clone()
        o = obs[rest]
        for _ in range(SECANT_ROUNDS):
            act = (hi - lo > 1).nonzero(as_tuple=True)[0]
            if act.numel() == 0:
                break
            l, u, fl, fu, aa, fa = lo[act], hi[act], vlo[act].double(), vhi[act].double(), a[act], va[act].double()
            slope = (fa - fu) / (aa - u).clamp(min=1).double()
            guess = torch.where(torch.isfinite(fl) & (fl > fu), l + (u - l) * fl / (fl - fu),
                                torch.where((aa > u) & (slope < 0), u - fu / slope, (l + u) / 2.0))
            cc = torch.minimum(torch.maximum(torch.ceil(guess.nan_to_num(0.0)).long(), l + 1), u)
            p_lo = (cc - 1 > l).nonzero(as_tuple=True)[0]
            p_hi = (cc < u).nonzero(as_tuple=True)[0]
            pv = grid_value(vhat, o[torch.cat([act[p_lo], act[p_hi]])], grid, torch.cat([cc[p_lo] - 1, cc[p_hi]]))
            value_rows += int(pv.numel())
            v1 = torch.full_like(fu, float("nan")).to(obs.dtype)
            v1[p_lo] = pv[: p_lo.numel()]
            v2 = torch.full_like(v1, float("nan"))
            v2[p_hi] = pv[p_lo.numel():]
            lower = (cc - 1 > l) & (v1 <= 0)      # crossing below c − 1: hi = c − 1
            upper = ~lower & (cc < u) & (v2 > 0)  # crossing above c: lo = c
            cell = ~lower & ~upper                # V̂(z_{c−1}) > 0 (or c − 1 = lo) and V̂(z_c) ≤ 0 (or c = hi)
            a[act] = torch.where(lower, u, aa)
            va[act] = torch.where(lower, fu.to(obs.dtype), va[act])
            hi[act] = torch.where(lower, cc - 1, torch.where(cell, cc, u))
            vhi[act] = torch.where(lower, v1, torch.where(cell & (cc < u), v2, vhi[act]))
            lo[act] = torch.where(upper, cc, torch.where(cell, cc - 1, l))
            vlo[act] = torch.where(upper, v2, torch.where(cell & (cc - 1 > l), v1, vlo[act]))
        ans, r = bisect(vhat, o, grid, lo.clone(), hi.clone())
        value_rows += r
        idx[rest] = ans
        todo = torch.cat([todo, rest])
    return search_result(vhat, obs, grid, idx, feasible, hit & (idx == k), value_rows, grad_rows, grad=grad, todo=todo)
