import numpy as np
import pytest
import torch

from madpinn.evaluation.metrics import across_seeds, scenario_metrics, seed_summary
from madpinn.simulation.recorder import record_trajectory


def _straight_line_world():
    """2 scenarios x 3 agents, 11 samples (dt = 0.1 s); agent 0 moves at 1 m/s toward its goal."""
    K, dt = 10, 0.1
    t = torch.arange(K + 1, dtype=torch.float64) * dt
    pos = torch.zeros(K + 1, 2, 3, 2, dtype=torch.float64)
    pos[:, :, 0, 0] = t[:, None]  # agent 0 from x=0 to x=1
    pos[:, :, 1, 0] = 5.0  # agent 1 parked at x=5
    pos[:, :, 2, 0] = -5.0  # agent 2 parked at x=-5
    goals = torch.zeros(2, 3, 2, dtype=torch.float64)
    goals[:, 0, 0] = 1.0
    goals[:, 1, 0] = 5.0
    goals[:, 2, 0] = -5.0
    return pos, goals, dt


def test_cost_is_integral_plus_terminal():
    pos, goals, dt = _straight_line_world()
    res = record_trajectory(pos, goals, dt, collision_radius=0.1)
    # ∫0^1 (1 - t) dt = 0.5 (trapezoid is exact for linear), terminal distance 0
    np.testing.assert_allclose(res.cost[:, 0], 0.5, atol=1e-12)
    np.testing.assert_allclose(res.cost[:, 1:], 0.0, atol=1e-12)
    assert not res.collided.any()


def test_single_step_collision_counts_and_cost_over_safe_agents_only():
    pos, goals, dt = _straight_line_world()
    pos[4, 1, 1] = pos[4, 1, 0] + torch.tensor([0.1, 0.0], dtype=torch.float64)  # one step at d = r in scenario 1
    res = record_trajectory(pos, goals, dt, collision_radius=0.1)
    assert res.collided[1].tolist() == [True, True, False]
    assert res.first_collision_step[1].tolist() == [4, 4, -1]
    assert not res.collided[0].any()
    df = scenario_metrics(res)
    assert df["safety_rate"].tolist() == pytest.approx([1.0, 1 / 3])
    assert df["safe"].tolist() == [True, False]
    # scenario 1: only agent 2 is collision-free, and its cost is 0
    assert df["cost_safe_mean"].tolist() == pytest.approx([0.5 / 3, 0.0])
    s = seed_summary(df)
    assert s["safety_rate"] == pytest.approx((1 + 1 / 3) / 2)
    assert s["safe_scenarios"] == 0.5


def test_all_collided_scenario_has_no_cost_and_is_skipped_in_the_mean():
    pos, goals, dt = _straight_line_world()
    pos[:, 1, :, :] = 0.0  # everyone on top of each other in scenario 1
    df = scenario_metrics(record_trajectory(pos, goals, dt, 0.1))
    assert np.isnan(df["cost_safe_mean"][1])
    assert seed_summary(df)["cost"] == pytest.approx(0.5 / 3)


def test_mean_and_std_across_seeds():
    import pandas as pd

    per_seed = pd.DataFrame(
        {"run": ["a"] * 3, "n_agents": [3] * 3, "safety_rate": [1.0, 0.9, 0.8], "safe_scenarios": [1.0, 1.0, 0.7], "cost": [1.0, 2.0, 3.0]}
    )
    agg = across_seeds(per_seed, ["run", "n_agents"]).iloc[0]
    assert agg["safety_rate_mean"] == pytest.approx(0.9)
    assert agg["safety_rate_std"] == pytest.approx(0.1)
    assert agg["cost_std"] == pytest.approx(1.0)
    assert agg["n_seeds"] == 3


def test_time_averaged_and_all_agent_costs():
    """T = 10 steps × 0.1 s = 1 s here, so ÷T must equal the integral; the all-agent variant
    keeps the collided agents that the paper's (collision-free) cost drops."""
    pos, goals, dt = _straight_line_world()
    pos[4, 1, 1] = pos[4, 1, 0] + torch.tensor([0.1, 0.0], dtype=torch.float64)   # agents 0, 1 collide in scenario 1
    df = scenario_metrics(record_trajectory(pos, goals, dt, collision_radius=0.1))
    assert df["episode_s"].tolist() == pytest.approx([1.0, 1.0])
    assert df["cost_safe_time_avg"].tolist() == pytest.approx(df["cost_safe_mean"].tolist())
    assert df["cost_all_mean"][1] > df["cost_safe_mean"][1] + 0.1   # agent 0 (cost ≈ 0.5) counted
    s = seed_summary(df)
    assert s["cost_time_avg"] == pytest.approx(s["cost"])
    assert s["cost_all"] > s["cost"]


def test_time_average_divides_by_the_episode_length():
    pos, goals, _ = _straight_line_world()
    df = scenario_metrics(record_trajectory(pos, goals, 0.3, collision_radius=0.1))   # T = 3 s
    assert df["cost_safe_time_avg"].to_numpy() == pytest.approx(df["cost_safe_mean"].to_numpy() / 3.0)


def test_old_result_rows_without_time_averaged_columns_still_summarise():
    pos, goals, dt = _straight_line_world()
    df = scenario_metrics(record_trajectory(pos, goals, dt, 0.1)).drop(columns=["cost_safe_time_avg", "cost_all_time_avg", "episode_s"])
    s = seed_summary(df)
    assert s["cost"] == pytest.approx(0.5 / 3) and np.isnan(s["cost_time_avg"])


