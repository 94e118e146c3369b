"""Issue 48.5: the cold z search at its floor gives bitwise the answers of the search it replaced
(``benchmarks/zsearch_reference.py``: every halving on every row, the terminal term recomputed at
each). The package's search skips the halvings of rows infeasible at z_max and computes the
terminal term's z-independent parts once; its grid indices, budgets, feasibility flags and control
gradients, and whole closed-loop episodes with the shipped models, are compared with ``torch.equal``
/ ``np.array_equal``. Issue 65: the policy step's network paths on reused buffers (V̂'s halvings,
its control gradient without the terminal term, V_s's neighbour scores) are bitwise the allocating
ones, and a policy step gives the reference path's neighbours, z* and controls."""

import sys

import numpy as np
import pytest
import torch

from conftest import REPO
from madpinn.dynamics import DoubleIntegrator
from madpinn.observation import build_observation
from madpinn.policies.madpinn import MadPinnPolicy
from madpinn.policies.neighbours import make_selector, value_selector
from madpinn.simulation import run_episode
from madpinn.simulation.backend import DoubleIntegratorBackend
from madpinn.value_functions import load_vhat, load_vs
from madpinn.value_functions.symmetry import symmetrize
from madpinn.value_functions.z_search import ROW_BLOCK, ZGrid, bisection_steps, cold_search, padded_rows
from policy_models import tiny_models
from settings_helpers import madpinn_settings, observation_settings

sys.path.insert(0, str(REPO / "benchmarks"))
from zsearch_reference import reference_cold_search  # noqa: E402

SPEC = observation_settings()


def _rows_are_batch_independent() -> bool:
    """Whether this CPU's BLAS gives a row of a batch bitwise the same value in the padded subsets
    ``padded_rows`` lays out (the precondition of every bitwise check below): plain linear layers of
    the network's widths, batches of every size class modulo ROW_BLOCK."""
    g = torch.Generator().manual_seed(0)
    for width_out in (256, 1):
        w = torch.randn(width_out, 256, generator=g)
        for B in (7, 45, 90, 200, 333):
            x = torch.randn(B, 256, generator=g)
            full = torch.nn.functional.linear(x, w)
            for share in (0.2, 0.5, 0.8):
                rows = padded_rows(torch.rand(B, generator=g) < share)
                if not torch.equal(torch.nn.functional.linear(x[rows], w), full[rows]):
                    return False
    return True


bitwise = pytest.mark.skipif(
    not _rows_are_batch_independent(),
    reason="this CPU's BLAS sums a subset's rows in blocks that do not divide ROW_BLOCK: the bitwise checks do not "
           "apply here (test_search_agrees_with_the_reference_within_rounding runs on every CPU)")


def crowded_observations(B: int, seed: int) -> torch.Tensor:
    """Observations ``[B, D]`` of random 3-agent groups, a third of them with a neighbour almost on
    the ego (V̂ > 0 at z_max: infeasible), the rest spread over the small arena."""
    g = torch.Generator().manual_seed(seed)
    state = torch.cat([2 * torch.rand(B, 3, 2, generator=g) - 1, 8 * torch.rand(B, 3, 2, generator=g) - 4], -1)
    close = torch.rand(B, generator=g) < 1 / 3
    state[close, 1, 0:2] = state[close, 0, 0:2] + 0.01
    goals = 2 * torch.rand(B, 3, 2, generator=g) - 1
    nbrs = torch.tensor([[1, 2], [0, 2], [0, 1]]).expand(B, 3, 2)
    return build_observation(state, goals, nbrs, SPEC)[:, 0]


def assert_same_search(new, ref):
    for field in ("index", "z", "feasible", "velocity_grad", "hit"):
        assert torch.equal(getattr(new, field), getattr(ref, field)), field
    assert new.grad_rows == ref.grad_rows


