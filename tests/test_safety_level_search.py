"""Issue 62: the z* search at a level δ (the one search run on V̂ + δ, safety_level.LeveledVHat).
δ = 0 gives bitwise today's answers (the search it replaced in issue 48,
benchmarks/zsearch_reference.py); δ > 0 gives the least grid budget with V̂ ≤ −δ, infeasible where
V̂(z_max) > −δ; a per-bin level is each row's own search; the warm search agrees."""

import sys

import pytest
import torch

from conftest import REPO
from madpinn.observation import join_observation, split_observation
from madpinn.policies.z_search import warm_search
from madpinn.value_functions.safety_level import LeveledVHat, SafetyLevel, at_level, closing_speed, speed_bin
from madpinn.value_functions.z_search import ZGrid, bisection_steps, cold_search, grid_value
from policy_models import tiny_models
from test_zsearch_exact import assert_same_search, bitwise, crowded_observations

sys.path.insert(0, str(REPO / "benchmarks"))
from zsearch_reference import reference_cold_search  # noqa: E402

GAP = 1e-5
"""rows whose V̂ lies within this of −δ at a checked grid point are not judged (rounding)"""
EDGES = (1.0, 3.0)
"""closing-speed bins of the per-bin tests (m/s)"""


def _grid(vhat):
    return ZGrid(vhat.z_max, bisection_steps(1e-3))


def _one(delta: float, n: int) -> SafetyLevel:
    return SafetyLevel((), (float(delta),), n)


@pytest.mark.parametrize("B", [7, 45, 200])
@bitwise
def test_level_zero_is_bitwise_the_reference(B):
    """δ = 0: ``at_level`` returns V̂ itself, and even the wrapper forced at δ = 0 (single and
    per-bin) gives indices, budgets, flags and gradients bit for bit those of the search before
    issue 62."""
    vhat, _ = tiny_models()
    n = vhat.system.spec.n_neighbours
    grid, obs = _grid(vhat), crowded_observations(B, seed=B)
    ref = reference_cold_search(vhat, obs, grid)
    assert at_level(vhat, _one(0.0, n)) is vhat and at_level(vhat, None) is vhat
    for level in (_one(0.0, n), SafetyLevel(EDGES, (0.0, 0.0, 0.0), n)):
        assert_same_search(cold_search(LeveledVHat(vhat, level), obs, grid), ref)


def test_level_zero_warm_search_is_the_plain_one():
    vhat, _ = tiny_models()
    grid, obs = _grid(vhat), crowded_observations(90, seed=3)
    pred = cold_search(vhat, obs, grid).index + 3
    forced = LeveledVHat(vhat, _one(0.0, vhat.system.spec.n_neighbours))
    assert_same_search(warm_search(forced, obs, grid, pred), warm_search(vhat, obs, grid, pred))


def _check_crossings(vhat, obs, grid, r, lv):
    """Infeasible exactly where V̂(z_max) > −δ; a feasible answer i is a crossing of −δ:
    V̂(z_i) ≤ −δ < V̂(z_{i−1}) (i = 1: no lower point); rows within GAP of −δ are skipped.
    ``lv``: δ per row ``[B]``."""
    top = grid_value(vhat, obs, grid, torch.full_like(r.index, grid.cells)) + lv
    clear = top.abs() > GAP
    assert torch.equal(r.feasible[clear], (top <= 0)[clear])
    f = r.feasible.nonzero(as_tuple=True)[0]
    at = grid_value(vhat, obs[f], grid, r.index[f]) + lv[f]
    below = grid_value(vhat, obs[f], grid, (r.index[f] - 1).clamp_min(1)) + lv[f]
    ok_at = (at <= 0) | (at.abs() <= GAP)
    ok_below = (r.index[f] == 1) | (below > 0) | (below.abs() <= GAP)
    assert bool(ok_at.all()) and bool(ok_below.all())


@pytest.mark.parametrize("delta", [0.05, 0.2])
def test_positive_level_is_the_crossing_of_minus_delta(delta):
    """A positive level: a subset of δ = 0's feasible rows, each budget a crossing of −δ; the
    control gradient is V̂'s own at that budget."""
    vhat, _ = tiny_models()
    n = vhat.system.spec.n_neighbours
    grid, obs = _grid(vhat), crowded_observations(300, seed=11)
    r0, r = cold_search(vhat, obs, grid), cold_search(at_level(vhat, _one(delta, n)), obs, grid)
    _check_crossings(vhat, obs, grid, r, torch.full((300,), delta))
    assert bool((r.feasible <= r0.feasible).all())          # accepted at δ ⇒ accepted at 0
    assert int(r.feasible.sum()) < int(r0.feasible.sum())   # the tiny V̂ has rows with V̂(z_max) in (−δ, 0]
    _, g, _ = vhat.value_and_grad(obs, r.z, 0.0)
    assert torch.equal(vhat.system.velocity_grad(g), r.velocity_grad)


