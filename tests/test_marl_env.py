"""Vectorised MARL environment, local observation and permutation-invariant networks."""

import pytest
import torch

from madpinn.dynamics import DoubleIntegrator
from madpinn.marl.env import EnvSettings, GoalReachingEnv, RewardSettings, goal_reward
from madpinn.marl.features import local_observation
from madpinn.marl.networks import GaussianActor, ValueCritic
from madpinn.scenarios import Arena
from madpinn.simulation import DoubleIntegratorBackend
from settings_helpers import observation_settings


pytestmark = pytest.mark.usefixtures("one_thread")


DYN = DoubleIntegrator(4.0, 4.0)
SPEC = observation_settings()


def _env(episode_s=3.0, substeps=5):
    return GoalReachingEnv(DYN, Arena("small", 1.0, episode_s), SPEC, EnvSettings(0.05, substeps, 4), seed=0)


def test_reset_shapes_and_scenario_rules():
    env = _env()
    obs = env.reset(16, 5)
    assert env.state.shape == (16, 5, 4) and env.goals.shape == (16, 5, 2)
    assert obs.ego.shape == (16, 5, 4) and obs.neighbours.shape == (16, 5, 4, 6) and obs.mask.shape == (16, 5, 4)
    assert (env.state[..., 2:] == 0).all() and (env.state[..., :2].abs() <= 1.0).all()
    d = torch.cdist(env.state[..., :2], env.state[..., :2]) + torch.eye(5) * 10
    assert (d >= 2 * SPEC.collision_radius - 1e-6).all()
    first = env.state.clone()
    env.reset(16, 5)
    assert not torch.equal(first, env.state)  # fresh scenarios every episode
    env.reset(16, 5, fixed_seed=7)
    fixed = env.state.clone()
    env.reset(16, 5, fixed_seed=7)
    assert torch.equal(fixed, env.state)
    assert env.horizon == 60


def test_step_matches_simulator_and_detects_collisions_inside_period():
    env = _env()
    env.reset(4, 3)
    start = env.state.clone()
    u = torch.rand(4, 3, 2, generator=torch.Generator().manual_seed(0)) * 16 - 8  # outside the box too
    _, info = env.step(u)
    sim = DoubleIntegratorBackend(DYN, dt=0.0025)
    sim.reset(start[..., :2], start[..., 2:])
    sim.command(u, 0.05)
    for _ in range(20):
        s = sim.step()
    assert torch.allclose(env.state, s, atol=1e-5)
    assert (info.accel.abs() <= 4.0).all()
    # two agents crossing through each other within one period: caught by the sub-step checks
    env.state = torch.tensor([[[-0.12, 0.0, 4.0, 0.0], [0.12, 0.0, -4.0, 0.0]]])
    env.goals = torch.zeros(1, 2, 2)
    env.t = 0
    _, info = env.step(torch.zeros(1, 2, 2))
    assert info.collided.all() and (env.state[0, 0, 0] > env.state[0, 1, 0])  # passed through


def test_reward_terms():
    env = _env()
    env.state = torch.tensor([[[0.5, 0.0, 0.0, 0.0], [-0.5, 0.5, 0.0, 0.0]]])
    env.goals = torch.tensor([[[0.0, 0.0], [-0.5, -0.5]]])
    env.t = 0
    _, info = env.step(torch.tensor([[[-4.0, 0.0], [0.0, 0.0]]]))
    w = RewardSettings(progress=1.0, distance=0.0, control=0.0, collision=0.0)
    r = goal_reward(info, w, 0.05, 4.0)
    assert r[0, 0] > 0 and r[0, 1] == 0  # moving towards the goal is rewarded
    w = RewardSettings(progress=0.0, distance=0.0, control=1.0, collision=0.0)
    assert torch.allclose(goal_reward(info, w, 0.05, 4.0), torch.tensor([[-0.05, 0.0]]))


def test_local_observation_masks_far_agents_and_nets_are_permutation_invariant():
    state = torch.tensor([[[0.0, 0.0, 0.1, 0.0], [0.3, 0.0, 0.0, 0.2], [0.0, -0.5, -1.0, 0.0], [0.9, 0.9, 0.0, 0.0]]])
    goals = torch.zeros(1, 4, 2)
    obs = local_observation(state, goals, SPEC, k=4)
    assert obs.mask[0, 0].tolist() == [True, True, False, False]  # agent 3 is 1.27 m away
    assert torch.allclose(obs.neighbours[0, 0, 0, :4], torch.tensor([0.3, 0.0, -0.1, 0.2]))
    assert (obs.neighbours[0, 0, 2:] == 0).all()
    torch.manual_seed(0)
    actor, critic = GaussianActor(4, 6, 16), ValueCritic(4, 6, 16, heads=2)
    flat = obs.flatten()
    perm = torch.tensor([1, 0, 3, 2])
    swapped = type(flat)(flat.ego, flat.neighbours[:, perm], flat.mask[:, perm])
    # summing the neighbour slots in another order rounds differently (a few float32 ulps, more
    # after the layers and on other CPUs); a non-invariant net differs by O(0.1)
    assert torch.allclose(actor(flat), actor(swapped), atol=1e-5)
    assert torch.allclose(critic(flat), critic(swapped), atol=1e-5)
    assert critic(flat).shape == (4, 2)
    # masked slots do not matter whatever they hold
    junk = flat.neighbours.clone()
    junk[~flat.mask] = 123.0
    assert torch.allclose(actor(flat), actor(type(flat)(flat.ego, junk, flat.mask)), atol=1e-6)