@pytest.mark.parametrize("B", [1, 7, 16, 45, 200, 333])
@bitwise
def test_cold_search_is_bitwise_the_reference(B):
    """Batches of every size class modulo ROW_BLOCK, with and without infeasible rows: the same
    answers and gradients, bit for bit; the halvings run on the padded feasible rows only."""
    vhat, _ = tiny_models()
    grid = ZGrid(vhat.z_max, bisection_steps(1e-3))
    obs = crowded_observations(B, seed=B)
    new, ref = cold_search(vhat, obs, grid), reference_cold_search(vhat, obs, grid)
    assert_same_search(new, ref)
    assert new.value_rows == B + grid.steps * padded_rows(new.feasible).numel()
    assert ref.value_rows == B * (1 + grid.steps)
    if B >= 200:
        assert (~new.feasible).sum() >= B // 5 and new.value_rows < 0.85 * ref.value_rows
    budgets = cold_search(vhat, obs, grid, with_grad=False)
    assert budgets.velocity_grad is None and torch.equal(budgets.index, ref.index)


@bitwise
def test_symmetrised_vhat_takes_the_generic_path_with_the_same_answers():
    vhat, _ = tiny_models()
    sym = symmetrize(vhat, "point")
    grid = ZGrid(vhat.z_max, bisection_steps(1e-3))
    obs = crowded_observations(150, seed=3)
    assert_same_search(cold_search(sym, obs, grid), reference_cold_search(sym, obs, grid))


def test_padded_rows_keep_every_kept_row_and_the_tail_and_the_size_class():
    g = torch.Generator().manual_seed(0)
    for B in (1, 15, 16, 17, 100, 513):
        for share in (0.0, 0.3, 0.9, 1.0):
            keep = torch.rand(B, generator=g) < share
            rows = padded_rows(keep)
            assert torch.equal(rows, rows.sort().values) and rows.unique().numel() == rows.numel()
            assert set(keep.nonzero().flatten().tolist()) <= set(rows.tolist())
            tail = list(range(B - B % ROW_BLOCK, B))
            assert rows.tolist()[len(rows) - len(tail):] == tail
            assert (rows.numel() - B) % ROW_BLOCK == 0


@bitwise
def test_observation_values_are_vhat_values_bitwise():
    """V̂ of fixed observations at any budgets, on all rows or on subsets laid out by padded_rows
    (of every size modulo ROW_BLOCK), equals ``vhat.value`` on the whole batch; the buffered
    network forward equals ``forward``. The shipped V̂ (256 hidden units), whose output layer sums
    a batch's last rows in another order (without the padding this test fails with MKL)."""
    vhat = load_vhat(REPO / "models" / "vhat.pt")
    obs = crowded_observations(90, seed=5)
    g = torch.Generator().manual_seed(1)
    values = vhat.at_observations(obs)
    for trial in range(8):
        z = torch.rand(90, generator=g) * vhat.z_max
        full = vhat.value(obs, z, 0.0)
        assert torch.equal(values(z), full)
        keep = torch.zeros(90, dtype=torch.bool)
        keep[torch.randperm(90, generator=g)[: 40 + trial]] = True
        rows = padded_rows(keep)
        assert torch.equal(values.rows(rows)(z[rows]), full[rows])
    x = torch.rand(64, vhat.net.in_features, generator=g) * 2 - 1
    with torch.no_grad():
        assert torch.equal(vhat.net.forward_reusing_buffers(x), vhat.net(x))


def _episode(vhat, vs, search, starts, goals, steps):
    import madpinn.policies.madpinn as madpinn_policy

    spec = SPEC
    pol = MadPinnPolicy(vhat, make_selector("value", spec.n_neighbours, vs=vs), spec, madpinn_settings(strategy="value"), 0.0025)
    backend = DoubleIntegratorBackend(DoubleIntegrator(u_max=4.0, v_max=4.0), 0.0025)
    saved = madpinn_policy.cold_search
    madpinn_policy.cold_search = search
    try:
        with torch.no_grad():
            result, _ = run_episode(backend, pol, starts, goals, steps, spec.collision_radius, progress=False)
    finally:
        madpinn_policy.cold_search = saved
    return result, pol.stats


