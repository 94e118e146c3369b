import json

import numpy as np
import pandas as pd
import pytest
import torch

from madpinn.config import deep_merge, validate_config
from madpinn.dynamics import DoubleIntegrator
from madpinn.commands.evaluate import evaluate
from madpinn.policies.nominal import NominalPD
from madpinn.scenarios import Arena, generate_scenarios
from madpinn.simulation import DoubleIntegratorBackend, run_episode


def _tiny(cfg, tmp_path, **study):
    over = {
        "paths": {"results": str(tmp_path / "results"), "figures": str(tmp_path / "figs")},
        "tracking": {"enabled": False},
        "arenas": {"small": {"half_width": 1.0, "episode_s": 0.5}},
        "sim": {"scenario_batch": 3},
        "studies": {"main": {"arena": "small", "agent_counts": [4], "seeds": [0], "scenarios": 5, "runs": ["nominal"], **study}},
        "figures": {"trajectories": {"study": "main", "n_agents": 4, "seed": 0}},
    }
    cfg = deep_merge(cfg, over)
    validate_config(cfg)
    return cfg


def test_nominal_policy_reaches_goals_single_agent():
    dyn = DoubleIntegrator(u_max=4.0, v_max=4.0)
    starts, goals = generate_scenarios(Arena("small", 1.0, 3.0), 1, seed=0, count=4, min_separation=0.2)
    res, stats = run_episode(DoubleIntegratorBackend(dyn, 0.0025), NominalPD(dyn, 6.0, 4.9), starts, goals, 1200, 0.1, progress=False)
    assert res.final_distance.max() < 0.01
    assert stats["steps"] == 1200


def test_policy_period_holds_the_command():
    class Counting:
        calls = 0

        def reset(self, state, goals):
            pass

        def act(self, state, goals, t):
            Counting.calls += 1
            return torch.ones_like(goals)

    dyn = DoubleIntegrator(u_max=4.0, v_max=4.0)
    starts = torch.zeros(1, 2, 2)
    starts[0, 1, 0] = 1.0
    res, _ = run_episode(DoubleIntegratorBackend(dyn, 0.01), Counting(), starts, starts.clone(), 10, 0.1, policy_period=5, progress=False)
    assert Counting.calls == 2


def test_evaluate_job_writes_files_and_is_deterministic(paper_cfg, tmp_path):
    cfg = _tiny(paper_cfg, tmp_path)
    out1, out2 = tmp_path / "a" / "n4_seed0.parquet", tmp_path / "b" / "n4_seed0.parquet"
    s1 = evaluate(cfg, "main", "nominal", 4, 0, out1, progress=False, track=False)
    s2 = evaluate(cfg, "main", "nominal", 4, 0, out2, progress=False, track=False)
    df1, df2 = pd.read_parquet(out1), pd.read_parquet(out2)
    assert len(df1) == 5 and df1["scenario"].tolist() == [0, 1, 2, 3, 4]
    pd.testing.assert_frame_equal(df1, df2)
    for k in ("safety_rate", "safe_scenarios", "cost"):
        assert s1[k] == s2[k]
    summary = json.loads(out1.with_suffix(".json").read_text())
    assert summary["n_agents"] == 4 and summary["n_steps"] == 200
    traj = np.load(tmp_path / "a" / "n4_seed0_traj.npz")
    assert traj["positions"].shape[1:] == (4, 2) and traj["goals"].shape == (4, 2)


def test_evaluate_rejects_unknown_study_and_method(paper_cfg, tmp_path):
    cfg = _tiny(paper_cfg, tmp_path)
    with pytest.raises(ValueError, match="unknown study"):
        evaluate(cfg, "nope", "nominal", 4, 0, tmp_path / "x.parquet", progress=False, track=False)
    with pytest.raises(Exception, match="unknown method"):
        evaluate(cfg, "main", "warp", 4, 0, tmp_path / "x.parquet", progress=False, track=False)
