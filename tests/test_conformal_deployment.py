"""Issue 62: deploying a calibrated level in the MAD-PINN policy. A level of 0 is today's policy bit
for bit; a positive level makes every agent feasible at δ = 0 or less often; the binned ranking
ranks an uncertified bin's partners first; a report of another V̂ or without the setting fails early."""

import json

import numpy as np

import pytest
import torch

from madpinn.dynamics import DoubleIntegrator
from madpinn.policies import make_policy
from madpinn.policies.leveled_neighbours import leveled_value_selector, pair_closing_speed
from madpinn.policies.neighbours import in_domain
from madpinn.simulation import make_backend, run_episode
from madpinn.simulation.settings import SimSettings
from madpinn.settings import AgentSettings
from madpinn.value_functions.safety_level import SafetyLevel
from policy_models import tiny_models
from test_madpinn_policy import context, scenario, tiny_cfg

EDGES = (1.0,)


def _report(path, vhat, pooled: float | None, binned: tuple, eps=0.1, beta=1e-3):
    """A calibration report in calibrate-vhat's layout with the given levels (a test input)."""
    row = lambda b, d: {"epsilon": eps, "beta": beta, "bin": b, "bin_label": str(b), "delta": d}
    block = {"speed_edges": list(EDGES), "pooled": [row(0, pooled)], "binned": [row(b, d) for b, d in enumerate(binned)]}
    path.write_text(json.dumps({"model_config_hash": vhat.meta.get("config_hash"), "distributions": {"conflict": block}}))
    return path


def _variant(cfg, binned: bool, eps=0.1):
    cfg["methods"]["madpinn"]["variants"]["cp"] = {"label": "cp", "conformal": {"distribution": "conflict", "epsilon": eps,
                                                                                "beta": 1e-3, "binned": binned}}


def _episode(cfg, run, report, state, goals):
    method, ctx = context(cfg, run)
    if report is not None:
        ctx.models["calibration"] = report
    pol = make_policy(method, ctx)
    backend = make_backend("double_integrator", SimSettings.from_config(cfg), AgentSettings.from_config(cfg), ctx.device, ctx.dtype)
    res, _ = run_episode(backend, pol, state[..., 0:2], goals, 30, 0.1, progress=False)
    return res, pol


@pytest.mark.parametrize("binned", [False, True])
def test_level_zero_is_todays_policy_bit_for_bit(tmp_path, binned):
    cfg = tiny_cfg(tmp_path)
    vhat, _ = tiny_models()
    _variant(cfg, binned)
    report = _report(tmp_path / "cal.json", vhat, 0.0, (0.0, 0.0))
    state, goals = scenario(S=2, N=6, seed=4)
    plain, _ = _episode(cfg, "madpinn", None, state, goals)
    leveled, pol = _episode(cfg, "madpinn-cp", report, state, goals)
    assert pol.vhat is not None and type(pol.vhat).__name__ != "LeveledVHat"
    assert np.array_equal(plain.cost, leveled.cost) and np.array_equal(plain.min_separation, leveled.min_separation)
    assert np.array_equal(plain.positions, leveled.positions)


@pytest.mark.parametrize("binned", [False, True])
def test_positive_level_accepts_fewer_agents(tmp_path, binned):
    """From the same first state, every agent feasible at δ > 0 is feasible at δ = 0 (first step)."""
    cfg = tiny_cfg(tmp_path)
    vhat, _ = tiny_models()
    _variant(cfg, binned)
    report = _report(tmp_path / "cal.json", vhat, 0.1, (0.05, float("inf")) if not binned else (0.05, 0.2))
    state, goals = scenario(S=2, N=6, seed=4)
    method, ctx = context(cfg, "madpinn")
    plain = make_policy(method, ctx)
    method, ctx = context(cfg, "madpinn-cp")
    ctx.models["calibration"] = report
    leveled = make_policy(method, ctx)
    for pol in (plain, leveled):
        pol.reset(state, goals)
        pol.act(state, goals, 0.0)
    assert type(leveled.vhat).__name__ == "LeveledVHat"
    assert bool((leveled.last_search.feasible <= plain.last_search.feasible).all())
    assert leveled.stats["infeasible"] >= plain.stats["infeasible"]


def test_binned_ranking_puts_an_uncertified_bins_partners_first():
    """δ = (0, +∞) for closing speeds (< 1, ≥ 1 m/s): for every ego, the selected partners that are
    sensed and in V_s's domain include all of those closing at ≥ 1 m/s (up to n) before any slower one."""
    _, vs = tiny_models()
    n = 2
    g = torch.Generator().manual_seed(7)
    state = torch.cat([1.6 * torch.rand(3, 8, 2, generator=g) - 0.8, 4 * torch.rand(3, 8, 2, generator=g) - 2], -1)
    level = SafetyLevel(EDGES, (0.0, float("inf")), n)
    sel = leveled_value_selector(vs, n, level, radius=1.0)(state)
    ok = in_domain(state, vs.system.p_range, vs.system.v_range, DoubleIntegrator, 1.0)
    fast = (pair_closing_speed(state, DoubleIntegrator) >= 1.0) & ok
    checked = 0
    for s in range(3):
        for i in range(8):
            chosen = [j for j in sel[s, i].tolist() if j >= 0]
            n_fast = int(fast[s, i].sum())
            assert sum(bool(fast[s, i, j]) for j in chosen) == min(n, n_fast)
            checked += n_fast > 0
    assert checked > 0
    with pytest.raises(ValueError, match="plain value selector"):
        leveled_value_selector(vs, n, SafetyLevel((), (0.1,), n))


def test_wrong_report_fails_early(tmp_path):
    cfg = tiny_cfg(tmp_path)
    vhat, _ = tiny_models()
    _variant(cfg, False, eps=0.02)
    method, ctx = context(cfg, "madpinn-cp")
    with pytest.raises(Exception, match="--model calibration=PATH"):
        make_policy(method, ctx)
    ctx.models["calibration"] = _report(tmp_path / "cal.json", vhat, 0.1, (0.0, 0.1))
    with pytest.raises(ValueError, match="no pooled level for ε = 0.02"):
        make_policy(method, ctx)
    other = json.loads(ctx.models["calibration"].read_text())
    other["model_config_hash"] = "another"
    (tmp_path / "other.json").write_text(json.dumps(other))
    ctx.models["calibration"] = tmp_path / "other.json"
    with pytest.raises(ValueError, match="calibrate the run's own V̂"):
        make_policy(method, ctx)
