"""SafeMARL end to end with a learned V_s (issue 3's PINN trainer, a small budget): two agents
on a head-on course do not collide under the filter, and the `safemarl` method runs through
the evaluation job with the V_s and nominal checkpoints loaded from disk."""

from pathlib import Path

import pytest
import torch
import yaml

from madpinn.config import deep_merge, validate_config
from madpinn.dynamics import DoubleIntegrator
from madpinn.dynamics.pair import PairSystem
from madpinn.marl.checkpoint import save_checkpoint
from madpinn.marl.env import EnvSettings, GoalReachingEnv
from madpinn.marl.trainer import PPOTrainer
from madpinn.policies.nominal import NominalPD
from madpinn.policies.safemarl import CBVFFilter, SafetyFilteredPolicy
from madpinn.scenarios import Arena
from madpinn.simulation import DoubleIntegratorBackend, run_episode
from madpinn.value_functions import load_vs
from madpinn.value_functions.model import model_payload, save_atomic
from madpinn.value_functions.problems import PairProblem
from madpinn.value_functions.train import TrainSettings, train
from settings_helpers import observation_settings, pair_system, ppo_settings, reward_settings

DYN = DoubleIntegrator(4.0, 4.0)
R = 0.1


@pytest.fixture(scope="module")
def models(tmp_path_factory):
    """A V_s trained for 300 iterations (seconds) and a one-iteration nominal policy, on disk."""
    n_threads = torch.get_num_threads()
    torch.set_num_threads(1)
    d = tmp_path_factory.mktemp("results") / "models"
    d.mkdir()
    problem = PairProblem(pair_system())
    s = TrainSettings(iterations=300, batch_size=512, lr=1e-3, lr_final=1e-4, curriculum_fraction=0.5,
                      checkpoint_every=10**6, network={"hidden": 64, "layers": 2, "first_omega": 30.0, "hidden_omega": 30.0}, seed=0,
                      loss="l1", output_scale=1.0, init_from=None, obstacle_weight=0.0, stop_at=None)
    net, _ = train(problem, s, d / "vs.ckpt.pt", "test", progress=False)
    save_atomic(model_payload(problem, net, 1.0, {}), d / "vs.pt")
    env = GoalReachingEnv(DYN, Arena("small", 1.0, 0.2), observation_settings(), EnvSettings(0.05, 1, 2), seed=0)
    tr = PPOTrainer(env, ppo_settings(iterations=1, agents_per_batch=12, epochs=1, minibatch=64), reward_settings(), (3,), hidden=8, seed=0)
    tr.train(progress=False)
    save_checkpoint(d / "safemarl_nominal.pt", tr)
    yield d
    torch.set_num_threads(n_threads)


@pytest.mark.parametrize("offset", [0.0, 0.02])
def test_head_on_agents_do_not_collide_with_the_learned_vs(models, offset):
    vs = load_vs(models / "vs.pt")
    starts = torch.tensor([[[-0.6, offset], [0.6, -offset]]])
    goals = torch.tensor([[[0.6, 0.0], [-0.6, 0.0]]])
    nominal = NominalPD(DYN, kp=6.0, kd=4.9)
    flt = CBVFFilter(vs, 4.0, gamma=1.0, critical=2, candidates=4, threshold=0.0, sensing_radius=1.0)
    res, _ = run_episode(DoubleIntegratorBackend(DYN, 0.0025), SafetyFilteredPolicy(nominal, flt), starts, goals, 800, R,
                         policy_period=4, progress=False)
    assert not res.collided.any() and res.min_separation.min() > R
    assert flt.stats.active > 0  # the filter did the avoiding
    alone, _ = run_episode(DoubleIntegratorBackend(DYN, 0.0025), nominal, starts, goals, 800, R, progress=False)
    assert alone.collided.all()


def test_safemarl_method_evaluates_end_to_end(models, tmp_path):
    from madpinn.commands.evaluate import evaluate

    root = Path(__file__).resolve().parents[1]
    cfg = deep_merge(yaml.safe_load((root / "config.yaml").read_text()), yaml.safe_load((root / "workflow/configs/smoke.yaml").read_text()))
    cfg["paths"] = {"results": str(models.parent), "figures": str(tmp_path / "figs")}
    cfg["tracking"]["enabled"] = False
    cfg["sim"]["backend"] = "double_integrator"
    validate_config(cfg)
    summary = evaluate(cfg, "main", "safemarl", 3, 0, tmp_path / "out.parquet", progress=False, track=False,
                       models={"nominal": models / "safemarl_nominal.pt", "vs": models / "vs.pt"})
    assert summary["method"] == "safemarl" and 0.0 <= summary["safety_rate"] <= 1.0
