"""Issue 48.5: the cold z search at its floor gives bitwise the answers of the search it replaced
(``benchmarks/zsearch_reference.py``: every halving on every row, the terminal term recomputed at
each). The package's search skips the halvings of rows infeasible at z_max and computes the
terminal term's z-independent parts once; its grid indices, budgets, feasibility flags and control
gradients, and whole closed-loop episodes with the shipped models, are compared with ``torch.equal``
/ ``np.array_equal``."""

import sys

import numpy as np
import pytest
import torch

from conftest import REPO
from madpinn.dynamics import DoubleIntegrator
from madpinn.observation import build_observation
from madpinn.policies.madpinn import MadPinnPolicy
from madpinn.policies.neighbours import make_selector
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
    for field in ("index", "z", "feasible", "grad", "hit"):
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
    assert budgets.grad is None and torch.equal(budgets.index, ref.index)


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
