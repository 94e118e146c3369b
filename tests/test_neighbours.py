"""Neighbour strategies: value (with pruning), nearest, random, phantom padding."""

import pytest
import torch

from madpinn.dynamics import DoubleIntegrator
from madpinn.observation import PHANTOM, pairwise_distances
from madpinn.policies.neighbours import (
    DriftMargins,
    _lexicographic_topk,
    calibrate_drift_margins,
    free_drift_lower_bound,
    in_domain,
    make_selector,
    pair_scores,
    pair_scores_bounded,
    pair_scores_brute_force,
    relative_states,
    select_lowest,
)
from madpinn.dynamics.pair import free_drift_and_grad
from madpinn.value_functions import load_vs
from pathlib import Path

from policy_models import tiny_models

SHIPPED_VS = Path(__file__).resolve().parents[1] / "models" / "vs.pt"


def random_states(S, N, half_width, v_max=4.0, seed=0, dtype=torch.float64):
    g = torch.Generator().manual_seed(seed)
    p = (2 * torch.rand(S, N, 2, generator=g, dtype=dtype) - 1) * half_width
    v = (2 * torch.rand(S, N, 2, generator=g, dtype=dtype) - 1) * v_max
    return torch.cat([p, v], dim=-1)


def test_select_lowest_and_padding():
    inf = float("inf")
    scores = torch.tensor([[[inf, 3.0, 1.0, 2.0], [0.5, inf, inf, inf], [inf, inf, inf, inf], [1.0, 1.5, 0.2, inf]]])
    idx = select_lowest(scores, 2)
    assert idx.tolist() == [[[2, 3], [0, PHANTOM], [PHANTOM, PHANTOM], [2, 0]]]
    # more neighbours requested than agents exist: padded with phantoms
    assert select_lowest(torch.full((1, 1, 1), inf), 2).tolist() == [[[PHANTOM, PHANTOM]]]


def test_nearest_strategy_and_padding():
    state = torch.zeros(1, 4, 4)
    state[0, :, 0] = torch.tensor([0.0, 0.3, -0.1, 5.0])
    idx = make_selector("nearest", 2, agent=DoubleIntegrator)(state)
    assert idx[0].tolist() == [[2, 1], [0, 2], [0, 1], [1, 0]]  # unlimited range: the far agent still gets 2
    single = make_selector("nearest", 2, agent=DoubleIntegrator)(torch.zeros(3, 1, 4))
    assert (single == PHANTOM).all() and single.shape == (3, 1, 2)


def test_random_strategy_within_radius_seeded_and_uniform():
    state = torch.zeros(1, 6, 4)
    state[0, :, 0] = torch.tensor([0.0, 0.5, -0.9, 0.1, 1.2, 3.0])  # agent 0 senses 1, 2, 3 (radius 1)
    sel = make_selector("random", 2, radius=1.0, generator=torch.Generator().manual_seed(3), agent=DoubleIntegrator)
    seen = set()
    for _ in range(60):
        idx = sel(state)[0]
        assert set(idx[0].tolist()) <= {1, 2, 3} and idx[0, 0] != idx[0, 1]
        seen.update(idx[0].tolist())
        assert idx[5].tolist() == [PHANTOM, PHANTOM]  # nobody within 1 m of agent 5
        assert idx[4].tolist() == [1, PHANTOM]  # only agent 1 (0.7 m) within range of agent 4
    assert seen == {1, 2, 3}
    a = make_selector("random", 2, radius=1.0, generator=torch.Generator().manual_seed(7), agent=DoubleIntegrator)
    b = make_selector("random", 2, radius=1.0, generator=torch.Generator().manual_seed(7), agent=DoubleIntegrator)
    many = random_states(4, 12, 1.0, dtype=torch.float32)
    assert all(torch.equal(a(many), b(many)) for _ in range(3))


def test_value_strategy_matches_per_pair_reference():
    _, vs = tiny_models(torch.float64)
    state = random_states(2, 7, 1.0, seed=1)
    idx = make_selector("value", 2, vs=vs)(state)
    for s in range(2):
        for i in range(7):
            vals = {j: float(vs.value((state[s, i] - state[s, j])[None], 0.0)) for j in range(7) if j != i}
            expected = sorted(vals, key=vals.get)[:2]
            assert idx[s, i].tolist() == expected


def test_value_strategy_out_of_domain_pairs_are_phantoms():
    _, vs = tiny_models(torch.float64)
    state = torch.zeros(1, 3, 4, dtype=torch.float64)
    state[0, :, 0] = torch.tensor([0.0, 1.5, 3.4])  # 0-1 and 1-2 within 2 m per axis, 0-2 not
    idx = make_selector("value", 2, vs=vs)(state)[0]
    assert idx[0].tolist() == [1, PHANTOM] and idx[2].tolist() == [1, PHANTOM] and sorted(idx[1].tolist()) == [0, 2]


