"""MPPI baseline: goal reaching, penalty effect, control box, determinism, input checks."""

from __future__ import annotations

import copy
from pathlib import Path

import pytest
import torch

from madpinn.config import ConfigError, load_config, method_config, validate_config
from madpinn.dynamics import DoubleIntegrator
from madpinn.observation import ObservationSettings
from madpinn.policies import PolicyContext, make_policy, policy_settings
from madpinn.policies.mppi import MPPIPlanner, MPPISettings, perturbation_cost, segment_distance
from madpinn.simulation import DoubleIntegratorBackend, run_episode

REPO = Path(__file__).resolve().parents[1]
SIM_DT = 0.0025
# Small but real settings: the same code path as config.yaml, cheaper per step.
FAST = {"samples": 48, "horizon": 8, "plan_dt": 0.1}


@pytest.fixture(scope="module")
def cfg() -> dict:
    return load_config([REPO / "config.yaml"])


def make(cfg, seed=0, period=2, **overrides):
    _, mcfg = method_config(cfg, "mppi")
    mcfg = {**mcfg, **FAST, **overrides}
    ctx = PolicyContext(
        method=policy_settings("mppi", mcfg), dynamics=DoubleIntegrator(u_max=4.0, v_max=4.0), obs_spec=ObservationSettings.from_config(cfg),
        device=torch.device("cpu"), dtype=torch.float32, seed=seed, sim_dt=SIM_DT, policy_period=period,
    )
    return make_policy("mppi", ctx)


def episode(cfg, starts, goals, seconds, period=2, **overrides):
    torch.set_num_threads(1)
    policy = make(cfg, period=period, **overrides)
    backend = DoubleIntegratorBackend(DoubleIntegrator(u_max=4.0, v_max=4.0), SIM_DT)
    steps = int(round(seconds / SIM_DT))
    result, _ = run_episode(backend, policy, torch.as_tensor(starts), torch.as_tensor(goals), steps,
                            cfg["agents"]["collision_radius"], policy_period=period, progress=False)
    return result


def test_single_agent_reaches_goal(cfg):
    result = episode(cfg, [[[-0.7, -0.5]]], [[[0.6, 0.7]]], seconds=2.5)
    assert result.final_distance[0, 0] < 0.05
    # far better than standing still (initial distance 1.77 m held for 2.5 s ≈ 6.2)
    assert result.cost[0, 0] < 2.0


def test_head_on_penalty_bends_paths(cfg):
    # 16 head-on encounters (the pair's axis turned by k·π/16) in one batch. Each encounter is a
    # chaotic draw (1e-6 m or another CPU's rounding changes its separation by centimetres), so the
    # test compares counts and means over the batch, without vs with a strong penalty, where the
    # difference is large. Seeds 0-6 (S=16): collisions 7-13 vs 0-1, mean separations 0.058-0.098 m
    # vs 0.178-0.194 m; a count bound of S/4 and a mean margin of r + margin/2 = 0.125 m hold by
    # several standard deviations.
    S = 16
    angle = torch.arange(S, dtype=torch.float64) * (torch.pi / S)
    d = (0.6 * torch.stack([angle.cos(), angle.sin()], dim=-1)).float()
    starts, goals = torch.stack([-d, d], dim=1), torch.stack([d, -d], dim=1)  # [S, 2, 2]
    r = cfg["agents"]["collision_radius"]
    margin = cfg["methods"]["mppi"]["margin"]
    fixed = {"lr": 0.0, "max": 1.0e4}  # fixed λ: isolate the penalty weight
    seps = {lam: episode(cfg, starts, goals, seconds=1.5, penalty_weight=lam, dual_ascent=fixed).min_separation.min(axis=1)
            for lam in (0.0, 1000.0)}
    collisions = {lam: int((sep < r).sum()) for lam, sep in seps.items()}
    assert collisions[0.0] >= S // 4  # without the penalty nothing keeps them apart
    assert collisions[1000.0] < S // 4
    assert seps[1000.0].mean() > r + 0.5 * margin
    assert seps[1000.0].mean() - seps[0.0].mean() > 0.5 * margin