@bitwise
def test_closed_loop_episode_with_the_shipped_models_is_bitwise_the_reference():
    """A small real cell: 2 scenarios × 48 agents in a 1.5 m arena, 30 policy steps, shipped V̂
    and V_s: every per-scenario metric and the final states are identical; the new search
    evaluates fewer V̂ rows where agents are infeasible."""
    vhat, vs = load_vhat(REPO / "models" / "vhat.pt"), load_vs(REPO / "models" / "vs.pt")
    g = torch.Generator().manual_seed(7)
    S, N = 2, 48
    starts = 3 * torch.rand(S, N, 2, generator=g) - 1.5
    goals = 3 * torch.rand(S, N, 2, generator=g) - 1.5
    new, new_stats = _episode(vhat, vs, cold_search, starts, goals, 30)
    ref, ref_stats = _episode(vhat, vs, reference_cold_search, starts, goals, 30)
    for field in ("cost", "collided", "min_separation", "final_distance"):
        assert np.array_equal(getattr(new, field), getattr(ref, field)), field
    assert new_stats["infeasible"] == ref_stats["infeasible"] > 0
    assert new_stats["z_sum"] == ref_stats["z_sum"]
    assert new_stats["vhat_value_rows"] < ref_stats["vhat_value_rows"]


def test_search_agrees_with_the_reference_within_rounding():
    """On every CPU (bitwise or not): the skipped halvings and the once-per-step terminal parts
    give the reference search's budgets on all but rounding-tie rows, its feasibility flags, and
    V̂ values within float rounding of the whole-batch values."""
    vhat = load_vhat(REPO / "models" / "vhat.pt")
    grid = ZGrid(vhat.z_max, bisection_steps(1e-3))
    obs = crowded_observations(333, seed=11)
    new, ref = cold_search(vhat, obs, grid), reference_cold_search(vhat, obs, grid)
    assert (new.index == ref.index).float().mean() >= 0.99 and (new.index - ref.index).abs().max() <= 1
    assert (new.feasible == ref.feasible).float().mean() >= 0.99 and (~new.feasible).sum() > 0
    z = torch.rand(333, generator=torch.Generator().manual_seed(2)) * vhat.z_max
    rows = padded_rows(new.feasible)
    full = vhat.value(obs, z, 0.0)
    assert torch.allclose(vhat.at_observations(obs).rows(rows)(z[rows]), full[rows], rtol=1e-5, atol=1e-6)


def _bits(t: torch.Tensor) -> torch.Tensor:
    """float32 ``t`` as its int32 bit patterns (tells −0 from +0, unlike ``torch.equal``)."""
    return t.contiguous().view(torch.int32)


def test_buffered_network_paths_are_bitwise_the_allocating_ones():
    """The shipped networks on reused workspace buffers (batches growing and shrinking, so a
    buffer's leading rows serve smaller ones) give bitwise the allocating paths' values and input
    gradients, and a result is not overwritten by the next call."""
    vhat, vs = load_vhat(REPO / "models" / "vhat.pt"), load_vs(REPO / "models" / "vs.pt")
    banded = load_vs(REPO / "models" / "vs.pt", band=True)
    g = torch.Generator().manual_seed(4)
    with torch.no_grad():
        for B in (90, 333, 17, 512, 64):
            x = torch.rand(B, vhat.net.in_features, generator=g) * 2 - 1
            grad = vhat.net.input_grad_reusing_buffers(x)
            assert torch.equal(_bits(grad), _bits(vhat.net.value_and_input_grad(x)[1]))
            assert torch.equal(_bits(vhat.net.forward_reusing_buffers(x)), _bits(vhat.net(x)))
            pairs = (torch.rand(B, 4, generator=g) * 2 - 1) * torch.tensor([vs.system.p_range] * 2 + [vs.system.v_range] * 2)
            for v in (vs, banded):
                buffered = v.value(pairs, 0.0, reuse_buffers=True)
                assert torch.equal(_bits(buffered), _bits(v.value(pairs, 0.0)))
                (bv, bg), (av, ag) = v.value_and_grad(pairs, 0.0, reuse_buffers=True), v.value_and_grad(pairs, 0.0)
                assert torch.equal(_bits(bv), _bits(av)) and torch.equal(_bits(bg), _bits(ag))   # the CBVF filter's rows
                v.value_and_grad(pairs.flip(0), 0.0, reuse_buffers=True)
                assert torch.equal(_bits(bg), _bits(ag))   # not overwritten by the next call
            kept = grad.clone()
            vhat.net.input_grad_reusing_buffers(torch.rand(B, vhat.net.in_features, generator=g))
            assert torch.equal(grad, kept)


