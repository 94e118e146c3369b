import json
import logging
import os
import signal
import time
from dataclasses import replace
from pathlib import Path

import pytest
import torch
from mlflow.entities import ViewType
from mlflow.tracking import MlflowClient

from madpinn.config import deep_merge
from madpinn.commands.evaluate import evaluate
from madpinn.tracking import JobKilled, TrackingError, TrackingSettings, flush_pending, init_store, job_run, log_job
from madpinn.tracking.record import pending_path


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
    info = init_store(TrackingSettings.from_config(cfg))
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
        init_store(TrackingSettings.from_config(cfg))
    out = tmp_path / "results" / "n3_seed0.parquet"
    summary = evaluate(cfg, "main", "nominal", 3, 0, out, progress=False, track=True)
    assert out.is_file() and out.with_suffix(".json").is_file()
    assert summary["safety_rate"] == 1.0


def test_tracking_disabled_logs_nothing(paper_cfg, tmp_path):
    cfg = deep_merge(_cfg(paper_cfg, tmp_path), {"tracking": {"enabled": False}})
    assert log_job(cfg, "job/z", "rule", {}) is None
    assert not (tmp_path / "mlflow").exists()


# ---- live runs (issue 17), pending runs (issue 18.3), permanent replacement (issue 18.8) ----------


def _settings(paper_cfg, tmp_path, monkeypatch, source="workflow", **kw):
    monkeypatch.delenv("MLFLOW_TRACKING_URI", raising=False)
    monkeypatch.setenv("MADPINN_TRACKING_SOURCE", source)
    s = TrackingSettings.from_config(_cfg(paper_cfg, tmp_path))
    return replace(s, **kw)


def _all_runs(settings, job=None):
    c = MlflowClient(settings.uri)
    exp = c.get_experiment_by_name(settings.experiment)
    runs = c.search_runs([exp.experiment_id], run_view_type=ViewType.ALL)
    return [r for r in runs if job is None or r.data.tags["madpinn.job"] == job]


def test_live_run_has_real_status_duration_and_step_curve(paper_cfg, tmp_path, monkeypatch):
    s = _settings(paper_cfg, tmp_path, monkeypatch, flush_every_s=0.0)
    out = tmp_path / "result.json"
    with job_run(s, job_key="train/x", rule="train_x", params={"a": {"b": 2}}) as run:
        c = MlflowClient(s.uri)
        assert c.get_run(run.run_id).info.status == "RUNNING"      # open while the job runs
        for step in range(1, 6):
            time.sleep(0.02)
            run.log_metrics({"loss": 1.0 / step}, step=step)
        assert len(c.get_metric_history(run.run_id, "loss")) == 5  # sent during the job (flush_every_s=0)
        time.sleep(0.3)
        out.write_text("{}")
        run.finish(metrics={"final": 0.5}, artifacts=[out], models={"net": torch.nn.Linear(2, 1)})
    info = c.get_run(run.run_id).info
    assert info.status == "FINISHED" and info.end_time - info.start_time >= 400
    hist = sorted(c.get_metric_history(run.run_id, "loss"), key=lambda m: m.step)
    assert [m.step for m in hist] == [1, 2, 3, 4, 5] and len({m.timestamp for m in hist}) == 5
    import mlflow.pytorch

    net = mlflow.pytorch.load_model(f"runs:/{run.run_id}/net")
    assert isinstance(net, torch.nn.Linear)
    assert c.get_run(run.run_id).data.params["a.b"] == "2"
    # an MLflow 3 logged model, output of the run, loadable by its id found by name
    exp = c.get_experiment_by_name(s.experiment).experiment_id
    models = c.search_logged_models([exp], filter_string="name = 'net'")
    assert [m.source_run_id for m in models] == [run.run_id]
    assert [o.model_id for o in c.get_run(run.run_id).outputs.model_outputs] == [models[0].model_id]
    assert isinstance(mlflow.pytorch.load_model(f"models:/{models[0].model_id}"), torch.nn.Linear)
    # a rerun of the job replaces its run and its logged model
    with job_run(s, job_key="train/x", rule="train_x") as again:
        again.finish(models={"net": torch.nn.Linear(2, 1)})
    assert [m.source_run_id for m in c.search_logged_models([exp], filter_string="name = 'net'")] == [again.run_id]


