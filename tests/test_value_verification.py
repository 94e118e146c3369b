"""Scenario-based verification of V̂ (issue 15) on a tiny trained model."""

import json

import pytest
import torch

from conftest import REPO, SMOKE
from madpinn.commands import main
from madpinn.commands.value_functions import deployed_z_tolerance
from madpinn.config import load_config, method_config
from madpinn.observation import build_observation
from madpinn.policies import policy_settings
from madpinn.policies.madpinn import MadPinnPolicy
from madpinn.policies.neighbours import make_selector
from madpinn.value_functions.sampling import ConflictSamplingSettings
from madpinn.value_functions.validation import heatmap_observations, heatmap_values
from madpinn.value_functions.verification import ScenarioSettings, draw_safe_states, epsilon_bound, rollout, verify
from madpinn.value_functions.z_search import ZGrid, cold_search, min_feasible_z
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
    rep = verify(vhat, s, True, 1e-3)
    assert rep["samples"] == 50 and 0.0 < rep["acceptance_rate"] <= 1.0
    for key in ("safety", "budget"):
        assert rep[key]["violations"] <= rep["any"]["violations"] <= rep["safety"]["violations"] + rep["budget"]["violations"]
        assert rep[key]["rate"] <= rep[key]["epsilon"]["0.001"] <= 1.0
    assert verify(vhat, s, True, 1e-3) == rep                        # same seed, same numbers
    out = tmp_path / "scenario.json"
    assert main(["verify-vhat", "--config", *CONFIGS, "--model", f"vhat={tiny_model_dir() / 'vhat.pt'}",
                 "--out", str(out), "--no-track"]) == 0
    report = json.loads(out.read_text())
    assert report["uniform"]["samples"] == report["conflict"]["samples"] == 64


def test_verification_and_heatmap_search_the_deployed_grid():
    """verify-vhat's and the heatmap's z* are the deployed policy's: the MAD-PINN policy built from
    the config (its first step is the cold search) and the verification's search (at the tolerance
    the command reads) give bitwise the same z* and feasibility on the same observations, feasible
    and infeasible rows alike; the verification's accepted budgets are cold-search answers."""
    from dataclasses import replace

    cfg = load_config([REPO / "config.yaml", SMOKE])
    vhat, vs = tiny_models()
    settings = replace(policy_settings(*method_config(cfg, "madpinn")), look_ahead=0.0)   # obs = build_observation
    tol = deployed_z_tolerance(cfg)
    assert tol == settings.z_tolerance
    pol = MadPinnPolicy(vhat, make_selector("nearest", 2, agent=vhat.obs_spec.agent), vhat.obs_spec, settings, sim_dt=0.0025)
    g = torch.Generator().manual_seed(5)
    state = torch.cat([2 * torch.rand(4, 6, 2, generator=g) - 1, 4 * torch.rand(4, 6, 2, generator=g) - 2], -1)
    goals = 2 * torch.rand(4, 6, 2, generator=g) - 1
    state[0, 1, 0:2] = state[0, 0, 0:2]   # a collision: V̂(z_max) > 0, the z_max fallback
    pol.reset(state, goals)
    pol.act(state, goals, 0.0)
    obs = build_observation(state, goals, pol.neighbours, vhat.obs_spec).reshape(24, -1)
    z, feasible = min_feasible_z(vhat, obs, tol)
    assert feasible.any() and (~feasible).any()
    assert torch.equal(z, pol.last_search.z) and torch.equal(feasible, pol.last_search.feasible)
    # the heatmap: the same search at the same tolerance
    _, hz, hf, _ = heatmap_values(vhat, tol, points=5)
    _, hobs = heatmap_observations(vhat.obs_spec, 1.0, 5)
    ref = cold_search(vhat, hobs, ZGrid.of(vhat.z_max, tol))
    assert torch.equal(hz.flatten(), ref.z) and torch.equal(hf.flatten(), ref.feasible)
    # the verification's draw: accepted states with their deployed cold-search budgets
    obs, zs, _ = draw_safe_states(vhat, 40, ConflictSamplingSettings(fraction=1.0, radius=0.3, tau=(0.0, 1.0), closing_speed=None),
                                  torch.Generator().manual_seed(101), 100_000, tol)
    ref = cold_search(vhat, obs, ZGrid.of(vhat.z_max, settings.z_tolerance))
    assert ref.feasible.all() and torch.equal(zs, ref.z)
