"""Scenario-based verification of V̂ (issue 15) on a tiny trained model."""

import json

import pytest
import torch

from conftest import REPO, SMOKE
from madpinn.commands import main
from madpinn.value_functions.verification import ScenarioSettings, epsilon_bound, rollout, verify
from policy_models import tiny_model_dir, tiny_models

CONFIGS = [str(REPO / "config.yaml"), str(SMOKE)]


def test_epsilon_bound_is_the_binomial_tail():
    from scipy.stats import binom

    for k, n, beta in ((0, 1000, 1e-3), (5, 1000, 1e-6), (40, 500, 0.05)):
        eps = epsilon_bound(k, n, beta)
        assert k / n < eps < 1.0
        assert binom.cdf(k, n, eps) == pytest.approx(beta, rel=1e-6)      # P[Bin(N, ε) ≤ k] = β
    assert epsilon_bound(0, 1000, 1e-3) == pytest.approx(1 - 1e-3 ** (1 / 1000), rel=1e-9)   # k = 0: 1 − β^(1/N)
    assert epsilon_bound(10, 10, 0.1) == 1.0
    with pytest.raises(ValueError):
        epsilon_bound(11, 10, 0.1)
    with pytest.raises(ValueError, match="validation seeds"):
        ScenarioSettings(samples=10000, dt=0.005, substeps=4, seed=3, betas=(1e-3,), conflict_radius=0.3)


def test_rollout_detects_a_certain_collision_and_a_clear_state():
    vhat, _ = tiny_models(torch.float64)
    spec = vhat.obs_spec
    obs = torch.zeros(2, spec.dim, dtype=torch.float64)   # [v_ego, g_ego, (p, v, g) of 2 neighbours]
    # row 0: neighbour 1 at 0.15 m closing at 4 m/s: contact within 0.02 s whatever the controls (r = 0.1 m)
    obs[0, 4:6], obs[0, 6:8] = torch.tensor([0.15, 0.0]), torch.tensor([-4.0, 0.0])
    # row 1: all three at rest at their goals, ≥ 2.69 m apart; 0.2 s of ±4 m/s² moves each ≤ 0.12 m
    obs[1, 4:6] = obs[1, 8:10] = torch.tensor([1.9, 1.9])
    obs[:, 10:12] = obs[:, 14:16] = torch.tensor([-1.9, 1.9])
    r = rollout(vhat, obs, torch.full((2,), vhat.z_max, dtype=torch.float64), dt=0.01, substeps=4)
    assert r["min_distance"][0] < spec.collision_radius < 2.4 < r["min_distance"][1]
    assert r["steps"] == round(vhat.horizon / 0.01)


def test_verify_reports_consistent_counts_and_cli(tmp_path):
    vhat, _ = tiny_models()
    s = ScenarioSettings(samples=50, dt=0.02, substeps=2, seed=100, betas=(1e-3,), conflict_radius=0.3)
    rep = verify(vhat, s, conflict=True)
    assert rep["samples"] == 50 and 0.0 < rep["acceptance_rate"] <= 1.0
    for key in ("safety", "budget"):
        assert rep[key]["violations"] <= rep["any"]["violations"] <= rep["safety"]["violations"] + rep["budget"]["violations"]
        assert rep[key]["rate"] <= rep[key]["epsilon"]["0.001"] <= 1.0
    assert verify(vhat, s, conflict=True) == rep                        # same seed, same numbers
    out = tmp_path / "scenario.json"
    assert main(["verify-vhat", "--config", *CONFIGS, "--model", f"vhat={tiny_model_dir() / 'vhat.pt'}",
                 "--out", str(out), "--no-track"]) == 0
    report = json.loads(out.read_text())
    assert report["uniform"]["samples"] == report["conflict"]["samples"] == 64
