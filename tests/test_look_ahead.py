"""Actuator-lag compensation (madpinn.policies.look_ahead): predictions and the observation in
which an agent sees its own predicted state and the others' constant-velocity ones."""

import pytest
import torch

from madpinn.observation import ObservationSettings, build_observation, nearest_neighbours
from madpinn.policies.look_ahead import look_ahead_observation, observation_with_own_state, predict_states

SPEC = ObservationSettings(n_neighbours=2, goal_range=2.0, offset_range=2.0, sensing_radius=1.0, collision_radius=0.1,
                           model="double_integrator", carrot_margin=0.0, neighbour_goal="ego")


def world(S=3, N=6, seed=0):
    g = torch.Generator().manual_seed(seed)
    pos = torch.rand(S, N, 2, generator=g, dtype=torch.float64) * 2 - 1
    vel = torch.rand(S, N, 2, generator=g, dtype=torch.float64) * 2 - 1
    goals = torch.rand(S, N, 2, generator=g, dtype=torch.float64) * 2 - 1
    return torch.cat([pos, vel], -1), goals


def test_predict_states_is_the_double_integrator_under_constant_acceleration():
    state, _ = world()
    a = torch.full(state.shape[:-1] + (2,), 2.0, dtype=state.dtype)
    out = predict_states(state, a, 0.05, SPEC.agent)
    assert torch.allclose(out[..., :2], state[..., :2] + 0.05 * state[..., 2:] + 0.5 * 2.0 * 0.05**2)
    assert torch.allclose(out[..., 2:], state[..., 2:] + 2.0 * 0.05)
    cv = predict_states(state, None, 0.05, SPEC.agent)
    assert torch.equal(cv[..., 2:], state[..., 2:])
    assert torch.allclose(cv[..., :2], state[..., :2] + 0.05 * state[..., 2:])
    assert torch.equal(predict_states(state, a, 0.0, SPEC.agent), state)


@pytest.mark.parametrize("neighbour_goal", ["ego", "neighbour"])
def test_own_state_equal_to_the_others_gives_the_plain_observation(neighbour_goal):
    from dataclasses import replace

    spec = replace(SPEC, neighbour_goal=neighbour_goal)
    state, goals = world()
    nbrs = nearest_neighbours(SPEC.agent.position(state), 2)
    nbrs[0, 0, 1] = -1                                   # a phantom slot stays a phantom
    assert torch.equal(observation_with_own_state(state, state, goals, nbrs, spec),
                       build_observation(state, goals, nbrs, spec))


def test_own_state_moves_only_the_ego_part_of_the_observation():
    state, goals = world()
    nbrs = nearest_neighbours(SPEC.agent.position(state), 2)
    own = state.clone()
    own[..., :2] += torch.tensor([0.03, -0.02], dtype=state.dtype)
    own[..., 2:] += torch.tensor([0.1, 0.2], dtype=state.dtype)
    obs = observation_with_own_state(own, state, goals, nbrs, SPEC)
    assert obs.shape == (3, 6, SPEC.dim)
    assert torch.allclose(obs[..., 0:2], own[..., 2:4])                          # own velocity
    assert torch.allclose(obs[..., 2:4], goals - own[..., :2])                   # own goal offset
    j = nbrs[0, 0, 0]
    assert torch.allclose(obs[0, 0, 4:6], state[0, j, :2] - own[0, 0, :2])     # others: as given
    assert torch.allclose(obs[0, 0, 6:8], state[0, j, 2:])
    with pytest.raises(ValueError, match="same shape"):
        observation_with_own_state(own[:, :2], state, goals, nbrs, SPEC)


def test_look_ahead_observation_predicts_own_state_under_the_command_and_others_at_constant_velocity():
    state, goals = world()
    nbrs = nearest_neighbours(SPEC.agent.position(state), 2)
    u = torch.full(state.shape[:-1] + (2,), -4.0, dtype=state.dtype)
    tau = 0.075
    obs = look_ahead_observation(state, u, goals, nbrs, SPEC, tau)
    own, others = predict_states(state, u, tau, SPEC.agent), predict_states(state, None, tau, SPEC.agent)
    assert torch.equal(obs, observation_with_own_state(own, others, goals, nbrs, SPEC))
    assert torch.allclose(obs[..., 0:2], state[..., 2:4] - 4.0 * tau)            # velocity after τ of −4 m/s²
    first = look_ahead_observation(state, None, goals, nbrs, SPEC, tau)           # no command yet: zero acceleration
    assert torch.equal(first, build_observation(others, goals, nbrs, SPEC))
    assert torch.equal(look_ahead_observation(state, u, goals, nbrs, SPEC, 0.0), build_observation(state, goals, nbrs, SPEC))
