"""Exactness of the fused SIREN derivatives against autograd double backward, and the exact
terminal condition of both parameterisations."""

import pytest
import torch

from madpinn.dynamics.epigraph import EpigraphSystem
from madpinn.dynamics.pair import PairSystem
from madpinn.observation import ObservationSpec
from madpinn.value_functions.model import PairValue, VHat, build_network
from madpinn.value_functions.problems import EpigraphProblem, PairProblem, assemble
from madpinn.value_functions.train import TrainSettings, make_head, training_batch

NET = {"hidden": 48, "layers": 3, "first_omega": 30.0, "hidden_omega": 30.0}


def problems():
    spec = ObservationSpec()
    return [EpigraphProblem(EpigraphSystem(spec, z_max=21.45)), PairProblem(PairSystem())]


@pytest.mark.parametrize("problem", problems(), ids=["vhat", "vs"])
@pytest.mark.parametrize("loss", ["l1", "l2"])
def test_fused_parameter_gradient_equals_autograd_double_backward(problem, loss):
    torch.manual_seed(0)
    st = TrainSettings(iterations=100, batch_size=300, lr=1e-4, lr_final=1e-4, curriculum_fraction=0.5,
                       checkpoint_every=50, loss=loss, output_scale=2.0, network=NET)
    net = build_network(problem, NET).double()
    # a first call on another batch: the reused workspace must not leak into the next call
    s0, t0 = training_batch(problem, st, 69, "cpu", torch.float64)
    b0, gb0 = problem.boundary_and_grad(s0)
    net.accumulate_loss_grad(problem.normalise(s0, t0), make_head(problem, s0, t0, b0, gb0, 2.0, loss))
    net.zero_grad(set_to_none=True)
    s, t = training_batch(problem, st, 70, "cpu", torch.float64)
    b, gb = problem.boundary_and_grad(s)
    x = problem.normalise(s, t)
    loss_fast, n_fast, g_fast = net.accumulate_loss_grad(x, make_head(problem, s, t, b, gb, 2.0, loss))
    fast = [p.grad.clone() for p in net.parameters()]
    net.zero_grad(set_to_none=True)
    xx = x.clone().requires_grad_(True)
    n = net(xx)
    g = torch.autograd.grad(n.sum(), xx, create_graph=True)[0]
    v, dvdt, dvds = assemble(problem, s, t, n, g, b, gb, 2.0)
    r = problem.residual(s, t, v, dvdt, dvds)
    ref = r.abs().mean() if loss == "l1" else r.square().mean()
    ref.backward()
    assert torch.allclose(n_fast, n, atol=1e-12) and torch.allclose(g_fast, g, atol=1e-10)
    assert abs(float(loss_fast) - float(ref.detach())) < 1e-12
    for p, f in zip(net.parameters(), fast):
        assert torch.allclose(f, p.grad, rtol=1e-9, atol=1e-12 * float(p.grad.abs().max()) + 1e-300)


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
