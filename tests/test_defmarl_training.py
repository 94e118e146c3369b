"""DEF-MARL training and deployment on a tiny budget: z conditions the actor, the epigraph
objective improves, determinism under a seed, checkpoints, the root-finding policy."""

import dataclasses

import pytest
import torch

from madpinn.dynamics import DoubleIntegrator
from madpinn.marl.checkpoint import CheckpointError, save_checkpoint
from madpinn.marl.defmarl.deploy import load_defmarl
from madpinn.marl.defmarl.epigraph import EpigraphSettings
from madpinn.marl.defmarl.trainer import DefMarlTrainer
from madpinn.marl.env import EnvSettings, GoalReachingEnv, RewardSettings
from madpinn.marl.ppo import PPOSettings
from madpinn.scenarios import Arena, generate_scenarios
from madpinn.simulation import DoubleIntegratorBackend, run_episode
from settings_helpers import observation_settings


pytestmark = pytest.mark.usefixtures("one_thread")


TINY = PPOSettings(iterations=12, agents_per_batch=96, epochs=4, minibatch=256, lr=3e-3, discount=0.95,
                 gae_lambda=0.9, clip=0.2, entropy_coef=0.0, value_coef=0.5, max_grad_norm=0.5, init_log_std=-0.5)
EPI = EpigraphSettings(z_min=-1.0, z_max=1.0, end_mass=0.2, h_clip=0.2, cost_lr=3e-3, h_margin=0.5)
Z_GRID = (-1.0, 0.0, 1.0)


def _trainer(ppo=TINY, seed=0, counts=(3,)):
    env = GoalReachingEnv(DoubleIntegrator(4.0, 4.0), Arena("small", 1.0, 0.5), observation_settings(), EnvSettings(0.05, 2, 3), seed=seed)
    return DefMarlTrainer(env, ppo, RewardSettings(1.0, 1.0, 0.01, 0.0), counts, hidden=16, seed=seed, epigraph=EPI)


def _objective(tr) -> float:
    return sum(tr.evaluate_epigraph(32, 3, z)["epigraph_objective"] for z in Z_GRID) / len(Z_GRID)


def test_actor_and_constraint_critic_depend_on_z():
    tr = _trainer()
    obs = tr.env.reset(4, 3)
    tr.on_reset(4, 3)
    outs = []
    for z in (-1.0, 1.0):
        tr.z = torch.full((4,), z)
        x = tr.obs_norm(tr.augment(obs)).flatten()
        assert x.ego.shape[-1] == 5  # ego features ‖ z
        outs.append((tr.actor(x), tr.critic(x), tr.cost_critic(x, 3)))
    for a, b in zip(*outs):
        assert not torch.allclose(a, b)
    assert outs[0][2].shape == (4,)  # one team cost value per environment


def test_rollout_tracks_z_dynamics_and_constraint():
    tr = _trainer()
    buf, last, stats = tr.collect(3)
    h, cost, z = tr.episode_tensors()
    T, E = cost.shape
    assert h.shape == (T, E, 3) and T == tr.env.horizon and len(buf) == T
    assert torch.allclose(z[1:], (z[:-1] - cost[:-1]).clamp(EPI.z_min, EPI.z_max))  # z' = z − l
    raw = buf.get("raw_reward")
    assert torch.allclose(cost, -raw.mean(-1))  # team cost = mean per-agent cost, no collision term
    assert 0.0 <= stats["violation_rate"] <= 1.0 and EPI.z_min <= stats["z_start_mean"] <= EPI.z_max
    adv, targets = tr.advantages(buf, last)
    assert adv.shape == (T, E, 3) and targets.shape == (T, E, 3, 1) and torch.isfinite(adv).all()


def test_smoke_training_improves_the_epigraph_objective():
    tr = _trainer()
    before = _objective(tr)
    hist = tr.train(progress=False)
    after = _objective(tr)
    assert after < before - 0.02, (before, after)
    assert all(k in hist[-1] for k in ("loss_cost", "violation_rate", "z_end_mean", "epigraph_objective"))


def test_determinism_under_a_seed():
    ppo = dataclasses.replace(TINY, iterations=2)
    a, b = _trainer(ppo), _trainer(ppo)
    ha, hb = a.train(progress=False), b.train(progress=False)
    for m in ("actor", "critic", "cost_critic"):
        for pa, pb in zip(getattr(a, m).parameters(), getattr(b, m).parameters()):
            assert torch.equal(pa, pb)
    assert [h["epigraph_objective"] for h in ha] == [h["epigraph_objective"] for h in hb]
    c = _trainer(ppo, seed=1)
    c.train(progress=False)
    assert not torch.equal(next(a.actor.parameters()), next(c.actor.parameters()))


def test_reward_with_collision_penalty_is_refused():
    env = GoalReachingEnv(DoubleIntegrator(4.0, 4.0), Arena("small", 1.0, 0.5), observation_settings(), EnvSettings(0.05, 2, 3), seed=0)
    with pytest.raises(ValueError, match="collision"):
        DefMarlTrainer(env, TINY, RewardSettings(1.0, 1.0, 0.01, 3.0), (3,), hidden=16, seed=0, epigraph=EPI)