def test_failed_and_killed_jobs_close_their_runs_with_that_status(paper_cfg, tmp_path, monkeypatch):
    s = _settings(paper_cfg, tmp_path, monkeypatch)
    with pytest.raises(ValueError):
        with job_run(s, job_key="job/fail", rule="r") as failed:
            raise ValueError("diverged")
    with pytest.raises(JobKilled):
        with job_run(s, job_key="job/kill", rule="r") as killed:
            os.kill(os.getpid(), signal.SIGTERM)
            time.sleep(5)   # the handler interrupts this
    c = MlflowClient(s.uri)
    assert c.get_run(failed.run_id).info.status == "FAILED"
    assert c.get_run(killed.run_id).info.status == "KILLED"
    assert signal.getsignal(signal.SIGTERM) is signal.SIG_DFL   # handler restored


def test_rerun_leaves_exactly_one_run_counting_deleted_and_manual_runs_apart(paper_cfg, tmp_path, monkeypatch):
    art = tmp_path / "a.json"
    art.write_text("{}")
    wf = _settings(paper_cfg, tmp_path, monkeypatch, source="workflow")
    first = log_job(wf, "evaluate/x", "evaluate", {}, artifacts=[art])
    first_artifacts = Path(MlflowClient(wf.uri).get_run(first).info.artifact_uri.removeprefix("file://"))
    assert (first_artifacts / "a.json").is_file()
    for _ in range(2):
        log_job(wf, "evaluate/x", "evaluate", {}, artifacts=[art])
    manual = replace(wf, source="manual")
    for _ in range(2):
        log_job(manual, "evaluate/x", "evaluate", {}, artifacts=[art])
    runs = _all_runs(wf, "evaluate/x")     # ViewType.ALL: soft-deleted runs would count
    assert sorted(r.data.tags["madpinn.source"] for r in runs) == ["manual", "workflow"]
    assert all(r.info.lifecycle_stage == "active" for r in runs)
    assert not first_artifacts.exists()    # purged with its artifacts, as `mlflow gc` does


def test_store_failure_mid_job_keeps_results_and_is_logged_exactly_once_later(paper_cfg, tmp_path, monkeypatch):
    good = _settings(paper_cfg, tmp_path, monkeypatch)
    (tmp_path / "mlflow").write_text("")   # the store is down: a file where its directory goes
    down = replace(good, uri="http://127.0.0.1:9")
    out = tmp_path / "model.csv"
    with job_run(good, job_key="train/y", rule="train_y", params={"p": 1}) as run:
        for step in range(3):
            run.log_metrics({"loss": 3.0 - step}, step=step)
            time.sleep(0.01)
        out.write_text("loss\n1\n")                         # results first
        run.finish(metrics={"final": 1.0}, artifacts=[out], models={"net": torch.nn.Linear(1, 1)})
    assert out.is_file() and run.run_id is None
    pending = pending_path(good, "train/y", "workflow")
    rec = json.loads(pending.read_text())
    assert rec["status"] == "FINISHED" and len(rec["metrics"]) == 4 and rec["uri"] == good.uri
    (tmp_path / "mlflow").unlink()          # the store is back
    init_store(good)
    assert flush_pending(good) == {"logged": 1, "dropped": 0, "failed": 0, "kept": 0}
    assert not pending.exists() and flush_pending(good)["logged"] == 0   # exactly once
    (r,) = _all_runs(good, "train/y")
    c = MlflowClient(good.uri)
    assert r.info.status == "FINISHED" and r.info.start_time == rec["start_ms"] and r.info.end_time == rec["end_ms"]
    assert [m.value for m in sorted(c.get_metric_history(r.info.run_id, "loss"), key=lambda m: m.step)] == [3.0, 2.0, 1.0]
    assert {a.path for a in c.list_artifacts(r.info.run_id)} == {"model.csv", "net"}
    # a later successful run of the job supersedes its pending record
    with job_run(down, job_key="train/y", rule="train_y"):
        pass
    assert pending.exists()
    newer = log_job(good, "train/y", "train_y", {})
    assert not pending.exists() and flush_pending(good)["logged"] == 0
    assert [r.info.run_id for r in _all_runs(good, "train/y")] == [newer]


