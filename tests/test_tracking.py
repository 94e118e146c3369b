import time

import pytest
from mlflow.entities import ViewType
from mlflow.tracking import MlflowClient

from madpinn.config import deep_merge
from madpinn.commands.evaluate import evaluate
from madpinn.tracking import TrackingError, init_store, log_job


def _cfg(paper_cfg, tmp_path, uri=None):
    return deep_merge(
        paper_cfg,
        {
            "experiment": "unit-test",
            "tracking": {"enabled": True, "uri": uri or f"sqlite:///{tmp_path / 'mlflow' / 'mlflow.db'}"},
            "paths": {"results": str(tmp_path / "results"), "figures": str(tmp_path / "figs")},
            "arenas": {"small": {"half_width": 1.0, "episode_s": 0.05}},
            "studies": {"main": {"arena": "small", "agent_counts": [3], "seeds": [0], "scenarios": 2, "runs": ["nominal"]}},
            "figures": {"trajectories": {"study": "main", "n_agents": 3, "seed": 0}},
        },
    )


def _runs(uri, name, view=ViewType.ACTIVE_ONLY):
    c = MlflowClient(uri)
    return c.search_runs([c.get_experiment_by_name(name).experiment_id], run_view_type=view)


def test_rerun_replaces_the_run(paper_cfg, tmp_path, monkeypatch):
    monkeypatch.delenv("MLFLOW_TRACKING_URI", raising=False)
    cfg = _cfg(paper_cfg, tmp_path)
    info = init_store(cfg)
    art = tmp_path / "a.json"
    art.write_text("{}")
    for value in (1.0, 2.0):
        assert log_job(cfg, "job/x", "rule_x", {"n": 3}, params={"p": {"q": 1}}, metrics={"m": value},
                       artifacts=[art], step_metrics={"loss": [3.0, 2.0, 1.0]})
    log_job(cfg, "job/y", "rule_y", {}, metrics={"m": 5.0})
    runs = _runs(info["uri"], "unit-test")
    assert sorted(r.data.tags["madpinn.job"] for r in runs) == ["job/x", "job/y"]
    x = next(r for r in runs if r.data.tags["madpinn.job"] == "job/x")
    assert x.data.metrics["m"] == 2.0 and x.data.params["p.q"] == "1"
    assert x.data.tags["wildcard.n"] == "3" and "madpinn.config_hash" in x.data.tags
    hist = MlflowClient(info["uri"]).get_metric_history(x.info.run_id, "loss")
    assert [m.value for m in sorted(hist, key=lambda m: m.step)] == [3.0, 2.0, 1.0]
    assert [a.path for a in MlflowClient(info["uri"]).list_artifacts(x.info.run_id)] == ["a.json"]


def test_unreachable_server_fails_init_early_and_never_loses_results(paper_cfg, tmp_path, monkeypatch):
    monkeypatch.setenv("MLFLOW_TRACKING_URI", "http://127.0.0.1:9")
    cfg = _cfg(paper_cfg, tmp_path)
    with pytest.raises(TrackingError, match="unreachable"):
        init_store(cfg)
    out = tmp_path / "results" / "n3_seed0.parquet"
    summary = evaluate(cfg, "main", "nominal", 3, 0, out, progress=False, track=True)
    assert out.is_file() and out.with_suffix(".json").is_file()
    assert summary["safety_rate"] == 1.0


def test_tracking_disabled_logs_nothing(paper_cfg, tmp_path):
    cfg = deep_merge(_cfg(paper_cfg, tmp_path), {"tracking": {"enabled": False}})
    assert log_job(cfg, "job/z", "rule", {}) is None
    assert not (tmp_path / "mlflow").exists()
