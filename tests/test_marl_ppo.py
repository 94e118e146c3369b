"""GAE, PPO learning on a tiny budget, determinism, checkpoints, NaN guard."""

import dataclasses

import pytest
import torch

from madpinn.dynamics import DoubleIntegrator
from madpinn.marl.checkpoint import CheckpointError, load_actor, save_checkpoint
from madpinn.marl.deploy import ActorPolicy
from madpinn.marl.env import EnvSettings, GoalReachingEnv, RewardSettings
from madpinn.marl.gae import gae
from madpinn.marl.ppo import PPOSettings
from madpinn.marl.trainer import PPOTrainer
from madpinn.scenarios import Arena
from madpinn.simulation import DoubleIntegratorBackend, run_episode
from settings_helpers import observation_settings, reward_settings


pytestmark = pytest.mark.usefixtures("one_thread")


TINY = PPOSettings(iterations=12, agents_per_batch=96, epochs=4, minibatch=256, lr=3e-3, discount=0.95,
                 gae_lambda=0.9, clip=0.2, entropy_coef=0.0, value_coef=0.5, max_grad_norm=0.5, init_log_std=-0.5)


def _trainer(ppo=TINY, seed=0, counts=(3,)):
    env = GoalReachingEnv(DoubleIntegrator(4.0, 4.0), Arena("small", 1.0, 0.5), observation_settings(),
                          EnvSettings(0.05, 2, 3), seed=seed)
    return PPOTrainer(env, ppo, RewardSettings(1.0, 1.0, 0.01, 1.0), counts, hidden=16, seed=seed)


def test_gae_against_hand_recursion():
    r = torch.tensor([[1.0], [0.0], [2.0]])
    v = torch.tensor([[0.5], [1.0], [-1.0]])
    last = torch.tensor([3.0])
    g, lam = 0.9, 0.8
    adv, ret = gae(r, v, last, g, lam)
    d2 = 2.0 + g * 3.0 - (-1.0)
    d1 = 0.0 + g * -1.0 - 1.0
    d0 = 1.0 + g * 1.0 - 0.5
    a2 = d2
    a1 = d1 + g * lam * a2
    a0 = d0 + g * lam * a1
    assert torch.allclose(adv.squeeze(), torch.tensor([a0, a1, a2]))
    assert torch.allclose(ret, adv + v)
    # λ = 1: discounted return minus value; a termination stops the bootstrap
    adv1, _ = gae(r, v, last, g, 1.0, terminated=torch.tensor([[False], [False], [True]]))
    assert torch.allclose(adv1[0], torch.tensor([1.0 + g * 0.0 + g * g * 2.0 - 0.5]))


def test_ppo_improves_return_on_tiny_budget():
    tr = _trainer()
    before = tr.evaluate(32, 3)
    tr.train(progress=False)
    after = tr.evaluate(32, 3)
    assert after["return"] > before["return"] + 0.1, (before, after)
    assert after["final_distance"] < before["final_distance"]
    assert len(tr.history) == TINY.iterations


def test_training_is_reproducible_under_a_seed():
    ppo = dataclasses.replace(TINY, iterations=2)
    a, b = _trainer(ppo), _trainer(ppo)
    ha, hb = a.train(progress=False), b.train(progress=False)
    for x, y in zip(ha, hb):
        assert {k: v for k, v in x.items() if k != "wall_s"} == {k: v for k, v in y.items() if k != "wall_s"}
    for p, q in zip(a.actor.parameters(), b.actor.parameters()):
        assert torch.equal(p, q)
    c = _trainer(ppo, seed=1)
    c.train(progress=False)
    assert not torch.equal(next(a.actor.parameters()), next(c.actor.parameters()))


def test_checkpoint_round_trip_deploys_and_errors(tmp_path):
    tr = _trainer(dataclasses.replace(TINY, iterations=1))
    tr.train(progress=False)
    path = save_checkpoint(tmp_path / "m.pt", tr, meta={"method": "test"})
    actor, norm, meta = load_actor(path)
    assert meta["method"] == "test" and meta["neighbours"] == 3 and meta["train_dt"] == 0.05
    obs = tr.env.reset(4, 3, fixed_seed=5)
    with torch.no_grad():
        assert torch.equal(actor(norm(obs).flatten()), tr.actor(tr.obs_norm(obs).flatten()))
    # deployment at the simulator's period through the Policy protocol
    policy = ActorPolicy(actor, norm, observation_settings(), meta["neighbours"], 4.0)
    starts, goals = tr.env.state[..., :2].clone(), tr.env.goals.clone()
    res, _ = run_episode(DoubleIntegratorBackend(DoubleIntegrator(u_max=4.0, v_max=4.0), 0.0025), policy, starts, goals, 10, 0.1, progress=False)
    assert res.cost.shape == (4, 3)
    with pytest.raises(CheckpointError, match="not found"):
        load_actor(tmp_path / "missing.pt")
    bad = tmp_path / "bad.pt"
    bad.write_bytes(b"not a checkpoint")
    with pytest.raises(CheckpointError, match="corrupted"):
        load_actor(bad)
    torch.save({"format": "something-else"}, tmp_path / "other.pt")
    with pytest.raises(CheckpointError, match="not a madpinn-marl-ppo"):
        load_actor(tmp_path / "other.pt")


def test_non_finite_loss_fails_clearly():
    class NaNReward(PPOTrainer):
        def reward(self, info):
            return super().reward(info) * float("nan")

    env = GoalReachingEnv(DoubleIntegrator(4.0, 4.0), Arena("small", 1.0, 0.2), observation_settings(), EnvSettings(0.05, 1, 2), seed=0)
    tr = NaNReward(env, dataclasses.replace(TINY, iterations=1), reward_settings(), (3,), hidden=8, seed=0)
    with pytest.raises(FloatingPointError, match="non-finite"):
        tr.train(progress=False)