def test_inside_a_workflow_short_jobs_keep_their_runs_until_it_ends_and_trainings_stay_live(paper_cfg, tmp_path,
                                                                                           monkeypatch, capsys):
    """TrackingSettings.deferred (MADPINN_TRACKING_DEFER=1, set by the workflow): a job that is not live
    opens nothing in the store and prints no warning; its record is logged by flush_pending (the
    workflow's end) with its real times, status, metrics and files, untagged as a failure's record;
    a live job (a training) is in the store while it runs."""
    monkeypatch.setenv("MADPINN_TRACKING_DEFER", "1")
    s = _settings(paper_cfg, tmp_path, monkeypatch)
    assert s.deferred
    init_store(s)
    out = tmp_path / "cell.json"
    with job_run(s, job_key="evaluate/c", rule="evaluate", params={"n": 3}) as run:
        run.log_metrics({"progress": 0.5}, step=1)
        out.write_text("{}")
        run.finish(metrics={"safety_rate": 0.9}, artifacts=[out])
    assert run.run_id is None and _all_runs(s, "evaluate/c") == []          # nothing in the store yet
    with pytest.raises(ValueError):
        with job_run(s, job_key="table/t", rule="table"):
            raise ValueError("bad input")
    with job_run(s, job_key="train/v", rule="train_vs", live=True) as live:
        assert MlflowClient(s.uri).get_run(live.run_id).info.status == "RUNNING"
    assert "WARNING" not in capsys.readouterr().err
    rec = json.loads(pending_path(s, "evaluate/c", "workflow").read_text())
    assert rec["deferred"] and rec["status"] == "FINISHED"
    assert flush_pending(s) == {"logged": 2, "dropped": 0, "failed": 0, "kept": 0}
    (r,) = _all_runs(s, "evaluate/c")
    assert r.info.status == "FINISHED" and (r.info.start_time, r.info.end_time) == (rec["start_ms"], rec["end_ms"])
    assert r.data.metrics["safety_rate"] == 0.9 and r.data.params["n"] == "3"
    assert "madpinn.logged_from_pending" not in r.data.tags
    assert {a.path for a in MlflowClient(s.uri).list_artifacts(r.info.run_id)} == {"cell.json"}
    assert [x.info.status for x in _all_runs(s, "table/t")] == ["FAILED"]
    monkeypatch.delenv("MADPINN_TRACKING_DEFER")
    assert not _settings(paper_cfg, tmp_path, monkeypatch).deferred            # by hand: live, as before


def test_runs_are_named_by_what_tells_them_apart(paper_cfg, tmp_path, monkeypatch):
    """The runs table's name leads with run, N, seed and study (a live run and one replayed from a
    pending record alike); the job key stays the ``madpinn.job`` tag."""
    good = _settings(paper_cfg, tmp_path, monkeypatch)
    cell, oracle = "evaluate/mujoco/scaling/madpinn/n64/seed0", "oracle/small/circle/n4/seed0/s1"
    (tmp_path / "mlflow").write_text("")    # the store is down (a file where its directory goes): a pending record
    with job_run(good, job_key=oracle, rule="oracle_pattern"):
        pass
    (tmp_path / "mlflow").unlink()
    init_store(good)
    assert flush_pending(good)["logged"] == 1
    log_job(good, cell, "evaluate", {})                      # a live run
    names = {r.data.tags["madpinn.job"]: r.info.run_name for r in _all_runs(good, None)}
    assert names == {cell: "madpinn · N=64 · seed 0 · scaling · mujoco",
                     oracle: "oracle · N=4 · seed 0 · small/circle · 1 scenario"}


