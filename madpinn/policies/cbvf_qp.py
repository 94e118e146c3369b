"""Exact batched solver of the 2-D safety-filter QP (closed-form active set).

    min_u ‖u − u_nom‖²   s.t.   a_k·u ≥ b_k  (k = 1…K, active rows only),   |u_x|, |u_y| ≤ u_max.

A strictly convex QP in the plane attains its optimum either at ``u_nom`` (nothing active), at
the projection of ``u_nom`` onto one constraint line (one active constraint), or at the
intersection of two constraint lines (a vertex). The solver enumerates these
``1 + M + M(M−1)/2`` candidates (M = K + 4 with the box edges), keeps the feasible ones and
returns the closest to ``u_nom`` — the exact optimum, for every problem of the batch at once.
When no candidate is feasible the QP is infeasible (the box alone is always feasible, so only
the CBVF rows can cause this); ``feasible`` is then False and ``u`` is ``u_nom`` clipped.
Computed in float64; tolerance ``tol`` is a distance to the constraint lines (m/s²).
"""

from __future__ import annotations

import torch

_INACTIVE = -1e30


def _constraint_set(a: torch.Tensor, b: torch.Tensor, u_max: float) -> tuple[torch.Tensor, torch.Tensor]:
    """Append the 4 box rows: ``G [B, K+4, 2]``, ``h [B, K+4]`` with ``G·u ≥ h``."""
    B = a.shape[0]
    eye = torch.eye(2, dtype=a.dtype, device=a.device)
    box_g = torch.cat([eye, -eye]).expand(B, 4, 2)
    box_h = torch.full((B, 4), -float(u_max), dtype=a.dtype, device=a.device)
    return torch.cat([a, box_g], dim=1), torch.cat([b, box_h], dim=1)


def solve_box_qp(
    u_nom: torch.Tensor,
    a: torch.Tensor,
    b: torch.Tensor,
    u_max: float,
    active: torch.Tensor | None = None,
    tol: float = 1e-7,
) -> tuple[torch.Tensor, torch.Tensor]:
    """u_nom ``[B, 2]``, rows a ``[B, K, 2]``, b ``[B, K]``, optional active mask ``[B, K]`` ->
    ``(u [B, 2], feasible [B] bool)``. Inactive rows are ignored."""
    if u_nom.dim() != 2 or u_nom.shape[-1] != 2 or a.shape[:1] != u_nom.shape[:1] or a.shape[-1] != 2 or b.shape != a.shape[:-1]:
        raise ValueError(f"expected u_nom [B,2], a [B,K,2], b [B,K]; got {tuple(u_nom.shape)}, {tuple(a.shape)}, {tuple(b.shape)}")
    out_dtype = u_nom.dtype
    u0 = u_nom.to(torch.float64)
    a = a.to(torch.float64)
    b = b.to(torch.float64)
    if active is not None:
        a = torch.where(active.unsqueeze(-1), a, torch.zeros_like(a))
        b = torch.where(active, b, torch.full_like(b, _INACTIVE))
    G, h = _constraint_set(a, b, u_max)  # [B, M, 2], [B, M]
    B, M, _ = G.shape
    norm2 = (G * G).sum(-1)  # [B, M]
    line = norm2 > 1e-24  # rows that define a line

    # candidates: u_nom, projections onto each line, intersections of each pair of lines
    proj = u0.unsqueeze(1) + ((h - (G * u0.unsqueeze(1)).sum(-1)) / norm2.clamp_min(1e-24)).unsqueeze(-1) * G
    i, j = torch.triu_indices(M, M, offset=1, device=G.device)
    Gi, Gj, hi, hj = G[:, i], G[:, j], h[:, i], h[:, j]
    det = Gi[..., 0] * Gj[..., 1] - Gi[..., 1] * Gj[..., 0]
    indep = det.abs() > 1e-12 * (norm2[:, i] * norm2[:, j]).sqrt()
    safe_det = torch.where(indep, det, torch.ones_like(det))
    vx = (hi * Gj[..., 1] - hj * Gi[..., 1]) / safe_det
    vy = (Gi[..., 0] * hj - Gj[..., 0] * hi) / safe_det
    vert = torch.stack([vx, vy], dim=-1)
    cand = torch.cat([u0.unsqueeze(1), proj, vert], dim=1)  # [B, C, 2]
    cand_ok = torch.cat([torch.ones(B, 1, dtype=torch.bool, device=G.device), line, indep & line[:, i] & line[:, j]], dim=1)

    # feasibility of every candidate against every row (distance-scaled slack)
    slack = (cand.unsqueeze(2) * G.unsqueeze(1)).sum(-1) - h.unsqueeze(1)  # [B, C, M]
    scale = torch.where(line, norm2.sqrt(), torch.ones_like(norm2)).unsqueeze(1)
    feas = cand_ok & (slack >= -tol * scale).all(-1)
    dist = ((cand - u0.unsqueeze(1)) ** 2).sum(-1).masked_fill(~feas, float("inf"))
    best = dist.argmin(dim=1)
    feasible = feas.any(dim=1)
    u = torch.gather(cand, 1, best.view(B, 1, 1).expand(B, 1, 2)).squeeze(1)
    u = torch.where(feasible.unsqueeze(-1), u, u0)
    return u.clamp(-u_max, u_max).to(out_dtype), feasible
