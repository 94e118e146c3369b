"""Relative pair system of V_s: Hamiltonian (sup over cooperative controls) vs brute force."""

import torch

from madpinn.dynamics.pair import PairSystem
from madpinn.dynamics import DoubleIntegrator
from settings_helpers import pair_system


def test_hamiltonian_and_control_match_brute_force():
    sy = pair_system()
    g = torch.Generator().manual_seed(0)
    x = sy.sample(128, g, dtype=torch.float64)
    grad = torch.randn(128, 4, generator=g, dtype=torch.float64)
    axis = torch.linspace(-sy.u_rel_max, sy.u_rel_max, 33, dtype=torch.float64)
    u = torch.cartesian_prod(axis, axis)  # [K, 2]
    f = sy.f(x[:, None, :].expand(-1, u.shape[0], -1), u[None].expand(128, -1, -1))
    brute = (grad[:, None, :] * f).sum(-1).max(1).values
    assert torch.allclose(sy.hamiltonian(x, grad), brute, atol=1e-9)
    ustar = sy.optimal_control(grad)
    assert torch.allclose((grad * sy.f(x, ustar)).sum(-1), brute, atol=1e-9)
    assert sy.u_rel_max == 8.0


def test_relative_system_is_difference_of_two_agents():
    sy, di = pair_system(), DoubleIntegrator(u_max=4.0, v_max=100.0)
    g = torch.Generator().manual_seed(1)
    si = torch.randn(64, 4, generator=g, dtype=torch.float64)
    sj = torch.randn(64, 4, generator=g, dtype=torch.float64)
    ui = 8 * torch.rand(64, 2, generator=g, dtype=torch.float64) - 4
    uj = 8 * torch.rand(64, 2, generator=g, dtype=torch.float64) - 4
    dt = 0.01
    rel = sy.step(si - sj, ui - uj, dt)
    assert torch.allclose(rel, di.step(si, ui, dt) - di.step(sj, uj, dt), atol=1e-12)


def test_target_and_domain():
    sy = pair_system()
    x = torch.tensor([[0.3, 0.4, 1.0, 2.0], [0.0, 0.05, 0.0, 0.0]], dtype=torch.float64)
    psi, grad = sy.target_and_grad(x)
    assert torch.allclose(psi, torch.tensor([0.4, -0.05], dtype=torch.float64))
    assert torch.allclose(grad[0], torch.tensor([0.6, 0.8, 0.0, 0.0], dtype=torch.float64))
    s = sy.sample(4096, torch.Generator().manual_seed(2))
    assert (s[:, :2].abs() <= 2.0).all() and (s[:, 2:].abs() <= 8.0).all()
    v = torch.zeros(2, dtype=torch.float64)
    r = sy.hjb_residual(x, v, torch.zeros(2, dtype=torch.float64), torch.zeros(2, 4, dtype=torch.float64))
    assert torch.allclose(r, torch.minimum(torch.zeros(2, dtype=torch.float64), psi))
