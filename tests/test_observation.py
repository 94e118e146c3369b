import math
from dataclasses import replace

import pytest
import torch

from madpinn.observation import (
    ObservationSettings,
    build_observation,
    constraint,
    nearest_neighbours,
    running_cost,
    shrink_to_box,
    split_observation,
)

SPEC = ObservationSettings(n_neighbours=2, goal_range=2.0, offset_range=2.0, sensing_radius=1.0, collision_radius=0.1,
                           model="double_integrator", carrot_margin=0.0, neighbour_goal="ego")


def _random_world(S=3, N=6, seed=0):
    g = torch.Generator().manual_seed(seed)
    pos = torch.rand(S, N, 2, generator=g) * 2 - 1
    vel = torch.rand(S, N, 2, generator=g) * 2 - 1
    goals = torch.rand(S, N, 2, generator=g) * 2 - 1
    return torch.cat([pos, vel], -1), goals


def test_layout_and_translation_invariance():
    state, goals = _random_world()
    nbrs = nearest_neighbours(SPEC.agent.position(state), 2)
    obs = build_observation(state, goals, nbrs, SPEC)
    assert obs.shape == (3, 6, SPEC.dim) == (3, 6, 16)
    shift = torch.tensor([0.37, -0.21])
    state2 = state.clone()
    state2[..., :2] += shift
    obs2 = build_observation(state2, goals + shift, nearest_neighbours(SPEC.agent.position(state2), 2), SPEC)
    assert torch.allclose(obs, obs2, atol=1e-5)
    # ego block: velocity and goal offset
    assert torch.allclose(obs[0, 0, :2], state[0, 0, 2:])
    assert torch.allclose(obs[0, 0, 2:4], goals[0, 0] - state[0, 0, :2])
    j = nbrs[0, 0, 0]
    assert torch.allclose(obs[0, 0, 4:6], state[0, j, :2] - state[0, 0, :2])
    assert torch.allclose(obs[0, 0, 6:8], state[0, j, 2:])
    assert torch.allclose(obs[0, 0, 8:10], goals[0, j] - state[0, 0, :2])


def test_phantom_padding_when_too_few_neighbours():
    state = torch.zeros(1, 2, 4)
    state[0, 1, 0] = 0.5
    goals = torch.zeros(1, 2, 2)
    nbrs = nearest_neighbours(SPEC.agent.position(state), 2)
    assert nbrs[0, 0].tolist() == [1, -1]
    obs = build_observation(state, goals, nbrs, SPEC)
    phantom = obs[0, 0, 10:16]
    assert torch.allclose(phantom, torch.tensor([-2.0, -2.0, 0.0, 0.0, -2.0, -2.0]))  # slot 1: opposite corner
    # the phantom sits at its goal (no cost) and far from everyone (no constraint)
    assert running_cost(obs[0, 0], 2).item() == pytest.approx(0.5)  # ego at goal, neighbour 0.5 m off
    assert constraint(obs[0, 0], 2, 0.1).item() == pytest.approx(0.1 - 0.5)


def test_radius_limited_neighbours_pad_with_phantoms():
    state = torch.zeros(1, 4, 4)
    state[0, :, 0] = torch.tensor([0.0, 0.5, 3.0, -3.0])
    nbrs = nearest_neighbours(SPEC.agent.position(state), 2, radius=1.0)
    assert nbrs[0, 0].tolist() == [1, -1]
    assert nbrs[0, 2].tolist() == [-1, -1]


def test_carrot_and_offset_clipping_keep_direction():
    v = torch.tensor([[6.0, 3.0], [1.0, -0.5], [-8.0, 8.0]])
    out = shrink_to_box(v, 2.0)
    assert out.abs().amax().item() <= 2.0 + 1e-6
    assert torch.allclose(out[1], v[1])
    for a, b in zip(out, v):
        assert math.isclose(float(a[0] * b[1] - a[1] * b[0]), 0.0, abs_tol=1e-5)  # parallel
        assert float((a * b).sum()) > 0
    state = torch.zeros(1, 3, 4)
    state[0, 1, :2] = torch.tensor([5.0, 0.0])
    state[0, 2, :2] = torch.tensor([0.0, -0.3])
    goals = torch.tensor([[[6.0, 0.0], [5.0, 1.0], [0.0, 0.0]]])
    obs = build_observation(state, goals, torch.tensor([[[1, 2], [0, 2], [0, 1]]]), SPEC)
    assert obs[0, 0, 2:4].tolist() == [2.0, 0.0]  # ego goal 6 m away -> carrot at 2 m
    assert obs[0, 0, 4:6].tolist() == [2.0, 0.0]  # neighbour 5 m away -> shrunk to 2 m


