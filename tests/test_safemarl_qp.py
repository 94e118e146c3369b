"""The exact 2-D CBVF QP solver against a brute-force grid over the control box."""

import pytest
import torch

from madpinn.policies.cbvf_qp import solve_box_qp


pytestmark = pytest.mark.usefixtures("one_thread")


U_MAX = 4.0


def _grid(n: int = 201) -> torch.Tensor:
    g = torch.linspace(-U_MAX, U_MAX, n, dtype=torch.float64)
    return torch.cartesian_prod(g, g)  # [n², 2]


def _random_problems(B: int, K: int, seed: int):
    gen = torch.Generator().manual_seed(seed)
    u_nom = (torch.rand(B, 2, generator=gen, dtype=torch.float64) * 2 - 1) * 6.0  # may lie outside the box
    a = torch.randn(B, K, 2, generator=gen, dtype=torch.float64)
    b = torch.randn(B, K, generator=gen, dtype=torch.float64) * 4.0
    active = torch.rand(B, K, generator=gen) > 0.2
    return u_nom, a, b, active


def test_matches_brute_force_grid():
    B, K = 200, 3
    u_nom, a, b, active = _random_problems(B, K, seed=0)
    u, feasible = solve_box_qp(u_nom, a, b, U_MAX, active)
    grid = _grid()
    step = 2 * U_MAX / 200
    # grid points that satisfy every active row (with a half-cell margin both ways)
    lhs = torch.einsum("gc,bkc->bgk", grid, a) - b.unsqueeze(1)  # [B, G, K]
    lhs = torch.where(active.unsqueeze(1), lhs, torch.ones_like(lhs))
    margin = step * a.norm(dim=-1).unsqueeze(1)
    strictly = (lhs >= margin).all(-1)  # surely feasible grid points
    loosely = (lhs >= -margin).all(-1)  # feasible up to grid resolution
    d_grid = ((grid.unsqueeze(0) - u_nom.unsqueeze(1)) ** 2).sum(-1)
    best_grid = d_grid.masked_fill(~strictly, float("inf")).amin(1)
    d_sol = ((u - u_nom) ** 2).sum(-1)
    assert (u.abs() <= U_MAX + 1e-9).all()
    n_checked = 0
    for k in range(B):
        if strictly[k].any():
            n_checked += 1
            assert feasible[k], f"problem {k}: grid has feasible points but the solver reports infeasible"
            # optimal: no surely-feasible grid point is closer to u_nom
            assert d_sol[k] <= best_grid[k] + 1e-9, (k, d_sol[k].item(), best_grid[k].item())
        if not loosely[k].any():
            assert not feasible[k], f"problem {k}: no feasible grid point but the solver reports feasible"
        if feasible[k]:
            row = (a[k] @ u[k] - b[k])[active[k]]
            assert (row >= -1e-6).all(), f"problem {k}: returned control violates a constraint {row}"
    assert n_checked > B // 3  # the random set exercises many feasible problems


def test_nominal_kept_when_inside_and_no_rows_active():
    u_nom = torch.tensor([[1.0, -2.0], [5.0, 0.5]], dtype=torch.float64)
    a = torch.zeros(2, 2, 2, dtype=torch.float64)
    b = torch.zeros(2, 2, dtype=torch.float64)
    u, feasible = solve_box_qp(u_nom, a, b, U_MAX, active=torch.zeros(2, 2, dtype=torch.bool))
    assert feasible.all()
    assert torch.equal(u[0], u_nom[0])
    assert torch.allclose(u[1], torch.tensor([4.0, 0.5], dtype=torch.float64))  # box projection


def test_single_halfplane_projection_and_infeasible():
    u_nom = torch.tensor([[0.0, 0.0], [0.0, 0.0]], dtype=torch.float64)
    a = torch.tensor([[[1.0, 1.0]], [[1.0, 0.0]]], dtype=torch.float64)
    b = torch.tensor([[2.0], [5.0]], dtype=torch.float64)  # second: u_x ≥ 5 is outside the box
    u, feasible = solve_box_qp(u_nom, a, b, U_MAX)
    assert feasible.tolist() == [True, False]
    assert torch.allclose(u[0], torch.tensor([1.0, 1.0], dtype=torch.float64))
    assert torch.equal(u[1], u_nom[1])


def test_vertex_solution_and_dtype():
    # u_x ≥ 3 and u_y ≥ 3 from u_nom at the origin: the vertex (3, 3)
    u_nom = torch.zeros(1, 2)
    a = torch.tensor([[[1.0, 0.0], [0.0, 1.0]]])
    b = torch.tensor([[3.0, 3.0]])
    u, feasible = solve_box_qp(u_nom, a, b, U_MAX)
    assert feasible.item() and u.dtype == torch.float32
    assert torch.allclose(u, torch.tensor([[3.0, 3.0]]))
