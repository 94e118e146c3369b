"""Exactness of the fused SIREN derivatives against autograd double backward, and the exact
terminal condition of both parameterisations."""

import pytest
import torch

from madpinn.value_functions.epigraph import EpigraphSystem
from madpinn.dynamics.pair import PairSystem
from madpinn.value_functions.model import PairValue, VHat, build_network
from madpinn.value_functions.problems import EpigraphProblem, PairProblem, assemble
from madpinn.value_functions.train import TrainSettings, make_head, training_batch
from settings_helpers import epigraph_system, observation_settings, pair_system

NET = {"hidden": 48, "layers": 3, "first_omega": 30.0, "hidden_omega": 30.0}


def problems():
    spec = observation_settings()
    return [EpigraphProblem(epigraph_system(spec=spec, z_max=21.45)), PairProblem(pair_system())]


@pytest.mark.parametrize("problem", problems(), ids=["vhat", "vs"])
@pytest.mark.parametrize("loss", ["l1", "l2"])
@pytest.mark.parametrize("obstacle", [0.0, 0.7], ids=["paper", "obstacle"])
def test_fused_parameter_gradient_equals_autograd_double_backward(problem, loss, obstacle):
    torch.manual_seed(0)
    st = TrainSettings(iterations=100, batch_size=300, lr=1e-4, lr_final=1e-4, curriculum_fraction=0.5,
                       checkpoint_every=50, loss=loss, output_scale=2.0, network=NET, seed=0,
                       init_from=None, obstacle_weight=0.0, stop_at=None)
    net = build_network(problem, NET).double()
    # a first call on another batch: the reused workspace must not leak into the next call
    s0, t0 = training_batch(problem, st, 69, "cpu", torch.float64)
    b0, gb0 = problem.boundary_and_grad(s0)
    net.accumulate_loss_grad(problem.normalise(s0, t0), make_head(problem, s0, t0, b0, gb0, 2.0, loss, obstacle))
    net.zero_grad(set_to_none=True)
    s, t = training_batch(problem, st, 70, "cpu", torch.float64)
    b, gb = problem.boundary_and_grad(s)
    x = problem.normalise(s, t)
    loss_fast, n_fast, g_fast = net.accumulate_loss_grad(x, make_head(problem, s, t, b, gb, 2.0, loss, obstacle))
    fast = [p.grad.clone() for p in net.parameters()]
    net.zero_grad(set_to_none=True)
    xx = x.clone().requires_grad_(True)
    n = net(xx)
    g = torch.autograd.grad(n.sum(), xx, create_graph=True)[0]
    v, dvdt, dvds = assemble(problem, s, t, n, g, b, gb, 2.0)
    r = problem.residual(s, t, v, dvdt, dvds)
    norm = torch.abs if loss == "l1" else torch.square
    ref = norm(r).mean() + obstacle * norm(problem.obstacle_violation(s, v)).mean()
    ref.backward()
    assert torch.allclose(n_fast, n, atol=1e-12) and torch.allclose(g_fast, g, atol=1e-10)
    assert abs(float(loss_fast) - float(ref.detach())) < 1e-12
    for p, f in zip(net.parameters(), fast):
        assert torch.allclose(f, p.grad, rtol=1e-9, atol=1e-12 * float(p.grad.abs().max()) + 1e-300)


def test_obstacle_penalty_pulls_v_s_down_to_psi_inside_the_disk():
    """Where V_s > ψ and the VI's min picks the other branch, the paper's loss passes no gradient
    to ψ − V; the obstacle penalty does, and always towards V ≤ ψ (it is 0 where V ≤ ψ)."""
    problem = PairProblem(pair_system())
    s = torch.tensor([[0.05, 0.0, 3.0, 0.0], [1.0, 1.0, 0.0, 0.0]], dtype=torch.float64)  # inside / far
    t = torch.tensor([0.5, 0.5], dtype=torch.float64)
    b, gb = problem.boundary_and_grad(s)
    n = torch.tensor([0.2, -0.3], dtype=torch.float64)   # V = ψ + 0.5·n: above ψ inside, below it far
    # ∂V/∂t = −n + τ·∂n/∂t: a steep fall (large ∂n/∂t) makes ∂_t V + H the smaller branch inside
    grad_n = torch.tensor([[0.0, 0.0, 0.0, 0.0, -40.0], [0.0] * 5], dtype=torch.float64)
    v, dvdt, dvds = assemble(problem, s, t, n, grad_n, b, gb, 1.0)
    r = problem.residual(s, t, v, dvdt, dvds)
    assert float(v[0] - b[0]) > 0.05 and float(r[0]) < float(b[0] - v[0]) - 1.0   # min picks ∂_t V + H
    viol = problem.obstacle_violation(s, v)
    assert float(viol[0]) == pytest.approx(float(v[0] - b[0])) and float(viol[1]) == 0.0
    _, n_bar0, _ = make_head(problem, s, t, b, gb, 1.0, "l1", 0.0)(n, grad_n)
    _, n_bar1, _ = make_head(problem, s, t, b, gb, 1.0, "l1", 1.0)(n, grad_n)
    # the penalty adds +τ/B to ∂loss/∂n of the violating state (descent lowers V) and nothing elsewhere
    assert float(n_bar1[0] - n_bar0[0]) == pytest.approx(0.5 / 2) and float(n_bar1[1] - n_bar0[1]) == 0.0


@pytest.mark.parametrize("problem", problems(), ids=["vhat", "vs"])
def test_value_and_grad_match_autograd_and_terminal_condition_is_exact(problem):
    torch.manual_seed(1)
    net = build_network(problem, NET)
    with torch.no_grad():  # random, large weights: the terminal condition must not depend on them
        for p in net.parameters():
            p.mul_(5.0)
    model = (VHat if problem.kind == "vhat" else PairValue)(problem, net, 3.0)
    s = problem.sample_states(500, torch.Generator().manual_seed(3), torch.float32)
    T = problem.horizon
    boundary, _ = problem.boundary_and_grad(s)
    assert torch.equal(model.state_value(s, T), boundary)
    v, dvdt, dvds = model.state_value_and_grads(s, torch.full((500,), T))
    assert torch.equal(v, boundary)
    # gradient at t < T against autograd through the plain forward
    s64 = s.double()
    model.net.double()
    t = torch.rand(500, dtype=torch.float64) * T
    with torch.no_grad():  # policies call under no_grad
        v, dvdt, dvds = model.state_value_and_grads(s64, t)
    ss = s64.clone().requires_grad_(True)
    tt = t.clone().requires_grad_(True)
    with torch.enable_grad():
        b = model._boundary(ss)
        ref = b + (T - tt) * 3.0 * model.net(problem.normalise(ss, tt))
        gs, gt = torch.autograd.grad(ref.sum(), [ss, tt])
    assert torch.allclose(v, ref.detach(), atol=1e-10)
    assert torch.allclose(dvds, gs, atol=1e-8) and torch.allclose(dvdt, gt, atol=1e-8)