def test_controls_always_in_box(cfg):
    torch.manual_seed(1)
    policy = make(cfg, noise_sigma=50.0, period=1)
    S, N = 3, 8
    state = torch.cat([torch.rand(S, N, 2) * 2 - 1, torch.rand(S, N, 2) * 8 - 4], dim=-1)
    goals = torch.rand(S, N, 2) * 2 - 1
    policy.reset(state, goals)
    for k in range(50):
        u = policy.act(state, goals, k * SIM_DT)
        assert u.shape == (S, N, 2)
        assert torch.isfinite(u).all()
        assert u.abs().max() <= 4.0
        assert policy.planner.U.abs().max() <= 4.0 + 1e-6
        state = DoubleIntegrator(u_max=4.0, v_max=4.0).step(state, u, SIM_DT)


def test_dual_ascent_raises_lambda_only_in_conflict(cfg):
    # scenario 0: two agents head-on; scenario 1: the same two agents far apart on parallel lanes
    starts = torch.tensor([[[-0.5, 0.0], [0.5, 0.0]], [[-0.5, -0.9], [-0.5, 0.9]]])
    goals = torch.tensor([[[0.5, 0.0], [-0.5, 0.0]], [[0.5, -0.9], [0.5, 0.9]]])
    policy = make(cfg, period=1, penalty_weight=10.0, dual_ascent={"lr": 1.0e6, "max": 500.0})
    state = torch.cat([starts, torch.zeros_like(starts)], dim=-1)
    policy.reset(state, goals)
    for k in range(80):
        state = DoubleIntegrator(u_max=4.0, v_max=4.0).step(state, policy.act(state, goals, k * SIM_DT), SIM_DT)
    lam = policy.planner.penalty.reshape(2, 2)
    assert torch.all(lam[0] > 10.0) and torch.all(lam[0] <= 500.0)
    assert torch.all(lam[1] == 10.0)


def _actions(cfg, seed, steps=30):
    policy = make(cfg, seed=seed, period=1)
    gen = torch.Generator().manual_seed(7)
    state = torch.cat([torch.rand(2, 6, 2, generator=gen) * 2 - 1, torch.zeros(2, 6, 2)], dim=-1)
    goals = torch.rand(2, 6, 2, generator=gen) * 2 - 1
    policy.reset(state, goals)
    out = []
    for k in range(steps):
        u = policy.act(state, goals, k * SIM_DT)
        out.append(u)
        state = DoubleIntegrator(u_max=4.0, v_max=4.0).step(state, u, SIM_DT)
    return torch.stack(out)


def test_deterministic_under_seed(cfg):
    a, b, c = _actions(cfg, 3), _actions(cfg, 3), _actions(cfg, 4)
    assert torch.equal(a, b)
    assert not torch.equal(a, c)


def test_warm_start_shifts_plan_by_knots(cfg):
    policy = make(cfg)
    planner = policy.planner
    planner.reset(2, torch.device("cpu"), torch.float32)
    planner.U = torch.arange(2 * 8 * 2, dtype=torch.float32).reshape(2, 8, 2)
    old = planner.U.clone()
    assert planner._advance_to(0.05) == pytest.approx(0.05)  # inside knot 0: no shift
    assert torch.equal(planner.U, old)
    assert planner._advance_to(0.25) == pytest.approx(0.05)  # knot 2: shift by two
    assert torch.equal(planner.U[:, :6], old[:, 2:]) and torch.all(planner.U[:, 6:] == 0)
    with pytest.raises(ValueError, match="before its current knot"):
        planner._advance_to(0.0)


def test_segment_distance_catches_crossings_between_knots():
    # first: crossing the origin between the knots; second: closest at the start point
    a = torch.tensor([[-1.0, 0.05], [0.3, 0.4]])
    b = torch.tensor([[1.0, 0.05], [0.6, 0.8]])
    d = segment_distance(a[:, 0], a[:, 1], b[:, 0], b[:, 1])
    torch.testing.assert_close(d, torch.tensor([0.05, 0.5]))


