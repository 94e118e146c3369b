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
