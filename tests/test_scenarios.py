import numpy as np
import pytest
import torch

from madpinn.scenarios import Arena, ScenarioInfeasibleError, generate_scenario, generate_scenarios

SMALL = Arena("small", 1.0, 3.0)
LARGE = Arena("large", 4.0, 6.0)


def _min_sep(p):
    d = np.linalg.norm(p[:, None] - p[None], axis=-1)
    np.fill_diagonal(d, np.inf)
    return d.min()


@pytest.mark.parametrize("arena,n", [(SMALL, 16), (LARGE, 256)])
def test_separation_and_bounds(arena, n):
    for index in range(3):
        starts, goals = generate_scenario(arena, n, seed=3, index=index, min_separation=0.2)
        assert starts.shape == goals.shape == (n, 2)
        assert _min_sep(starts) >= 0.2 and _min_sep(goals) >= 0.2
        assert np.abs(starts).max() <= arena.half_width and np.abs(goals).max() <= arena.half_width


def test_pure_function_of_arena_n_seed_index():
    a = generate_scenario(SMALL, 8, seed=1, index=4, min_separation=0.2)
    b = generate_scenario(SMALL, 8, seed=1, index=4, min_separation=0.2)
    np.testing.assert_array_equal(a[0], b[0])
    np.testing.assert_array_equal(a[1], b[1])
    for other in [(SMALL, 8, 2, 4), (SMALL, 8, 1, 5), (SMALL, 12, 1, 4), (Arena("large", 1.0, 3.0), 8, 1, 4)]:
        c = generate_scenario(other[0], other[1], seed=other[2], index=other[3], min_separation=0.2)
        assert not np.array_equal(a[0][: min(8, other[1])], c[0][: min(8, other[1])])


def test_batches_equal_single_scenarios():
    starts, goals = generate_scenarios(SMALL, 12, seed=0, count=3, min_separation=0.2, first_index=5)
    assert starts.shape == (3, 12, 2) and starts.dtype == torch.float32
    single = generate_scenario(SMALL, 12, seed=0, index=6, min_separation=0.2)
    np.testing.assert_allclose(starts[1].numpy(), single[0], atol=1e-6)
    np.testing.assert_allclose(goals[1].numpy(), single[1], atol=1e-6)


def test_infeasible_request_fails_fast_with_clear_message():
    # the up-front coverage check names the limit instead of sampling forever
    with pytest.raises(ScenarioInfeasibleError, match=r"cannot place 200 agents.*at most \d+ agents"):
        generate_scenario(SMALL, 200, seed=0, index=0, min_separation=0.2)
    with pytest.raises(ScenarioInfeasibleError):
        generate_scenario(SMALL, 0, seed=0, index=0, min_separation=0.2)


# --- structured conflicts (madpinn/conflicts.py) ---

from madpinn.conflicts import JITTER, PATTERNS  # noqa: E402


def _match(a, b, tol):
    """For every row of a, the index of the row of b within tol (m), or -1."""
    d = np.linalg.norm(a[:, None] - b[None], axis=-1)
    return np.where(d.min(1) <= tol, d.argmin(1), -1)


@pytest.mark.parametrize("pattern", PATTERNS)
@pytest.mark.parametrize("n", [3, 8, 16])
def test_conflict_patterns_are_separated_inside_the_arena_and_reproducible(pattern, n):
    for index in range(5):
        starts, goals = generate_scenario(SMALL, n, seed=0, index=index, min_separation=0.2, pattern=pattern)
        assert starts.shape == goals.shape == (n, 2)
        assert _min_sep(starts) >= 0.2 and _min_sep(goals) >= 0.2
        assert np.abs(starts).max() <= SMALL.half_width and np.abs(goals).max() <= SMALL.half_width
        again = generate_scenario(SMALL, n, seed=0, index=index, min_separation=0.2, pattern=pattern)
        np.testing.assert_array_equal(starts, again[0])
    other = generate_scenario(SMALL, n, seed=0, index=1, min_separation=0.2, pattern=pattern)[0]
    assert not np.allclose(starts, other)   # index 4 vs 1: another rotation / placement


@pytest.mark.parametrize("pattern", ["head_on_pairs", "head_on_lines"])
def test_head_on_patterns_swap_partners(pattern):
    """Every agent's goal is its partner's start and the partner's goal its start (up to the jitter)."""
    tol = 2 * np.sqrt(2) * JITTER * SMALL.half_width + 1e-9
    for index in range(5):
        starts, goals = generate_scenario(SMALL, 8, seed=2, index=index, min_separation=0.2, pattern=pattern)
        partner = _match(goals, starts, tol)
        assert (partner >= 0).all() and (partner != np.arange(8)).all()
        np.testing.assert_array_equal(partner[partner], np.arange(8))