def test_per_bin_level_is_each_rows_own_search():
    """A per-bin level gives each row the answer of a search at its own bin's δ (flags, indices);
    an uncertified bin (δ = +∞) accepts nothing."""
    vhat, _ = tiny_models()
    n = vhat.system.spec.n_neighbours
    grid, obs = _grid(vhat), crowded_observations(240, seed=5)
    deltas = (0.0, 0.05, 0.2)
    bins = speed_bin(closing_speed(obs, n), EDGES)
    assert len(set(bins.tolist())) == 3
    lv = torch.tensor(deltas)[bins]
    r = cold_search(LeveledVHat(vhat, SafetyLevel(EDGES, deltas, n)), obs, grid)
    _check_crossings(vhat, obs, grid, r, lv)
    for b, d in enumerate(deltas):
        rows = (bins == b).nonzero(as_tuple=True)[0]
        alone = cold_search(LeveledVHat(vhat, _one(d, n)), obs[rows], grid)
        assert torch.equal(alone.feasible, r.feasible[rows])
    inf = cold_search(LeveledVHat(vhat, SafetyLevel(EDGES, (0.0, float("inf"), 0.0), n)), obs, grid)
    assert not bool(inf.feasible[bins == 1].any()) and bool((inf.index[bins == 1] == grid.cells).all())


def test_warm_search_at_a_level_keeps_the_cold_feasibility():
    vhat, _ = tiny_models()
    n = vhat.system.spec.n_neighbours
    grid, obs = _grid(vhat), crowded_observations(150, seed=9)
    leveled = LeveledVHat(vhat, SafetyLevel(EDGES, (0.0, 0.1, 0.1), n))
    cold = cold_search(leveled, obs, grid)
    warm = warm_search(leveled, obs, grid, cold.index + 5)
    assert torch.equal(warm.feasible, cold.feasible)
    _check_crossings(vhat, obs, grid, warm, torch.tensor([0.0, 0.1, 0.1])[speed_bin(closing_speed(obs, n), EDGES)])


def test_bad_levels_fail_early():
    with pytest.raises(ValueError, match="one per bin"):
        SafetyLevel((1.0, 2.0), (0.1, 0.2), 2)
    with pytest.raises(ValueError, match="ascend"):
        SafetyLevel((2.0, 1.0), (0.1, 0.2, 0.3), 2)
    with pytest.raises(ValueError, match="δ ≥ 0"):
        SafetyLevel((), (-0.1,), 2)


def test_closing_speed_and_bins():
    """Two agents approaching head-on at 3 m/s each close at 6 m/s; a separating pair is negative;
    the bins of edges (2, 4): [<2, 2–4, ≥4] with the edge in the upper bin."""
    vhat, _ = tiny_models()
    n = vhat.system.spec.n_neighbours
    obs = crowded_observations(4, seed=0).clone()
    # ego at origin moving +x at 3; neighbour 1 at +1 m moving −x at 3; neighbour 2 at 1.9 m, at rest
    pos, vel, goal = split_observation(obs, n)
    pos[:, 1] = torch.tensor([1.0, 0.0]); vel[:, 1] = torch.tensor([-3.0, 0.0])
    pos[:, 2] = torch.tensor([0.0, 1.9]); vel[:, 2] = torch.tensor([0.0, 0.0])
    vel[:, 0] = torch.tensor([3.0, 0.0])
    speed = closing_speed(join_observation(pos, vel, goal), n)
    assert torch.allclose(speed, torch.full((4,), 6.0))
    vel[:, 0] = torch.tensor([-3.0, 0.0]); vel[:, 1] = torch.tensor([3.0, 0.0]); vel[:, 2] = torch.tensor([0.0, 1.0])
    assert bool((closing_speed(join_observation(pos, vel, goal), n) < 0).all())
    assert speed_bin(torch.tensor([0.0, 1.99, 2.0, 3.0, 4.0, 9.0]), (2.0, 4.0)).tolist() == [0, 0, 1, 1, 2, 2]
    lvl = SafetyLevel((2.0, 4.0), (0.0, 0.1, float("inf")), n)
    assert lvl.of(join_observation(pos, vel, goal)).tolist() == [0.0] * 4
    assert SafetyLevel((), (0.0,), n).is_zero and SafetyLevel((), (0.0,), n).of(obs) == 0.0
