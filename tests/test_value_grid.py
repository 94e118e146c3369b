"""Grid reference of V_s (hj_reachability) and its comparison with the PINN (issue 15)."""

import json

import numpy as np
import pytest

from conftest import REPO, SMOKE
from madpinn.commands import main
from madpinn.dynamics.pair import PairSystem
from madpinn.value_functions.grid_reference import (
    GridSettings, compare_values, convergence, load_solution, solve_pair_grid,
)
from policy_models import tiny_model_dir
from settings_helpers import pair_system

CONFIGS = [str(REPO / "config.yaml"), str(SMOKE)]


@pytest.fixture(scope="module")
def grids():
    system = pair_system()
    fine = solve_pair_grid(system, 9, 1.0, 6.0, (0.0, 0.5), accuracy="low")
    coarse = solve_pair_grid(system, 5, 1.0, 6.0, (0.0, 0.5), accuracy="low")
    return system, fine, coarse


def _at(sol, ti, p, v):
    idx = [int(np.argmin(np.abs(sol.p_axis - c))) for c in p] + [int(np.argmin(np.abs(sol.v_axis - c))) for c in v]
    assert np.allclose([sol.p_axis[idx[0]], sol.p_axis[idx[1]], sol.v_axis[idx[2]], sol.v_axis[idx[3]]], [*p, *v])
    return float(sol.values[ti][tuple(idx)])


def test_grid_solution_obeys_the_physics_of_the_pair_problem(grids):
    system, fine, _ = grids
    psi = np.linalg.norm(fine.states()[..., :2], axis=-1) - system.collision_radius
    assert fine.times == (0.0, 0.5)
    assert np.all(fine.values <= psi[None] + 1e-6)                    # min with ψ of the VI
    # a longer time-to-go can only lower the min over time (t = 0 has 1 s left, t = 0.5 has 0.5 s)
    assert np.all(fine.values[0] <= fine.values[1] + 0.05)
    # moving apart at 3 m/s from 0.5 m: the minimum of ψ is now, V = ψ = 0.4 m
    assert abs(_at(fine, 0, (0.5, 0.0), (3.0, 0.0)) - 0.4) < 0.05
    # head-on at 6 m/s from 0.5 m: contact in 0.083 s, a lateral swerve of ½·8·0.083² = 0.03 m < r cannot avoid it
    assert _at(fine, 0, (0.5, 0.0), (-6.0, 0.0)) < 0.0


def test_convergence_and_metrics_on_nested_grids(grids):
    _, fine, coarse = grids
    conv = convergence(fine, coarse, 0.5, 3.0)
    assert set(conv) == {"0", "0.5"}
    for m in conv.values():
        assert 0.0 <= m["mae"] <= m["max_error"] and 0.0 <= m["sign_agreement"] <= 1.0
    same = compare_values(fine.values[0], fine.values[0])
    assert same["mae"] == 0.0 and same["sign_agreement"] == 1.0 and same["unsafe_called_safe"] == 0.0
    shifted = compare_values(fine.values[0], fine.values[0] + 10.0)    # everything called safe
    assert shifted["unsafe_called_safe"] == 1.0 and shifted["safe_called_unsafe"] == 0.0
    with pytest.raises(ValueError, match="odd"):
        GridSettings(nodes=8, p_range=1.0, v_range=6.0, interior_p=0.6, interior_v=3.0, times=(0.0,), accuracy="low")
    with pytest.raises(ValueError, match="interior"):
        GridSettings(nodes=9, p_range=1.0, v_range=6.0, interior_p=2.0, interior_v=3.0, times=(0.0,), accuracy="low")


def test_cli_solve_and_validate_vs_grid(tmp_path):
    grid = tmp_path / "grid.npz"
    assert main(["solve-vs-grid", "--config", *CONFIGS, "--out", str(grid), "--no-track", "--no-progress"]) == 0
    sol, header = load_solution(grid)
    assert sol.values.shape == (2, 9, 9, 9, 9) and header["coarse_nodes"] == 5
    assert set(header["convergence"]) == {"0", "0.5"}
    model = tiny_model_dir() / "vs.pt"
    out = tmp_path / "vs_grid.json"
    assert main(["validate-vs-grid", "--config", *CONFIGS, "--model", f"vs={model}", "--grid", str(grid),
                 "--out", str(out), "--fig-stem", str(tmp_path / "fig"), "--no-track"]) == 0
    report = json.loads(out.read_text())
    assert set(report["vs_vs_grid"]) == {"0", "0.5"} and isinstance(report["meets_target"], bool)
    for m in report["vs_vs_grid"].values():
        assert m["states"] == report["grid"]["interior_nodes"] > 0 and 0.0 <= m["unsafe_called_safe"] <= 1.0
    assert (tmp_path / "fig.png").stat().st_size > 1000