@pytest.mark.parametrize(
    "S,N,half_width,v_max",
    [(3, 16, 1.0, 4.0),    # dense small arena: every pair in the V_s domain
     (2, 64, 4.0, 4.0),    # large arena
     (1, 96, 8.0, 4.0),    # sparse: most pairs out of range, some agents alone
     (2, 24, 1.5, 6.0)],   # velocity differences beyond the V_s domain (|dv| > 8)
)
def test_pruned_selection_identical_to_brute_force(S, N, half_width, v_max):
    _, vs = tiny_models(torch.float64)
    state = random_states(S, N, half_width, v_max, seed=N)
    pruned, brute = pair_scores(state, vs, chunk=500), pair_scores_brute_force(state, vs)
    mask = in_domain(state, vs.system.p_range, vs.system.v_range, DoubleIntegrator)
    assert torch.equal(torch.isinf(pruned), ~mask) and torch.equal(torch.isinf(brute), ~mask)
    assert torch.allclose(pruned[mask], brute[mask], rtol=0, atol=1e-12)
    sel_p = make_selector("value", 2, vs=vs)(state)
    sel_b = select_lowest(brute, 2)
    assert torch.equal(sel_p, sel_b)
    if half_width >= 4.0:
        assert mask.sum() < 0.5 * S * N * (N - 1)  # pruning skips most network evaluations


def test_unknown_strategy_and_missing_inputs():
    with pytest.raises(ValueError, match="unknown neighbour strategy"):
        make_selector("closest", 2)
    with pytest.raises(ValueError, match="needs the pairwise safety value"):
        make_selector("value", 2)
    with pytest.raises(ValueError, match="sensing radius"):
        make_selector("random", 2, agent=DoubleIntegrator)
    with pytest.raises(ValueError, match="needs the agents' model"):
        make_selector("nearest", 2)


