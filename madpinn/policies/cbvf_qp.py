"""Exact batched solver of the safety-filter QP in d dimensions (active-set enumeration).

    min_u ‖u − u_nom‖²   s.t.   a_k·u ≥ b_k  (k = 1…K, active rows only),   |u_c| ≤ u_max  (c = 1…d).

The optimum of a strictly convex QP is the projection of ``u_nom`` onto the affine hull of its
active constraints, and those can be chosen linearly independent, so at most d of them. The
solver enumerates every such candidate — ``u_nom`` itself, its projection onto each constraint
plane, onto the intersection of each 2, …, d−1 planes, and the vertex of each d planes — over
the M = K + 2d rows (the box's 2d faces included), keeps the feasible ones and returns the
closest to ``u_nom``: the exact optimum, for every problem of the batch at once. In the plane
(d = 2) the candidates are ``1 + M + M(M−1)/2`` (the former closed form, in the same order and
the same float operations). Projections onto k planes solve ``(G Gᵀ) λ = h − G u_nom`` and
vertices ``G u = h`` by Cramer's rule (cofactor determinants; d is small). When no candidate is
feasible the QP is infeasible (the box alone is always feasible, so only the CBVF rows can cause
this); ``feasible`` is then False and ``u`` is ``u_nom`` clipped. Computed in float64;
tolerance ``tol`` is a distance to the constraint planes (m/s²).
"""

from __future__ import annotations

import itertools

import torch

_INACTIVE = -1e30


def _constraint_set(a: torch.Tensor, b: torch.Tensor, u_max: float) -> tuple[torch.Tensor, torch.Tensor]:
    """Append the 2d box rows: ``G [B, K+2d, d]``, ``h [B, K+2d]`` with ``G·u ≥ h``."""
    B, _, d = a.shape
    eye = torch.eye(d, dtype=a.dtype, device=a.device)
    box_g = torch.cat([eye, -eye]).expand(B, 2 * d, d)
    box_h = torch.full((B, 2 * d), -float(u_max), dtype=a.dtype, device=a.device)
    return torch.cat([a, box_g], dim=1), torch.cat([b, box_h], dim=1)


def _det(rows: list[list[torch.Tensor]]) -> torch.Tensor:
    """Determinant of a small matrix given as ``rows[r][c]`` (batched tensors), by cofactor
    expansion along the first row (2 × 2: ``m00·m11 − m01·m10``)."""
    if len(rows) == 1:
        return rows[0][0]
    total = None
    for c in range(len(rows)):
        term = rows[0][c] * _det([row[:c] + row[c + 1:] for row in rows[1:]])
        total = term if total is None else (total - term if c % 2 else total + term)
    return total