def test_costs_and_constraint_on_hand_built_observation():
    obs = torch.zeros(16)
    obs[2:4] = torch.tensor([3.0, 4.0])  # ego goal 5 m away
    obs[4:6] = torch.tensor([0.05, 0.0])  # neighbour 1 at 5 cm: collision
    obs[8:10] = torch.tensor([0.05, 1.0])  # its goal 1 m from it
    obs[10:12] = torch.tensor([1.0, 1.0])  # neighbour 2
    obs[14:16] = torch.tensor([1.0, 1.0])  # at its goal
    assert running_cost(obs, 2).item() == pytest.approx(6.0)
    assert constraint(obs, 2, 0.1).item() == pytest.approx(0.05)
    positions, velocities, goals = split_observation(obs.expand(5, 16), 2)
    assert positions.shape == velocities.shape == goals.shape == (5, 3, 2)


def test_bad_shapes_are_rejected():
    state, goals = _random_world()
    with pytest.raises(ValueError, match="neighbours must be"):
        build_observation(state, goals, torch.zeros(3, 6, 3, dtype=torch.long), SPEC)
    with pytest.raises(ValueError, match="state must be"):
        build_observation(state[0], goals, torch.zeros(3, 6, 2, dtype=torch.long), SPEC)
    with pytest.raises(ValueError, match="features"):
        running_cost(torch.zeros(4, 15), 2)


def test_pairwise_distances_are_exact_at_arena_scale():
    from madpinn.observation import pairwise_distances

    g = torch.Generator().manual_seed(1)
    p = torch.rand(2, 300, 2, generator=g) * 8 - 4
    d = pairwise_distances(p)
    ref = torch.linalg.vector_norm(p.double()[:, :, None] - p.double()[:, None], dim=-1)
    ref.diagonal(dim1=1, dim2=2).fill_(float("inf"))
    assert torch.allclose(d.double(), ref, atol=1e-5, rtol=0)


def test_phantoms_never_conflict_with_each_other():
    """An agent with no neighbour in range gets two phantoms that are far apart, so g_d < 0."""
    state = torch.zeros(1, 3, 4)
    state[0, 1, 0], state[0, 2, 0] = 3.0, -3.0
    nbrs = nearest_neighbours(SPEC.agent.position(state), 2, radius=1.0)
    assert nbrs[0, 0].tolist() == [-1, -1]
    obs = build_observation(state, torch.zeros(1, 3, 2), nbrs, SPEC)
    assert constraint(obs[0, 0], 2, 0.1).item() < -1.0
    assert running_cost(obs[0, 0], 2).item() == pytest.approx(0.0)


# --- issue 14: carrot margin and neighbour-relative goal shortening --------------------------

def _heading_deg(vec: torch.Tensor) -> float:
    return math.degrees(math.atan2(float(vec[1]), float(vec[0])))


def test_carrot_strictly_inside_the_trained_box_by_the_margin():
    spec = replace(SPEC, carrot_margin=0.25)
    gen = torch.Generator().manual_seed(100)
    state = torch.cat([torch.rand(4, 6, 2, generator=gen) * 16 - 8, torch.zeros(4, 6, 2)], dim=-1)
    goals = torch.rand(4, 6, 2, generator=gen) * 16 - 8
    nbrs = nearest_neighbours(SPEC.agent.position(state), 2)
    obs = build_observation(state, goals, nbrs, spec)
    ego_goal = obs[..., 2:4]
    assert ego_goal.abs().amax() <= 1.75 + 1e-6          # goal_range − margin
    far = (goals - state[..., 0:2]).abs().amax(-1) > 2.0
    assert far.any()
    # shortened along its own direction, onto the inner box edge
    assert torch.allclose(ego_goal[far].abs().amax(-1), torch.full((int(far.sum()),), 1.75), atol=1e-5)
    cos = torch.nn.functional.cosine_similarity(ego_goal[far], (goals - state[..., 0:2])[far], dim=-1)
    assert cos.min() > 1 - 1e-5
    # neighbour goals stay inside the inner box (or, for a neighbour beyond it, no farther out than it)
    for mode in ("neighbour", "ego"):
        o = build_observation(state, goals, nbrs, replace(spec, neighbour_goal=mode))
        nbr = o[..., 4:].reshape(4, 6, 2, 6)
        bound = nbr[..., 0:2].abs().amax(-1).clamp_min(1.75) if mode == "neighbour" else 1.75
        assert (nbr[..., 4:6].abs().amax(-1) <= bound + 1e-6).all()
    # margin 0: the old mapping (carrot on the box edge)
    old = build_observation(state, goals, nbrs, SPEC)
    assert torch.allclose(old[..., 2:4][far].abs().amax(-1), torch.full((int(far.sum()),), 2.0), atol=1e-5)