def test_velocity_grad_is_the_velocity_block_of_value_and_grad_bitwise():
    """``VHat.velocity_grad`` (the network's gradient alone) equals the velocity block of the full
    gradient bit for bit: the terminal term ``max(φ_d − z, g_d)`` has a +0 velocity gradient."""
    vhat = load_vhat(REPO / "models" / "vhat.pt")
    obs = crowded_observations(200, seed=8)
    z = torch.rand(200, generator=torch.Generator().manual_seed(9)) * vhat.z_max
    system = vhat.system
    _, go, _ = system.terminal_value_and_grad(obs, z)
    assert torch.equal(_bits(system.velocity_grad(go)), torch.zeros_like(_bits(system.velocity_grad(go))))
    full = system.velocity_grad(vhat.value_and_grad(obs, z, 0.0)[1])
    assert torch.equal(_bits(vhat.velocity_grad(obs, z, 0.0)), _bits(full))
    assert torch.equal(system.velocity_control(vhat.velocity_grad(obs, z, 0.0), obs),
                       system.optimal_control(vhat.value_and_grad(obs, z, 0.0)[1], obs))


class _Allocating:
    """A V_s whose every value call takes the allocating network path (the reference scoring)."""

    def __init__(self, vs):
        self.vs = vs

    def __getattr__(self, name):
        return getattr(self.vs, name)

    def value(self, x, t=0.0, reuse_buffers=False):
        return self.vs.value(x, t)


@bitwise
def test_policy_step_is_bitwise_the_reference_path():
    """One policy step on random crowded states (shipped V̂ and V_s, 2 scenarios × 64 agents in a
    2 m arena): the deployed path (bounded neighbour scores on reused buffers, the cold search at
    its floor, the control from the network's velocity gradient) gives the reference path's
    (exhaustive allocating scores, :func:`reference_cold_search`) neighbours, z*, feasibility and
    controls, bit for bit."""
    vhat, vs = load_vhat(REPO / "models" / "vhat.pt"), load_vs(REPO / "models" / "vs.pt")
    import madpinn.policies.madpinn as madpinn_policy

    n = SPEC.n_neighbours
    for seed in range(3):
        g = torch.Generator().manual_seed(seed)
        state = torch.cat([4 * torch.rand(2, 64, 2, generator=g) - 2, 4 * torch.rand(2, 64, 2, generator=g) - 2], -1)
        goals = 4 * torch.rand(2, 64, 2, generator=g) - 2
        steps = []
        for selector, search in ((make_selector("value", n, vs=vs), cold_search),
                                 (value_selector(_Allocating(vs), n, bounded=False), reference_cold_search)):
            pol = MadPinnPolicy(vhat, selector, SPEC, madpinn_settings(strategy="value"), 0.0025)
            pol.reset(state, goals)
            saved, madpinn_policy.cold_search = madpinn_policy.cold_search, search
            try:
                with torch.no_grad():
                    u = pol.act(state, goals, 0.0)
            finally:
                madpinn_policy.cold_search = saved
            steps.append((pol.neighbours, pol.last_search, u))
        (nb_new, r_new, u_new), (nb_ref, r_ref, u_ref) = steps
        assert torch.equal(nb_new, nb_ref) and (nb_new >= 0).float().mean() > 0.5
        assert torch.equal(r_new.z, r_ref.z) and torch.equal(r_new.feasible, r_ref.feasible)
        assert (~r_new.feasible).any() and r_new.feasible.any()
        assert torch.equal(_bits(u_new), _bits(u_ref))