def test_bad_parameters_fail_early(cfg):
    bad = copy.deepcopy(cfg)
    bad["methods"]["mppi"]["temperature"] = -1.0
    with pytest.raises(ConfigError, match="temperature"):
        validate_config(bad)
    bad = copy.deepcopy(cfg)
    bad["methods"]["mppi"]["dual_ascent"] = {"lr": 1.0, "step": 2}
    with pytest.raises(ConfigError):
        validate_config(bad)
    with pytest.raises(ValueError, match="samples"):
        MPPISettings(samples=0, horizon=4, plan_dt=0.1, noise_sigma=1.0, temperature=0.1, penalty_weight=1.0, margin=0.0,
                      terminal_weight=1.0, dual_lr=0.0, penalty_max=1.0e4, penalty_check="segment", action_cost=False)
    with pytest.raises(ValueError, match="penalty_check"):
        MPPISettings(samples=4, horizon=4, plan_dt=0.1, noise_sigma=1.0, temperature=0.1, penalty_weight=1.0,
                     margin=0.0, terminal_weight=1.0, dual_lr=0.0, penalty_max=1.0e4, penalty_check="midpoint", action_cost=False)
    bad = copy.deepcopy(cfg)
    bad["methods"]["mppi"]["penalty_check"] = "midpoint"
    with pytest.raises(ConfigError, match="penalty_check"):
        validate_config(bad)


def _flyby_lambda(cfg, penalty_check: str) -> float:
    """λ after one dual-ascent plan of an ego at 4 m/s, 0.2 m head-on from a neighbour at −4 m/s.

    The pair closes at 8 m/s, so the first 0.1 s knot interval takes it straight through the
    neighbour while both knot positions stay ≥ 0.2 − 0.02 m apart (±4 m/s² moves either agent by
    ≤ 0.02 m in 0.1 s, and the relative speed stays > 0 over the 0.8 s horizon): every sample
    violates r + margin = 0.15 m on the segment and none at the knots.
    """
    _, mcfg = method_config(cfg, "mppi")
    params = policy_settings("mppi", {**mcfg, **FAST, "penalty_check": penalty_check, "penalty_weight": 10.0,
                                      "dual_ascent": {"lr": 1.0e6, "max": 1.0e4}})
    planner = MPPIPlanner(params, DoubleIntegrator(u_max=4.0, v_max=4.0), cfg["agents"]["collision_radius"],
                          torch.Generator().manual_seed(0))
    planner.reset(1, torch.device("cpu"), torch.float32)
    planner.plan(ego_vel=torch.tensor([[4.0, 0.0]]), goal=torch.tensor([[0.8, 0.0]]),
                 nbr_pos=torch.tensor([[[0.2, 0.0]]]), nbr_vel=torch.tensor([[[-4.0, 0.0]]]),
                 nbr_mask=torch.tensor([[True]]), t=0.0)
    return float(planner.penalty[0])


def test_knot_check_misses_a_crossing_that_the_segment_check_sees(cfg):
    assert _flyby_lambda(cfg, "knots") == 10.0  # no violation seen: λ stays at its floor
    # violation seen: ≈ 0.1 s · (0.15 − 0.02 m) per sample, so λ ≈ 10 + 1e6 · 0.013 (capped at 1e4)
    assert _flyby_lambda(cfg, "segment") >= 1.0e3


def test_perturbation_cost_is_pytorch_mppis():
    # pytorch_mppi (noise_abs_cost=False): lambda_ · Σ_t U_t · (ε_t @ Σ⁻¹), Σ = σ²·I here
    gen = torch.Generator().manual_seed(5)
    B, H, K, sigma, temperature = 3, 4, 6, 2.0, 0.3
    U = torch.randn(B, H, 2, generator=gen, dtype=torch.float64)
    V = torch.randn(H, B, K, 2, generator=gen, dtype=torch.float64)
    sigma_inv = torch.linalg.inv(sigma ** 2 * torch.eye(2, dtype=torch.float64))
    ref = torch.empty(B, K, dtype=torch.float64)
    for b in range(B):
        for k in range(K):
            eps = V[:, b, k] - U[b]                                   # [H, 2]
            ref[b, k] = temperature * torch.sum(U[b] * (eps @ sigma_inv))
    torch.testing.assert_close(perturbation_cost(U, V, temperature, sigma), ref)


@pytest.mark.parametrize("overrides", [{"penalty_check": "knots"}, {"action_cost": True, "terminal_weight": 0.0}])
def test_pytorch_mppi_style_options_still_reach_the_goal(cfg, overrides):
    result = episode(cfg, [[[-0.7, -0.5]]], [[[0.6, 0.7]]], seconds=2.5, **overrides)
    assert result.final_distance[0, 0] < 0.05