def test_neighbour_goal_is_shortened_relative_to_the_neighbour_keeping_its_heading():
    # the example: a neighbour at (1.5, −1.5) heading to (6, 6), ego at the origin
    state = torch.tensor([[[0.0, 0.0, 0.0, 0.0], [1.5, -1.5, 0.0, 0.0]]])
    goals = torch.tensor([[[1.0, 0.0], [6.0, 6.0]]])
    nbrs = torch.tensor([[[1, -1], [0, -1]]])
    true_heading = _heading_deg(torch.tensor([4.5, 7.5]))
    new = build_observation(state, goals, nbrs, replace(SPEC, neighbour_goal="neighbour"))[0, 0]
    old = build_observation(state, goals, nbrs, replace(SPEC, neighbour_goal="ego"))[0, 0]
    p_j, g_j = new[4:6], new[8:10]
    assert abs(_heading_deg(g_j - p_j) - true_heading) < 0.01
    assert g_j.abs().amax() <= 2.0 + 1e-6 and (g_j - p_j).norm() > 0.5   # inside the box, still heading out
    # the old mapping turns it by ≈ 23° (the distortion this fixes)
    assert abs(_heading_deg(old[8:10] - old[4:6]) - true_heading) > 15.0
    # a neighbour whose goal is already inside the box is unchanged by either mapping
    goals_in = torch.tensor([[[1.0, 0.0], [1.0, -0.5]]])
    a = build_observation(state, goals_in, nbrs, replace(SPEC, neighbour_goal="neighbour"))
    b = build_observation(state, goals_in, nbrs, replace(SPEC, neighbour_goal="ego"))
    assert torch.allclose(a, b)


def test_neighbour_beyond_the_box_heading_outward_is_not_pushed_further_out():
    spec = replace(SPEC, neighbour_goal="neighbour", carrot_margin=0.3)
    state = torch.tensor([[[0.0, 0.0, 0.0, 0.0], [1.9, 0.0, 0.0, 0.0]]])   # beyond 1.7, inside offset_range
    goals = torch.tensor([[[0.0, 0.0], [5.0, 0.5]]])
    g_j = build_observation(state, goals, torch.tensor([[[1, -1], [0, -1]]]), spec)[0, 0, 8:10]
    assert torch.allclose(g_j, torch.tensor([1.9, 0.0]), atol=1e-6)   # s = 0: goal at the neighbour


def test_bad_carrot_margin_and_mode_fail_early():
    with pytest.raises(ValueError, match="carrot_margin"):
        replace(SPEC, carrot_margin=2.0)
    with pytest.raises(ValueError, match="neighbour_goal"):
        replace(SPEC, neighbour_goal="sideways")


def test_deployment_only_keys_change_neither_the_training_spec_nor_the_training_hash(paper_cfg):
    import copy

    from madpinn.value_functions.epigraph import EpigraphSystem
    from madpinn.value_functions.build import training_hash

    cfg = copy.deepcopy(paper_cfg)
    cfg["observation"].update(carrot_margin=0.5, neighbour_goal="ego")
    assert training_hash(cfg, "vhat") == training_hash(paper_cfg, "vhat")
    spec = EpigraphSystem.from_config(cfg).spec
    assert spec.carrot_margin == 0.0 and spec.neighbour_goal == "ego"
    cfg["value_functions"]["vhat"]["velocity_saturation"] = True      # this one does retrain
    assert training_hash(cfg, "vhat") != training_hash(paper_cfg, "vhat")


def test_join_observation_inverts_split_observation():
    from madpinn.observation import join_observation, split_observation

    obs = torch.randn(5, 7, SPEC.layout.dim(3), generator=torch.Generator().manual_seed(3), dtype=torch.float64)
    assert torch.equal(join_observation(*split_observation(obs, 3)), obs)