def test_lexicographic_selection_orders_by_score_then_index():
    g = torch.Generator().manual_seed(0)
    for N in (1, 2, 3, 17, 300):
        x = torch.randint(-3, 4, (6, N), generator=g).float() * 0.5
        x[torch.rand(6, N, generator=g) < 0.2] = float("inf")
        x[x == 0] = -0.0  # −0 and +0 are equal scores: ordered by index
        x[:, : N // 2][x[:, : N // 2] == -0.0] = 0.0
        k = min(2, N)
        assert torch.equal(_lexicographic_topk(x, k), torch.sort(x, dim=-1, stable=True).indices[:, :k])
        assert torch.equal(_lexicographic_topk(x.double(), k), torch.sort(x, dim=-1, stable=True).indices[:, :k])


def test_free_drift_bound_is_the_closest_approach():
    x = torch.tensor([[1.0, 0.0, -2.0, 0.0],    # head-on: passes through p = 0 at τ = 0.5 s
                      [1.0, 0.3, -1.0, 0.0],    # closest 0.3 m at τ = 1 s
                      [1.0, 0.0, 1.0, 0.0],     # diverging: now
                      [3.0, 0.0, -1.0, 0.0]])   # still 2 m apart at the horizon
    lb = free_drift_lower_bound(x, 1.0, 0.1, DoubleIntegrator)
    assert torch.allclose(lb, torch.tensor([-0.1, 0.2, 0.9, 1.9]), atol=1e-6)
    psi = x[:, :2].norm(dim=-1) - 0.1
    assert (lb <= psi + 1e-7).all()
    y = torch.randn(500, 4, generator=torch.Generator().manual_seed(0))
    assert torch.equal(free_drift_lower_bound(y, 1.0, 0.1, DoubleIntegrator), free_drift_and_grad(y, 1.0, 0.1, DoubleIntegrator)[0])


def test_in_domain_is_the_box_test_on_every_ordered_pair():
    """Axis by axis as the definition: ``|p_i − p_j| ≤ p_range`` and ``|v_i − v_j| ≤ v_range`` per
    axis, the partner within the radius, no self-pair."""
    state = random_states(2, 40, 2.0, 3.0, seed=1)
    x = relative_states(state)
    box = (x[..., :2].abs() <= 1.0).all(-1) & (x[..., 2:].abs() <= 2.5).all(-1) & ~torch.eye(40, dtype=torch.bool)
    assert torch.equal(in_domain(state, 1.0, 2.5, DoubleIntegrator), box) and 0 < int(box.sum()) < box.numel() // 2
    near = box & (pairwise_distances(state[..., :2]) <= 0.8)
    assert torch.equal(in_domain(state, 1.0, 2.5, DoubleIntegrator, radius=0.8), near)


def crowd_states(S, N, half_width, v_max, seed, converging=0.0):
    """Uniform positions in the arena; velocities uniform in ±v_max plus ``converging`` m/s towards the centre."""
    state = random_states(S, N, half_width, v_max, seed=seed, dtype=torch.float32)
    if converging:
        p = state[..., 0:2]
        state[..., 2:4] = (state[..., 2:4] - converging * p / p.norm(dim=-1, keepdim=True).clamp_min(1e-3)).clamp(-4, 4)
    return state


@pytest.mark.skipif(not SHIPPED_VS.is_file(), reason="shipped models/vs.pt not present")
@pytest.mark.parametrize(
    "S,N,half_width,v_max,converging",
    [(1, 256, 4.0, 4.0, 0.0),    # 256 agents, large arena (4 agents/m²)
     (1, 256, 4.0, 2.0, 3.0),    # the same crowd converging on the centre (high closing speeds)
     (2, 128, 2.0, 4.0, 0.0),    # 8 agents/m²
     (8, 16, 1.0, 4.0, 0.0),     # small arena, 16 agents
     (8, 16, 1.0, 1.0, 3.5)],    # small arena, converging
)
def test_bounded_scoring_selects_exactly_what_exhaustive_scoring_selects(S, N, half_width, v_max, converging):
    vs = load_vs(SHIPPED_VS)
    margins = calibrate_drift_margins(vs)
    state = crowd_states(S, N, half_width, v_max, seed=N + S, converging=converging)
    counts = {}
    bounded = select_lowest(pair_scores_bounded(state, vs, 2, margins, chunk=4096, counts=counts), 2, exact_ties=True)
    exhaustive = select_lowest(pair_scores_brute_force(state, vs), 2, exact_ties=True)
    assert torch.equal(bounded, exhaustive)
    assert torch.equal(make_selector("value", 2, vs=vs)(state), exhaustive)
    assert counts["evaluated"] < counts["in_domain"]
    # the margin covers the measured excess of the free-drift bound over V_s on these states
    mask = in_domain(state, 2.0, 8.0, DoubleIntegrator)
    s, i, j = mask.nonzero(as_tuple=True)
    x = state[s, i] - state[s, j]
    assert (free_drift_lower_bound(x, vs.horizon, vs.collision_radius, DoubleIntegrator) - margins.of(x, DoubleIntegrator) <= vs.value(x, 0.0)).all()


@pytest.mark.skipif(not SHIPPED_VS.is_file(), reason="shipped models/vs.pt not present")
def test_bounded_scoring_edge_cases_fewer_candidates_phantoms_and_ties():
    vs = load_vs(SHIPPED_VS)
    margins = calibrate_drift_margins(vs)
    state = torch.zeros(1, 7, 4)
    state[0, :, 0] = torch.tensor([0.0, 0.5, 0.5, 0.5, 1.0, 6.0, 9.9])  # 1, 2, 3 coincide (same state): exact ties
    state[0, :, 3] = torch.tensor([0.0, -1.0, -1.0, -1.0, 0.5, 0.0, 0.0])
    state[0, 6, 1] = 0.5  # agent 6 has no in-domain partner; agent 5 neither
    for n in (1, 2, 3, 8):  # n = 8 > N: padding
        ref = select_lowest(pair_scores_brute_force(state, vs), n, exact_ties=True)
        got = select_lowest(pair_scores_bounded(state, vs, n, margins), n, exact_ties=True)
        assert torch.equal(got, ref)
        assert got[0, 5].tolist() == [PHANTOM] * n and got[0, 6].tolist() == [PHANTOM] * n
        assert (got[0, :5] != PHANTOM).sum(-1).tolist() == [min(n, 4)] * 5
    pick = select_lowest(pair_scores_bounded(state, vs, 2, margins), 2, exact_ties=True)[0]
    assert pick[0].tolist() == [1, 2]  # three tied partners: the lower indices, in order
    # an ego with fewer in-domain partners than n: every partner is evaluated, none pruned
    counts = {}
    pair_scores_bounded(state[:, :3], vs, 3, margins, counts=counts)
    assert counts["evaluated"] == counts["in_domain"] == 6
    # a margin too small to hold is still exact when nothing can be pruned (fewer than n partners)
    zero = DriftMargins(margins.edges, tuple(0.0 for _ in margins.margins))
    assert torch.equal(select_lowest(pair_scores_bounded(state, vs, 8, zero), 8, exact_ties=True),
                       select_lowest(pair_scores_brute_force(state, vs), 8, exact_ties=True))


@pytest.mark.skipif(not SHIPPED_VS.is_file(), reason="shipped models/vs.pt not present")
def test_pair_values_do_not_depend_on_the_batching():
    from madpinn.policies.neighbours import _vs_in_chunks

    vs = load_vs(SHIPPED_VS)
    x = vs.system.sample(3000, torch.Generator().manual_seed(2))
    full = _vs_in_chunks(vs, x, 65536)
    for size in (1, 5, 17, 999):
        parts = torch.cat([_vs_in_chunks(vs, x[i : i + size], 65536) for i in range(0, 3000, size)])
        assert torch.equal(parts, full)
    assert torch.equal(_vs_in_chunks(vs, x, 100), full)  # chunked calls too
