"""The oracle cost lower bound (madpinn/evaluation/oracle.py) against exact cases and against
simulated controllers on the same scenarios: no trajectory of the double integrator can cost
less than the bound (drones do not touch, so each agent's trajectory is a lone agent's)."""

import numpy as np
import pytest
import torch

from madpinn.dynamics import DoubleIntegrator
from madpinn.evaluation.oracle import OracleSettings, lower_bound, scenario_bounds, upper_bound
from madpinn.policies.nominal import NominalPD
from madpinn.scenarios import Arena, generate_scenarios
from madpinn.simulation import DoubleIntegratorBackend, run_episode

SIM_DT = 0.0025


class BangBang:
    """Per-axis time-optimal switching law u = −u_max·sign(x + v|v|/(2u_max)), x = p − g."""

    def __init__(self, u_max=4.0):
        self.u_max = u_max

    def reset(self, state, goals):
        pass

    def act(self, state, goals, t):
        x, v = state[..., 0:2] - goals, state[..., 2:4]
        s = x + v * v.abs() / (2 * self.u_max)
        return -self.u_max * torch.sign(s)


def test_goal_at_start_costs_zero():
    s = OracleSettings(horizon_s=1.0, u_max=4.0, v_max=4.0, dt=0.05)
    assert lower_bound(np.zeros((2, 2)), s) == pytest.approx([0.0, 0.0], abs=1e-6)
    assert upper_bound(np.zeros((1, 2)), s)[0] == pytest.approx(0.0, abs=1e-6)


def test_one_metre_trip_is_sandwiched_around_the_bang_bang_cost():
    """1 m along x, T = 3 s: accelerating 0.5 s and braking 0.5 s costs ∫ = 0.5 exactly (peak
    speed 2 m/s, the velocity box is inactive). The bound must not exceed any attainable cost,
    and the feasible programme must come within its gap."""
    s = OracleSettings(horizon_s=3.0, u_max=4.0, v_max=4.0, dt=0.025)
    lb, ub = lower_bound(np.array([[1.0, 0.0]]), s)[0], upper_bound(np.array([[1.0, 0.0]]), s)[0]
    assert lb <= 0.5 + 1e-6
    assert lb <= ub <= lb + 0.02
    assert lb > 0.47


def test_bound_is_invariant_under_axis_reflections_and_swaps():
    s = OracleSettings(horizon_s=1.0, u_max=4.0, v_max=4.0, dt=0.05)
    lb = lower_bound(np.array([[0.6, -0.3], [-0.6, 0.3], [0.3, 0.6]]), s)
    assert np.ptp(lb) < 1e-5


def test_bad_settings_fail_early():
    with pytest.raises(ValueError, match="divide"):
        OracleSettings(horizon_s=1.0, u_max=4.0, v_max=4.0, dt=0.3)
    with pytest.raises(ValueError, match="positive"):
        OracleSettings(horizon_s=1.0, u_max=4.0, v_max=4.0, dt=-0.1)
    with pytest.raises(ValueError, match="finite"):
        lower_bound(np.array([[np.nan, 0.0]]), OracleSettings(horizon_s=1.0, u_max=4.0, v_max=4.0, dt=0.1))


def _simulate(policy, arena, n, count, seed=0):
    starts, goals = generate_scenarios(arena, n, seed, count, 0.2, dtype=torch.float64)
    steps = int(round(arena.episode_s / SIM_DT))
    res, _ = run_episode(DoubleIntegratorBackend(DoubleIntegrator(u_max=4.0, v_max=4.0), SIM_DT), policy, starts, goals, steps, 0.1, progress=False)
    return (starts - goals).numpy(), res.cost


@pytest.mark.parametrize("name", ["nominal", "bang_bang"])
def test_bound_below_simulated_controllers_per_agent(name):
    arena = Arena("small", 1.0, 1.0)
    policy = NominalPD(DoubleIntegrator(u_max=4.0, v_max=4.0), 6.0, 4.9) if name == "nominal" else BangBang()
    offsets, cost = _simulate(policy, arena, n=4, count=3)
    lb = lower_bound(offsets.reshape(-1, 2), OracleSettings(horizon_s=arena.episode_s, u_max=4.0, v_max=4.0, dt=0.025)).reshape(cost.shape)
    assert (lb <= cost + 1e-4).all()          # simulator: trapezoid over 2.5 ms steps
    if name == "bang_bang":                   # near time-optimal: within a few % of the bound
        assert cost.mean() < 1.1 * lb.mean()


def test_scenario_bounds_match_the_scenarios_and_lie_below_mad_pinn(tmp_path):
    """Smoke-scale MAD-PINN (tiny trained V̂, V_s) on the double integrator: its per-scenario mean
    cost over all agents is ≥ the scenario's oracle bound."""
    from madpinn.commands.evaluate import evaluate
    from test_madpinn_policy import models_of, tiny_cfg

    cfg = tiny_cfg(tmp_path)
    cfg["arenas"]["small"]["episode_s"] = 0.5
    cfg["sim"]["backend"] = "double_integrator"
    cfg["studies"]["main"].update(agent_counts=[3], seeds=[0], scenarios=2)
    evaluate(cfg, "main", "madpinn", 3, 0, tmp_path / "m.parquet", models=models_of(cfg), progress=False, track=False)
    import pandas as pd

    df = pd.read_parquet(tmp_path / "m.parquet")
    arena = Arena.from_config(cfg, "small")
    ob = scenario_bounds(arena, 3, 0, 2, 0.1, OracleSettings(horizon_s=0.5, u_max=4.0, v_max=4.0, dt=0.025))
    assert ob["scenario"].tolist() == [0, 1]
    assert (ob["oracle_cost"].to_numpy() <= df["cost_all_mean"].to_numpy() + 1e-4).all()
    assert ob["oracle_cost_time_avg"].to_numpy() == pytest.approx(ob["oracle_cost"].to_numpy() / 0.5)


def test_conflict_pattern_bounds_are_those_of_the_pattern_scenarios():
    """A structured-conflict study's bound is computed on its own scenarios (madpinn/conflicts.py),
    not on the uniform ones of the same (arena, N, seed)."""
    from madpinn.scenarios import generate_scenario

    arena = Arena("small", 1.0, 0.5)
    s = OracleSettings(horizon_s=0.5, u_max=4.0, v_max=4.0, dt=0.025)
    ob = scenario_bounds(arena, 4, 0, 2, 0.1, s, pattern="circle_swap")
    assert set(ob["pattern"]) == {"circle_swap"}
    starts, goals = generate_scenario(arena, 4, 0, 1, 0.2, "circle_swap")
    assert ob["oracle_cost"].iloc[1] == pytest.approx(lower_bound(starts - goals, s).mean())
    uniform = scenario_bounds(arena, 4, 0, 2, 0.1, s)
    assert set(uniform["pattern"]) == {"uniform"} and not np.allclose(uniform["oracle_cost"], ob["oracle_cost"])