def _cramer(m: torch.Tensor, rhs: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """``det(m)`` ``[...]`` and the Cramer numerators ``[..., k]`` of ``m x = rhs`` (``m [..., k, k]``)."""
    k = m.shape[-1]
    rows = [[m[..., r, c] for c in range(k)] for r in range(k)]
    det = _det(rows)
    nums = [_det([[rhs[..., r] if c == j else rows[r][c] for c in range(k)] for r in range(k)]) for j in range(k)]
    return det, torch.stack(nums, dim=-1)


def _subset_candidates(u0: torch.Tensor, G: torch.Tensor, h: torch.Tensor, norm2: torch.Tensor, line: torch.Tensor,
                       k: int) -> tuple[torch.Tensor, torch.Tensor]:
    """Candidates ``[B, C, d]`` of every k-subset of rows (``itertools.combinations`` order) and
    whether each is defined ``[B, C]`` (rows independent, none of them zero). k = d: the vertex
    ``G_S u = h_S``; 1 < k < d: the projection of ``u0`` onto ``{G_S u = h_S}``."""
    B, M, d = G.shape
    idx = torch.tensor(list(itertools.combinations(range(M), k)), dtype=torch.long, device=G.device)   # [C, k]
    Gs, hs = G[:, idx], h[:, idx]                                 # [B, C, k, d], [B, C, k]
    scale = norm2[:, idx[:, 0]]
    for r in range(1, k):
        scale = scale * norm2[:, idx[:, r]]
    rows_ok = line[:, idx].all(-1)
    if k == d:
        det, nums = _cramer(Gs, hs)
        indep = det.abs() > 1e-12 * scale.sqrt()
        safe = torch.where(indep, det, torch.ones_like(det))
        return nums / safe.unsqueeze(-1), indep & rows_ok
    gram = Gs @ Gs.transpose(-1, -2)                              # [B, C, k, k]
    rhs = hs - (Gs * u0[:, None, None, :]).sum(-1)
    det, nums = _cramer(gram, rhs)
    indep = det > 1e-24 * scale
    lam = nums / torch.where(indep, det, torch.ones_like(det)).unsqueeze(-1)
    return u0[:, None, :] + (lam.unsqueeze(-1) * Gs).sum(-2), indep & rows_ok


def solve_box_qp(
    u_nom: torch.Tensor,
    a: torch.Tensor,
    b: torch.Tensor,
    u_max: float,
    active: torch.Tensor | None = None,
    tol: float = 1e-7,
) -> tuple[torch.Tensor, torch.Tensor]:
    """u_nom ``[B, d]``, rows a ``[B, K, d]``, b ``[B, K]``, optional active mask ``[B, K]`` ->
    ``(u [B, d], feasible [B] bool)``. Inactive rows are ignored."""
    if u_nom.dim() != 2 or a.dim() != 3 or a.shape[:1] != u_nom.shape[:1] or a.shape[-1] != u_nom.shape[-1] or b.shape != a.shape[:-1]:
        raise ValueError(f"expected u_nom [B,d], a [B,K,d], b [B,K]; got {tuple(u_nom.shape)}, {tuple(a.shape)}, {tuple(b.shape)}")
    if active is not None and active.shape != b.shape:
        raise ValueError(f"active must be [B,K] like b, got {tuple(active.shape)}")
    out_dtype = u_nom.dtype
    d = u_nom.shape[-1]
    u0 = u_nom.to(torch.float64)
    a = a.to(torch.float64)
    b = b.to(torch.float64)
    if active is not None:
        a = torch.where(active.unsqueeze(-1), a, torch.zeros_like(a))
        b = torch.where(active, b, torch.full_like(b, _INACTIVE))
    G, h = _constraint_set(a, b, u_max)  # [B, M, d], [B, M]
    B, M, _ = G.shape
    norm2 = (G * G).sum(-1)  # [B, M]
    line = norm2 > 1e-24  # rows that define a plane

    # candidates: u_nom, projections onto each plane, onto intersections of 2 … d−1 planes, vertices of d planes
    proj = u0.unsqueeze(1) + ((h - (G * u0.unsqueeze(1)).sum(-1)) / norm2.clamp_min(1e-24)).unsqueeze(-1) * G
    cands, oks = [u0.unsqueeze(1), proj], [torch.ones(B, 1, dtype=torch.bool, device=G.device), line]
    for k in range(2, min(d, M) + 1):
        c, ok = _subset_candidates(u0, G, h, norm2, line, k)
        cands.append(c)
        oks.append(ok)
    cand = torch.cat(cands, dim=1)  # [B, C, d]
    cand_ok = torch.cat(oks, dim=1)

    # feasibility of every candidate against every row (distance-scaled slack)
    slack = (cand.unsqueeze(2) * G.unsqueeze(1)).sum(-1) - h.unsqueeze(1)  # [B, C, M]
    scale = torch.where(line, norm2.sqrt(), torch.ones_like(norm2)).unsqueeze(1)
    feas = cand_ok & (slack >= -tol * scale).all(-1)
    dist = ((cand - u0.unsqueeze(1)) ** 2).sum(-1).masked_fill(~feas, float("inf"))
    best = dist.argmin(dim=1)
    feasible = feas.any(dim=1)
    u = torch.gather(cand, 1, best.view(B, 1, 1).expand(B, 1, d)).squeeze(1)
    u = torch.where(feasible.unsqueeze(-1), u, u0)
    return u.clamp(-u_max, u_max).to(out_dtype), feasible