def test_check_store_is_read_only(paper_cfg, tmp_path, monkeypatch):
    from madpinn.tracking import check_store

    s = _settings(paper_cfg, tmp_path, monkeypatch)
    check_store(s)
    assert not (tmp_path / "mlflow").exists()
    with pytest.raises(TrackingError, match="unreachable"):
        check_store(replace(s, uri="http://127.0.0.1:9"))
    ro = tmp_path / "ro"
    ro.mkdir()
    ro.chmod(0o500)
    try:
        if not os.access(ro, os.W_OK):   # root ignores permissions
            with pytest.raises(TrackingError, match="unreachable"):
                check_store(replace(s, uri=f"sqlite:///{ro / 'sub' / 'mlflow.db'}"))
    finally:
        ro.chmod(0o700)


def test_experiment_is_tagged_as_model_training(paper_cfg, tmp_path, monkeypatch):
    """The experiment says it is model training (mlflow.experimentKind=custom_model_development,
    not GenAI); an older experiment without the tag gets it at the next start."""
    from madpinn.tracking.mlflow_store import (EXPERIMENT_KIND, EXPERIMENT_KIND_TAG, PAPER_METRICS, PAPER_VIEW_KEY,
                                               PAPER_VIEW_TAG, view_url)

    monkeypatch.delenv("MLFLOW_TRACKING_URI", raising=False)
    settings = TrackingSettings.from_config(_cfg(paper_cfg, tmp_path))
    info = init_store(settings)
    c = MlflowClient(settings.uri)
    assert c.get_experiment(info["experiment_id"]).tags[EXPERIMENT_KIND_TAG] == EXPERIMENT_KIND
    # the paper's shared view: the cells, the paper's metric columns, opened by its URL
    view = json.loads(c.get_experiment(info["experiment_id"]).tags[PAPER_VIEW_TAG])
    assert view["searchFilter"] == "tags.`madpinn.rule` = 'evaluate'"
    assert [f"metrics.`{m}`" for m in PAPER_METRICS] == [col for col in view["selectedColumns"] if col.startswith("metrics.")]
    assert view_url("http://h:5000/", "7") == ("http://h:5000/#/experiments/7/runs?viewStateShareKey="
                                               f"{PAPER_VIEW_KEY}&workflowType=machine_learning")
    c.delete_experiment_tag(info["experiment_id"], EXPERIMENT_KIND_TAG)
    init_store(settings)
    assert c.get_experiment(info["experiment_id"]).tags[EXPERIMENT_KIND_TAG] == EXPERIMENT_KIND


def test_models_are_saved_without_the_pickle_warning(paper_cfg, tmp_path, monkeypatch):
    seen = []

    class Keep(logging.Handler):
        def emit(self, record):
            seen.append(record.getMessage())

    logger = logging.getLogger("mlflow.pytorch")       # mlflow's loggers do not propagate to root
    handler = Keep(level=logging.WARNING)
    logger.addHandler(handler)
    try:
        s = _settings(paper_cfg, tmp_path, monkeypatch)
        with job_run(s, job_key="train/y", rule="train_y") as run:
            run.finish(models={"net": torch.nn.Linear(2, 1)})
        import mlflow.pytorch

        mlflow.pytorch.save_model(torch.nn.Linear(2, 1), str(tmp_path / "direct"), serialization_format="pickle")
    finally:
        logger.removeHandler(handler)
    assert len([m for m in seen if "Pickle" in m]) == 1               # the direct call's only
    assert logger.filters == []                                       # silenced for our call only


def test_pending_run_is_logged_into_its_own_store_never_into_another(paper_cfg, tmp_path, monkeypatch):
    """Issue 35 item 7: a run kept pending while its store was unreachable was logged into whatever
    store the next start used (the local SQLite one). The record remembers its store: another
    store's start keeps it pending; it is logged into its own store once that is reachable."""
    local = _settings(paper_cfg, tmp_path, monkeypatch)
    init_store(local)
    (tmp_path / "server").write_text("")   # its store is unreachable (a file where its directory goes)
    server = replace(local, uri=f"sqlite:///{tmp_path / 'server' / 'mlflow.db'}")
    with job_run(server, job_key="train/z", rule="train_z") as run:
        run.finish(metrics={"final": 1.0})
    pending = pending_path(local, "train/z", "workflow")
    assert run.run_id is None and pending.exists()
    assert flush_pending(local) == {"logged": 0, "dropped": 0, "failed": 0, "kept": 1}
    assert pending.exists() and _all_runs(local, "train/z") == []
    (tmp_path / "server").unlink()          # its store is back
    init_store(server)
    assert flush_pending(local) == {"logged": 1, "dropped": 0, "failed": 0, "kept": 0}
    assert not pending.exists() and _all_runs(local, "train/z") == []
    (r,) = _all_runs(server, "train/z")
    assert r.data.metrics["final"] == 1.0