def test_circle_swap_converges_on_the_centre_and_crossing_flows_cross_at_right_angles():
    starts, goals = generate_scenario(SMALL, 16, seed=0, index=0, min_separation=0.2, pattern="circle_swap")
    mid = (starts + goals) / 2                         # the straight paths all pass (near) the centre at mid-trip
    assert np.abs(mid).max() <= 2 * JITTER * SMALL.half_width
    starts, goals = generate_scenario(SMALL, 16, seed=0, index=0, min_separation=0.2, pattern="crossing_flows")
    heading = (goals - starts) / np.linalg.norm(goals - starts, axis=1, keepdims=True)
    cos = heading @ heading[0]
    assert (np.abs(np.abs(cos) - 1) < 0.1).sum() == 8 and (np.abs(cos) < 0.1).sum() == 8   # two perpendicular streams


def test_uniform_scenarios_do_not_depend_on_the_conflict_patterns():
    a = generate_scenario(SMALL, 8, seed=1, index=4, min_separation=0.2)
    b = generate_scenario(SMALL, 8, seed=1, index=4, min_separation=0.2, pattern="uniform")
    np.testing.assert_array_equal(a[0], b[0])
    c = generate_scenario(SMALL, 8, seed=1, index=4, min_separation=0.2, pattern="circle_swap")
    assert not np.allclose(a[0], c[0])


def test_too_dense_pattern_fails_with_a_clear_message():
    with pytest.raises(ScenarioInfeasibleError, match="head_on_lines.*apart"):
        generate_scenario(LARGE, 128, seed=0, index=0, min_separation=0.2, pattern="head_on_lines")


# --- issue 60: a local goal law and the layout's straight-line encounters ------------------------------------------

def test_local_goals_keep_the_uniform_starts_and_lie_within_r_inside_the_arena():
    from madpinn.scenarios import Arena, generate_scenario, local_goal_radius

    arena = Arena("large", 4.0, 6.0)
    assert local_goal_radius("goals_within_2m") == 2.0 and local_goal_radius("uniform") is None
    assert local_goal_radius("goals_within_0m") is None and local_goal_radius("head_on_pairs") is None
    for radius in (1, 2, 4):
        for index in range(3):
            starts, goals = generate_scenario(arena, 128, 100, index, 0.2, f"goals_within_{radius}m")
            uniform_starts, uniform_goals = generate_scenario(arena, 128, 100, index, 0.2)
            assert np.array_equal(starts, uniform_starts) and not np.array_equal(goals, uniform_goals)
            assert np.all(np.linalg.norm(goals - starts, axis=1) <= radius + 1e-12)
            assert np.all(np.abs(goals) <= arena.half_width)
            gap = np.linalg.norm(goals[:, None] - goals[None], axis=-1) + np.eye(len(goals)) * 1e9
            assert gap.min() >= 0.2
            again = generate_scenario(arena, 128, 100, index, 0.2, f"goals_within_{radius}m")
            assert np.array_equal(again[1], goals)


def test_local_goal_laws_are_accepted_by_the_schema_and_bad_ones_refused():
    import copy

    from conftest import REPO
    from madpinn.config import ConfigError, load_config, validate_config

    cfg = load_config([REPO / "config.yaml"])
    ok = copy.deepcopy(cfg)
    ok["studies"]["scaling"]["pattern"] = "goals_within_2m"
    validate_config(ok)
    for bad in ("goals_within_0m", "goals_within_2.5m", "goals_near"):
        broken = copy.deepcopy(cfg)
        broken["studies"]["scaling"]["pattern"] = bad
        with pytest.raises(ConfigError):
            validate_config(broken)


def test_straight_line_encounters_count_crossing_paths_only():
    from madpinn.encounters import straight_line_encounters

    # 0 and 1 swap head-on along y = 0; 2 flies parallel 1 m away; 3 stays at its goal on 0/1's line, past 1's end
    starts = np.array([[-1.0, 0.0], [1.0, 0.0], [-1.0, 1.0], [3.0, 0.0]])
    goals = np.array([[1.0, 0.0], [-1.0, 0.0], [1.0, 1.0], [3.0, 0.0]])
    count = straight_line_encounters(starts, goals, speed=1.0, radius=0.2, horizon=3.0)
    assert count.tolist() == [1, 1, 0, 0]
    assert straight_line_encounters(starts, goals, speed=1.0, radius=1.01, horizon=3.0).tolist() == [2, 2, 2, 0]
