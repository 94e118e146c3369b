import pytest
import torch

from madpinn.dynamics import DoubleIntegrator

DI = DoubleIntegrator(u_max=4.0, v_max=4.0)


def test_step_matches_closed_form_without_saturation():
    g = torch.Generator().manual_seed(0)
    s0 = torch.cat([torch.rand(64, 2, generator=g) * 2 - 1, torch.rand(64, 2, generator=g) - 0.5], -1).double()
    u = (torch.rand(64, 2, generator=g) * 8 - 4).double()
    t = 0.3
    s = DI.step(s0, u, t)
    p_exact = s0[:, :2] + s0[:, 2:] * t + 0.5 * u * t**2
    v_exact = s0[:, 2:] + u * t
    assert torch.allclose(s[:, :2], p_exact, atol=1e-12)
    assert torch.allclose(s[:, 2:], v_exact, atol=1e-12)


def test_many_small_steps_equal_one_exact_step_with_saturation():
    s0 = torch.tensor([[0.0, 0.0, 3.0, -3.5]], dtype=torch.float64)
    u = torch.tensor([[4.0, -4.0]], dtype=torch.float64)
    big = DI.step(s0, u, 1.0)
    s = s0
    for _ in range(400):
        s = DI.step(s, u, 0.0025)
    assert torch.allclose(big, s, atol=1e-10)
    # hand-derived: x-axis ramps 3->4 in 0.25 s (0.875 m) then cruises 0.75 s at 4 m/s (3.0 m)
    assert big[0, 0].item() == pytest.approx(0.875 + 3.0)
    # y-axis ramps -3.5->-4 in 0.125 s (-0.46875 m) then cruises 0.875 s (-3.5 m)
    assert big[0, 1].item() == pytest.approx(-0.46875 - 3.5)
    assert big[0, 2:].tolist() == [4.0, -4.0]


def test_control_is_clipped_and_shapes_checked():
    s0 = torch.zeros(1, 4)
    s = DI.step(s0, torch.tensor([[100.0, -100.0]]), 0.1)
    assert torch.allclose(s[0, 2:], torch.tensor([0.4, -0.4]))
    with pytest.raises(ValueError):
        DI.step(torch.zeros(3), torch.zeros(2), 0.1)


def test_batched_over_scenarios_and_agents():
    s0 = torch.zeros(5, 7, 4)
    u = torch.ones(5, 7, 2)
    s = DI.step(s0, u, 0.5)
    assert s.shape == (5, 7, 4)
    assert torch.allclose(s[..., 0], torch.full((5, 7), 0.125))


def test_hold_step_is_the_one_exact_step():
    """The unsaturated hold (pair, look-ahead, verification, oracle) is the closed form; with a
    bound no state reaches, the saturated branch (the agents' step) agrees to rounding."""
    from madpinn.dynamics.double_integrator import hold_step

    g = torch.Generator().manual_seed(1)
    p, v, a = (torch.rand(32, 2, generator=g, dtype=torch.float64) * 2 - 1 for _ in range(3))
    p1, v1 = hold_step(p, v, a, 0.1)
    assert torch.allclose(p1, p + v * 0.1 + 0.5 * a * 0.01, rtol=0, atol=1e-15)
    assert torch.allclose(v1, v + a * 0.1, rtol=0, atol=1e-15)
    p2, v2 = hold_step(p, v, a, 0.1, v_max=100.0)
    assert torch.allclose(p2, p1, rtol=0, atol=1e-14) and torch.allclose(v2, v1, rtol=0, atol=1e-15)
    # a tensor of hold times gives the positions along the step
    s = torch.tensor([0.05, 0.1], dtype=torch.float64)[:, None, None]
    traj, vels = hold_step(p[None], v[None], a[None], s)
    assert torch.equal(traj[-1], p1) and torch.equal(vels[-1], v1)


def test_per_agent_bounds_broadcast_over_agents():
    """u_max / v_max given per agent clip each agent to its own box."""
    di = DoubleIntegrator(u_max=(1.0, 4.0), v_max=(0.5, 4.0))
    s = di.step(torch.zeros(3, 2, 4), torch.full((3, 2, 2), 10.0), 1.0)
    assert torch.equal(s[:, 0, 2:], torch.full((3, 2), 0.5)) and torch.equal(s[:, 1, 2:], torch.full((3, 2), 4.0))
    # agent 0 ramps 0.5 s at 1 m/s² (0.125 m) then cruises 0.5 s at 0.5 m/s; agent 1 ramps the whole second
    assert torch.allclose(s[:, 0, :2], torch.full((3, 2), 0.375)) and torch.allclose(s[:, 1, :2], torch.full((3, 2), 2.0))
    assert torch.equal(di.clip_control(torch.full((2, 2), -9.0)), torch.tensor([[-1.0, -1.0], [-4.0, -4.0]]))
    assert torch.equal(di.clip_state(torch.full((2, 4), 3.0))[:, 2:], torch.tensor([[0.5, 0.5], [3.0, 3.0]]))


def test_box_hamiltonian_of_the_agent_model():
    """H = ⟨∂V/∂p, v⟩ − u_max·‖∂V/∂v‖₁ and u* = −u_max·sign(∂V/∂v), derived from the box."""
    g = torch.Generator().manual_seed(2)
    s, grad = (torch.randn(16, 4, generator=g, dtype=torch.float64) for _ in range(2))
    h = DI.hamiltonian(s, grad)
    assert torch.allclose(h, (grad[:, :2] * s[:, 2:]).sum(-1) - 4.0 * grad[:, 2:].abs().sum(-1))
    assert torch.equal(DI.optimal_control(grad), -4.0 * torch.sign(grad[:, 2:]))
    assert torch.allclose(DI.f(s, DI.optimal_control(grad)), DI.drift(s) + DI.optimal_control(grad) @ DI.control_matrix().double().T)