def test_replaced_runs_leave_no_empty_artifact_directories(paper_cfg, tmp_path, monkeypatch):
    """Issue 35 item 6: a purged run's artifact directories stayed behind, empty (22 after three
    crashes and a rerun); now only the active runs' directories remain."""
    art = tmp_path / "a.json"
    art.write_text("{}")
    wf = _settings(paper_cfg, tmp_path, monkeypatch)
    for _ in range(3):
        log_job(wf, "evaluate/x", "evaluate", {}, artifacts=[art])
        log_job(wf, "table/y", "table", {})   # a run without artifacts
    runs = _all_runs(wf)
    assert len(runs) == 2 and all(r.info.lifecycle_stage == "active" for r in runs)
    root = tmp_path / "mlflow" / "artifacts" / wf.experiment
    assert [d for d in root.rglob("*") if d.is_dir() and not any(d.iterdir())] == []
    assert {d.name for d in root.iterdir()} <= {r.info.run_id for r in runs}


def test_a_rerun_for_another_results_path_never_deletes_the_first_paths_run(paper_cfg, tmp_path, monkeypatch):
    """Issue 50 item 2: two results paths sharing one store (the smoke run with `paths.results:
    results_a`, then `results_b`): the second run of `train/vs` permanently deleted the first's while
    results_a stayed on disk. Runs are owned by their results path (tag madpinn.results): a rerun
    replaces its own path's run only."""
    a = _settings(paper_cfg, tmp_path, monkeypatch, results=str(tmp_path / "results_a"))
    b = replace(a, results=str(tmp_path / "results_b"))
    first_a = log_job(a, "train/vs", "train_vs", {})
    first_b = log_job(b, "train/vs", "train_vs", {})
    runs = _all_runs(a, "train/vs")
    assert {r.info.run_id for r in runs} == {first_a, first_b}
    assert all(r.info.lifecycle_stage == "active" for r in runs)
    assert {r.data.tags["madpinn.results"] for r in runs} == {a.results, b.results}
    second_a = log_job(a, "train/vs", "train_vs", {})        # a rerun for results_a replaces results_a's run only
    assert {r.info.run_id for r in _all_runs(a, "train/vs")} == {second_a, first_b}


def test_results_path_of_a_run_is_its_absolute_results_directory(paper_cfg, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    monkeypatch.delenv("MLFLOW_TRACKING_URI", raising=False)
    cfg = deep_merge(_cfg(paper_cfg, tmp_path), {"paths": {"results": "results_a"}})
    assert TrackingSettings.from_config(cfg).results == str(tmp_path / "results_a")


def test_replaced_runs_leave_no_logged_model_files(paper_cfg, tmp_path, monkeypatch):
    """Issue 50 item 9: a purged run's logged MLflow models (≈ 330 kB each for a V̂) stayed in the
    artifact store, soft-deleted; now they are removed with the run, as `mlflow gc` would."""
    s = _settings(paper_cfg, tmp_path, monkeypatch)
    for _ in range(3):
        with job_run(s, job_key="train/z", rule="train_z") as run:
            run.finish(models={"net": torch.nn.Linear(4, 3)})
    (live,) = _all_runs(s, "train/z")
    c = MlflowClient(s.uri)
    exp = c.get_experiment_by_name(s.experiment).experiment_id
    models = c.search_logged_models([exp])
    assert [m.source_run_id for m in models] == [live.info.run_id]
    root = tmp_path / "mlflow" / "artifacts" / s.experiment
    owners = {p.relative_to(root).parts[1] if p.relative_to(root).parts[0] == "models" else p.relative_to(root).parts[0]
              for p in root.rglob("MLmodel")}
    assert owners == {models[0].model_id, live.info.run_id}          # the live run's model only
    assert [d for d in root.rglob("*") if d.is_dir() and not any(d.iterdir())] == []
