"""Neighbour strategies: value (with pruning), nearest, random, phantom padding."""

import pytest
import torch

from madpinn.observation import PHANTOM
from madpinn.policies.neighbours import (
    in_domain,
    make_selector,
    pair_scores,
    pair_scores_brute_force,
    select_lowest,
)
from policy_models import tiny_models


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
    idx = make_selector("nearest", 2)(state)
    assert idx[0].tolist() == [[2, 1], [0, 2], [0, 1], [1, 0]]  # unlimited range: the far agent still gets 2
    single = make_selector("nearest", 2)(torch.zeros(3, 1, 4))
    assert (single == PHANTOM).all() and single.shape == (3, 1, 2)


def test_random_strategy_within_radius_seeded_and_uniform():
    state = torch.zeros(1, 6, 4)
    state[0, :, 0] = torch.tensor([0.0, 0.5, -0.9, 0.1, 1.2, 3.0])  # agent 0 senses 1, 2, 3 (radius 1)
    sel = make_selector("random", 2, radius=1.0, generator=torch.Generator().manual_seed(3))
    seen = set()
    for _ in range(60):
        idx = sel(state)[0]
        assert set(idx[0].tolist()) <= {1, 2, 3} and idx[0, 0] != idx[0, 1]
        seen.update(idx[0].tolist())
        assert idx[5].tolist() == [PHANTOM, PHANTOM]  # nobody within 1 m of agent 5
        assert idx[4].tolist() == [1, PHANTOM]  # only agent 1 (0.7 m) within range of agent 4
    assert seen == {1, 2, 3}
    a = make_selector("random", 2, radius=1.0, generator=torch.Generator().manual_seed(7))
    b = make_selector("random", 2, radius=1.0, generator=torch.Generator().manual_seed(7))
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
    mask = in_domain(state, vs.system.p_range, vs.system.v_range)
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
        make_selector("random", 2)
