"""The d-dimensional CBVF QP (issue 63 item 2): in the plane it is the former closed form (kept here
as the reference, verbatim), in 3-D it agrees with SciPy's SLSQP on random problems."""

import numpy as np
import pytest
import torch
from scipy.optimize import minimize

from madpinn.policies.cbvf_qp import solve_box_qp

pytestmark = pytest.mark.usefixtures("one_thread")

U_MAX = 4.0


def closed_form_2d(u_nom, a, b, u_max, active=None, tol=1e-7):
    """The 2-D solver before issue 63 (commit de98c23, ``madpinn/policies/cbvf_qp.py``)."""
    u0, a, b = u_nom.to(torch.float64), a.to(torch.float64), b.to(torch.float64)
    if active is not None:
        a = torch.where(active.unsqueeze(-1), a, torch.zeros_like(a))
        b = torch.where(active, b, torch.full_like(b, -1e30))
    B = a.shape[0]
    eye = torch.eye(2, dtype=a.dtype)
    G = torch.cat([a, torch.cat([eye, -eye]).expand(B, 4, 2)], dim=1)
    h = torch.cat([b, torch.full((B, 4), -float(u_max), dtype=a.dtype)], dim=1)
    M = G.shape[1]
    norm2 = (G * G).sum(-1)
    line = norm2 > 1e-24
    proj = u0.unsqueeze(1) + ((h - (G * u0.unsqueeze(1)).sum(-1)) / norm2.clamp_min(1e-24)).unsqueeze(-1) * G
    i, j = torch.triu_indices(M, M, offset=1)
    Gi, Gj, hi, hj = G[:, i], G[:, j], h[:, i], h[:, j]
    det = Gi[..., 0] * Gj[..., 1] - Gi[..., 1] * Gj[..., 0]
    indep = det.abs() > 1e-12 * (norm2[:, i] * norm2[:, j]).sqrt()
    safe_det = torch.where(indep, det, torch.ones_like(det))
    vx = (hi * Gj[..., 1] - hj * Gi[..., 1]) / safe_det
    vy = (Gi[..., 0] * hj - Gj[..., 0] * hi) / safe_det
    cand = torch.cat([u0.unsqueeze(1), proj, torch.stack([vx, vy], dim=-1)], dim=1)
    cand_ok = torch.cat([torch.ones(B, 1, dtype=torch.bool), line, indep & line[:, i] & line[:, j]], dim=1)
    slack = (cand.unsqueeze(2) * G.unsqueeze(1)).sum(-1) - h.unsqueeze(1)
    scale = torch.where(line, norm2.sqrt(), torch.ones_like(norm2)).unsqueeze(1)
    feas = cand_ok & (slack >= -tol * scale).all(-1)
    dist = ((cand - u0.unsqueeze(1)) ** 2).sum(-1).masked_fill(~feas, float("inf"))
    feasible = feas.any(dim=1)
    u = cand[torch.arange(B), dist.argmin(dim=1)]
    return torch.where(feasible.unsqueeze(-1), u, u0).clamp(-u_max, u_max), feasible


def _problems(B: int, K: int, d: int, seed: int):
    gen = torch.Generator().manual_seed(seed)
    u_nom = (torch.rand(B, d, generator=gen, dtype=torch.float64) * 2 - 1) * 6.0   # may lie outside the box
    a = torch.randn(B, K, d, generator=gen, dtype=torch.float64)
    b = torch.randn(B, K, generator=gen, dtype=torch.float64) * 4.0
    active = torch.rand(B, K, generator=gen) > 0.2
    return u_nom, a, b, active


@pytest.mark.parametrize("K", [1, 2, 3])
def test_planar_case_is_the_former_closed_form(K):
    u_nom, a, b, active = _problems(2000, K, 2, seed=K)
    u, feasible = solve_box_qp(u_nom, a, b, U_MAX, active)
    u_ref, feasible_ref = closed_form_2d(u_nom, a, b, U_MAX, active)
    assert torch.equal(feasible, feasible_ref)
    assert torch.equal(u, u_ref)   # by construction: the same candidates in the same order, the same float operations


def _slsqp(u0, a, b, active):
    rows = [(a_k, b_k) for a_k, b_k, on in zip(a, b, active) if on]
    cons = [{"type": "ineq", "fun": (lambda u, a_k=a_k, b_k=b_k: a_k @ u - b_k), "jac": (lambda u, a_k=a_k: a_k)}
            for a_k, b_k in rows]
    res = minimize(lambda u: ((u - u0) ** 2).sum(), np.clip(u0, -U_MAX, U_MAX), jac=lambda u: 2 * (u - u0),
                   bounds=[(-U_MAX, U_MAX)] * len(u0), constraints=cons, method="SLSQP",
                   options={"ftol": 1e-14, "maxiter": 500})
    ok = all(a_k @ res.x - b_k >= -1e-6 for a_k, b_k in rows) and res.success
    return res.x, ok


@pytest.mark.parametrize("K", [1, 2])
def test_3d_matches_scipy(K):
    u_nom, a, b, active = _problems(300, K, 3, seed=10 + K)
    u, feasible = solve_box_qp(u_nom, a, b, U_MAX, active)
    assert u.shape == (300, 3) and (u.abs() <= U_MAX + 1e-12).all()
    agree = 0
    for i in range(300):
        ref, ok = _slsqp(u_nom[i].numpy(), a[i].numpy(), b[i].numpy(), active[i].numpy())
        if not ok:   # SciPy found no feasible point: ours must not claim one of its rows far off
            continue
        assert bool(feasible[i]), f"problem {i}: SciPy found a feasible point, the enumeration none"
        # both feasible: the enumeration's optimum is never farther from u_nom than SciPy's, and at the same point
        d_ours = float(((u[i] - u_nom[i]) ** 2).sum())
        d_ref = float(((torch.from_numpy(ref) - u_nom[i]) ** 2).sum())
        assert d_ours <= d_ref + 1e-6
        assert np.allclose(u[i].numpy(), ref, atol=1e-4)
        agree += 1
    assert agree >= 150   # most random problems are feasible


def test_3d_feasible_answers_satisfy_every_row_and_infeasible_ones_keep_the_nominal():
    u_nom, a, b, active = _problems(500, 2, 3, seed=3)
    u, feasible = solve_box_qp(u_nom, a, b, U_MAX, active)
    slack = (a * u[:, None, :]).sum(-1) - b
    assert (slack[feasible & active.any(-1)].masked_fill(~active[feasible & active.any(-1)], 0.0) >= -1e-6).all()
    assert torch.equal(u[~feasible], u_nom[~feasible].clamp(-U_MAX, U_MAX))
    with pytest.raises(ValueError, match="expected u_nom"):
        solve_box_qp(u_nom, a[..., :2], b, U_MAX)