def test_bootstrap_interval_brackets_the_mean_shrinks_with_scenarios_and_is_repeatable():
    from madpinn.evaluation.metrics import bootstrap_interval

    assert bootstrap_interval(np.full(20, 0.75)) == (0.75, 0.75)            # no spread, no interval
    rng = np.random.default_rng(5)
    few, many = rng.uniform(0.6, 1.0, 20), rng.uniform(0.6, 1.0, 2000)
    lo, hi = bootstrap_interval(few)
    assert lo < few.mean() < hi and hi <= 1.0 and lo >= 0.6
    lo2, hi2 = bootstrap_interval(many)
    assert (hi2 - lo2) < 0.5 * (hi - lo)                                     # ~1/sqrt(100) as wide
    assert bootstrap_interval(few) == (lo, hi)
    with_nan = np.concatenate([few, [np.nan] * 5])                            # all-collided scenarios: no cost
    assert bootstrap_interval(with_nan)[0] >= 0.6 and bootstrap_interval(with_nan)[1] <= 1.0
    assert np.isnan(bootstrap_interval(np.array([np.nan, np.nan]))[0])


def test_single_seed_tables_show_bootstrap_intervals_and_multi_seed_tables_the_std():
    import pandas as pd

    from madpinn.evaluation.tables import format_table, per_seed

    rng = np.random.default_rng(1)
    rows = pd.DataFrame({"run": "madpinn", "n_agents": 64, "seed": 100, "scenario": range(20),
                         "safety_rate": rng.uniform(0.8, 1.0, 20), "safe": rng.uniform(size=20) < 0.5,
                         "cost_safe_time_avg": rng.uniform(1.0, 1.5, 20), "cost_safe_mean": 1.0})
    one = across_seeds(per_seed(rows), ["run", "n_agents"]).assign(label="MAD-PINN")
    cell = format_table(one, "summary")["Safety Rate"].iloc[0]
    lo, hi = one.iloc[0]["safety_rate_ci_lo"], one.iloc[0]["safety_rate_ci_hi"]
    assert cell == f"{100 * rows.safety_rate.mean():.1f}% [{100 * lo:.1f}, {100 * hi:.1f}]" and lo < hi
    two = pd.concat([rows, rows.assign(seed=101)])
    agg = across_seeds(per_seed(two), ["run", "n_agents"]).assign(label="MAD-PINN")
    assert "±" in format_table(agg, "summary")["Safety Rate"].iloc[0] and np.isnan(agg.iloc[0]["safety_rate_ci_lo"])


def _passing_pair(offset_y: float):
    """1 scenario x 2 agents meeting head-on at 1 m/s each (dt = 0.1 s, 21 samples), lateral offset ``offset_y`` (m)."""
    K, dt = 20, 0.1
    t = torch.arange(K + 1, dtype=torch.float64) * dt
    pos = torch.zeros(K + 1, 1, 2, 2, dtype=torch.float64)
    pos[:, 0, 0, 0] = -1.0 + t
    pos[:, 0, 1, 0] = 1.0 - t
    pos[:, 0, 1, 1] = offset_y
    vel = torch.zeros_like(pos)
    vel[:, 0, 0, 0], vel[:, 0, 1, 0] = 1.0, -1.0
    goals = pos[-1].clone()
    return pos, vel, goals, dt


def test_encounter_speed_is_the_relative_speed_at_the_closest_approach_or_first_collision():
    for offset, collides in ((0.5, False), (0.05, True)):
        pos, vel, goals, dt = _passing_pair(offset)
        res = record_trajectory(pos, goals, dt, collision_radius=0.1, velocities=vel)
        assert res.collided.all() == collides
        np.testing.assert_allclose(res.encounter_speed, 2.0, atol=1e-12)   # head-on at 1 m/s each
        assert scenario_metrics(res)["encounter_speed_mean"].iloc[0] == pytest.approx(2.0)
    res = record_trajectory(pos, goals, dt, collision_radius=0.1)   # no velocities: not measured
    assert np.isnan(res.encounter_speed).all()


def test_cost_and_safety_at_an_earlier_horizon_equal_the_cut_episode():
    pos, vel, goals, dt = _passing_pair(0.05)   # the pair collides at t = 1 s (step 10)
    full = record_trajectory(pos, goals, dt, collision_radius=0.1, velocities=vel, horizon_steps=(5, 15))
    for k in (5, 15):
        cut = record_trajectory(pos[: k + 1], goals, dt, collision_radius=0.1)
        np.testing.assert_allclose(full.cost_at[k], cut.cost, rtol=0, atol=1e-12)
    row = scenario_metrics(full).iloc[0]
    assert row["safety_rate_at_0.5s"] == 1.0 and row["safety_rate_at_1.5s"] == 0.0 and row["safety_rate"] == 0.0
    summary = seed_summary(scenario_metrics(full))
    assert summary["safe_scenarios_at_0.5s"] == 1.0 and summary["safe_scenarios_at_1.5s"] == 0.0
    assert summary["cost_all_time_avg_at_0.5s"] == pytest.approx(float(full.cost_at[5].mean()) / 0.5)