def test_checkpoint_and_root_finding_deployment(tmp_path):
    tr = _trainer(dataclasses.replace(TINY, iterations=2))
    tr.train(progress=False)
    path = save_checkpoint(tmp_path / "defmarl.pt", tr, meta={"method": "defmarl", "epigraph": dataclasses.asdict(EPI)})
    spec = observation_settings()
    pol = load_defmarl(path, spec, 4.0, spec.collision_radius, iterations=20)
    starts, goals = generate_scenarios(Arena("small", 1.0, 0.2), 4, 0, 3, 2 * spec.collision_radius)
    state = torch.cat([starts, torch.zeros_like(starts)], -1)
    _, z, root = pol.budgets(state, goals)
    assert ((z >= EPI.z_min) & (z <= EPI.z_max)).all()
    assert torch.equal(z, z.amax(-1, keepdim=True).expand_as(z))  # one budget per team: the maximum
    # each agent's own root is its smallest safe z under its critic (or a documented fallback)
    zi = root.z
    assert (root.all_safe <= (zi == EPI.z_min)).all() and (root.none_safe <= (zi == EPI.z_max)).all()
    # actions follow the team budget: same as the actor queried at that z directly
    u = pol.act(state, goals, 0.0)
    assert u.shape == (3, 4, 2) and (u.abs() <= 4.0 + 1e-6).all()
    tr.z = z[:, 0]
    from madpinn.marl.features import local_observation
    x = tr.obs_norm(tr.augment(local_observation(state, goals, spec, 3))).flatten()
    assert torch.allclose(u, (tr.actor(x).clamp(-1, 1) * 4.0).view(3, 4, 2), atol=1e-5)
    res, _ = run_episode(DoubleIntegratorBackend(DoubleIntegrator(4.0, 4.0), 0.0025), pol, starts, goals, 40, spec.collision_radius)
    assert res.cost.shape == (3, 4) and pol.stats.steps == 41 * 12  # + the act() above
    # budgets re-solved every root_period policy steps, held in between
    held = load_defmarl(path, spec, 4.0, spec.collision_radius, root_period=4)
    held.reset(state, goals)
    for k in range(8):
        held.act(state + 0.01 * k, goals, 0.0)
    assert held.stats.steps == 2 * 12
    # a SafeMARL-style PPO checkpoint or a corrupted file is refused with a clear error
    plain = save_checkpoint(tmp_path / "plain.pt", tr, meta={"method": "safemarl-nominal"})
    with pytest.raises(CheckpointError, match="not a DEF-MARL checkpoint"):
        load_defmarl(plain, spec, 4.0, spec.collision_radius)
    (tmp_path / "bad.pt").write_bytes(b"garbage")
    with pytest.raises(CheckpointError, match="cannot read"):
        load_defmarl(tmp_path / "bad.pt", spec, 4.0, spec.collision_radius)
    with pytest.raises(ValueError, match="u_max"):
        load_defmarl(path, spec, 2.0, spec.collision_radius)


def test_attention_encoder_and_its_deployment(tmp_path):
    """``encoder="attention"``: invariant to the neighbours' order, blind to masked slots, zeros
    without neighbours; a DEF-MARL model trained with it is saved, reloaded with the same encoder
    and deployed (actions = the actor at the team budget; V_h at the chosen z = the critic's)."""
    from madpinn.marl.features import LocalObs, local_observation
    from madpinn.marl.networks import AttentionEncoder

    torch.manual_seed(0)
    enc = AttentionEncoder(5, 6, 8)
    ego, nbr = torch.randn(3, 5), torch.randn(3, 4, 6)
    mask = torch.tensor([[True, True, True, False], [True, False, False, False], [False] * 4])
    out = enc(LocalObs(ego, nbr, mask))
    perm = torch.tensor([2, 0, 1, 3])
    assert torch.allclose(out, enc(LocalObs(ego, nbr[:, perm], mask[:, perm])), atol=1e-6)
    nbr2 = nbr.clone()
    nbr2[~mask] = 100.0
    assert torch.allclose(out, enc(LocalObs(ego, nbr2, mask)), atol=1e-6)
    assert torch.equal(out[2, 5:13], torch.zeros(8))   # no neighbour: the attention pool is 0
    z_changed = ego.clone()
    z_changed[:, 4] += 3.0                              # an extra ego column (z) only moves itself
    assert torch.equal(enc(LocalObs(z_changed, nbr, mask))[:, 5:], out[:, 5:])

    env = GoalReachingEnv(DoubleIntegrator(4.0, 4.0), Arena("small", 1.0, 0.5), observation_settings(), EnvSettings(0.05, 2, 3), seed=0)
    tr = DefMarlTrainer(env, dataclasses.replace(TINY, iterations=2), RewardSettings(1.0, 1.0, 0.01, 0.0), (3,), hidden=16,
                        seed=0, epigraph=EPI, encoder="attention")
    tr.train(progress=False)
    path = save_checkpoint(tmp_path / "att.pt", tr, meta={"method": "defmarl", "epigraph": dataclasses.asdict(EPI)})
    spec = observation_settings()
    pol = load_defmarl(path, spec, 4.0, spec.collision_radius)
    assert type(pol.critic.encoder).__name__ == "AttentionEncoder"
    starts, goals = generate_scenarios(Arena("small", 1.0, 0.2), 4, 0, 3, 2 * spec.collision_radius)
    state = torch.cat([starts, torch.zeros_like(starts)], -1)
    _, z, root = pol.budgets(state, goals)
    # the search's fast path (first trunk layer affine in z) agrees with the critic itself: each
    # agent's own root is predicted safe by the critic evaluated directly there
    obs = local_observation(state, goals, spec, 3).with_extra(root.z.view(3, 4, 1))
    vh = tr.critic(tr.obs_norm(obs).flatten())[:, 0]
    # (at z_min for the all-safe fallback; at z_max, predicted unsafe, for the none-safe one)
    assert (vh[~root.none_safe] <= 1e-4).all() and (vh[root.none_safe] > -1e-4).all()
    u = pol.act(state, goals, 0.0)
    tr.z = z[:, 0]
    x = tr.obs_norm(tr.augment(local_observation(state, goals, spec, 3))).flatten()
    assert torch.allclose(u, (tr.actor(x).clamp(-1, 1) * 4.0).view(3, 4, 2), atol=1e-5)
