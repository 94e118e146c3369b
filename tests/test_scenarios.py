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
        starts, goals = generate_scenario(arena, n, seed=3, index=index, collision_radius=0.1)
        assert starts.shape == goals.shape == (n, 2)
        assert _min_sep(starts) >= 0.2 and _min_sep(goals) >= 0.2
        assert np.abs(starts).max() <= arena.half_width and np.abs(goals).max() <= arena.half_width


def test_pure_function_of_arena_n_seed_index():
    a = generate_scenario(SMALL, 8, seed=1, index=4, collision_radius=0.1)
    b = generate_scenario(SMALL, 8, seed=1, index=4, collision_radius=0.1)
    np.testing.assert_array_equal(a[0], b[0])
    np.testing.assert_array_equal(a[1], b[1])
    for other in [(SMALL, 8, 2, 4), (SMALL, 8, 1, 5), (SMALL, 12, 1, 4), (Arena("large", 1.0, 3.0), 8, 1, 4)]:
        c = generate_scenario(other[0], other[1], seed=other[2], index=other[3], collision_radius=0.1)
        assert not np.array_equal(a[0][: min(8, other[1])], c[0][: min(8, other[1])])


def test_batches_equal_single_scenarios():
    starts, goals = generate_scenarios(SMALL, 12, seed=0, count=3, collision_radius=0.1, first_index=5)
    assert starts.shape == (3, 12, 2) and starts.dtype == torch.float32
    single = generate_scenario(SMALL, 12, seed=0, index=6, collision_radius=0.1)
    np.testing.assert_allclose(starts[1].numpy(), single[0], atol=1e-6)
    np.testing.assert_allclose(goals[1].numpy(), single[1], atol=1e-6)


def test_infeasible_request_fails_fast_with_clear_message():
    # the up-front coverage check names the limit instead of sampling forever
    with pytest.raises(ScenarioInfeasibleError, match=r"cannot place 200 agents.*at most \d+ agents"):
        generate_scenario(SMALL, 200, seed=0, index=0, collision_radius=0.1)
    with pytest.raises(ScenarioInfeasibleError):
        generate_scenario(SMALL, 0, seed=0, index=0, collision_radius=0.1)
