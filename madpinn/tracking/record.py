"""A job's run as plain data (:class:`RunRecord`), replayed into the store as one run, and kept
as a pending-run file when the store fails during the job.

A pending file ``<results>/tracking/pending/<source>__<job>.json`` (model directories beside it)
holds everything the job logged, with the original timestamps, and the store it was meant for. A
short workflow job writes one by choice (``TrackingSettings.deferred``), which the workflow logs when
it ends; a live run writes one when its store fails.
:func:`flush_pending` — called at every workflow start with a reachable store and at its end
(``log_pending_runs`` in ``workflow/rules/common.smk``) — logs each one as the job's run into that store and removes the file. Exactly once: a replay replaces every
other run of the job (same key and source), so a replay interrupted before its file is removed
is replaced by the next one; a pending record older than a run already in the store is dropped.
"""

from __future__ import annotations

import json
import math
import re
import shutil
import sys
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path

from madpinn.tracking.mlflow_store import (RESULTS_TAG, TrackingError, check_store, client, experiment_id, job_runs,
                                           purge_runs, run_name)
from madpinn.tracking.settings import TrackingSettings

PARAMS_PER_BATCH = 100     # MLflow's log_batch limits
METRICS_PER_BATCH = 1000


def now_ms() -> int:
    return int(time.time() * 1000)


@dataclass
class RunRecord:
    job_key: str
    source: str
    tags: dict
    start_ms: int
    params: dict = field(default_factory=dict)          # flat name -> str
    metrics: list = field(default_factory=list)         # [key, value, timestamp_ms, step]
    artifacts: list = field(default_factory=list)       # file paths (result files)
    models: dict = field(default_factory=dict)          # artifact path -> local MLflow model directory
    registered: dict = field(default_factory=dict)      # artifact path -> Model Registry name
    status: str = "RUNNING"
    end_ms: int | None = None
    run_id: str | None = None                            # the live run, if one was created
    uri: str | None = None                               # the store it belongs to (None: records from before)
    deferred: bool = False                               # kept by choice (a short workflow job), not after a store failure

    def add_metrics(self, metrics: dict, step: int, ts: int | None = None) -> list:
        ts = now_ms() if ts is None else ts
        rows = [[k, float(v), ts, int(step)] for k, v in metrics.items()
                if v is not None and isinstance(v, (int, float)) and math.isfinite(float(v))]
        self.metrics.extend(rows)
        return rows


def metric_entities(rows):
    from mlflow.entities import Metric

    return [Metric(k, v, ts, step) for k, v, ts, step in rows]


def log_params(c, run_id: str, params: dict) -> None:
    from mlflow.entities import Param

    items = [Param(k, v) for k, v in params.items()]
    for i in range(0, len(items), PARAMS_PER_BATCH):
        c.log_batch(run_id, params=items[i : i + PARAMS_PER_BATCH])


def log_metric_rows(c, run_id: str, rows) -> None:
    for i in range(0, len(rows), METRICS_PER_BATCH):
        c.log_batch(run_id, metrics=metric_entities(rows[i : i + METRICS_PER_BATCH]))


def log_files(c, run_id: str, artifacts, models: dict, registered: dict | None = None) -> list[str]:
    """Log result files and model directories (each model in ``registered`` also registered in the
    Model Registry under that name); return the result files that no longer exist."""
    missing = []
    for path in artifacts:
        if Path(path).is_file():
            c.log_artifact(run_id, str(path))
        else:
            missing.append(str(path))
    for name, local in models.items():
        c.log_artifacts(run_id, str(local), artifact_path=name)   # runs:/<run id>/<name>
        model_id = log_logged_model(c, run_id, name, local)
        if name in (registered or {}):
            register_model(c, registered[name], model_id, run_id)
    return missing


def register_model(c, name: str, model_id: str, run_id: str) -> str:
    """A new version of registered model ``name`` (created when missing) for logged model
    ``model_id`` of run ``run_id`` (load: ``mlflow.pytorch.load_model("models:/<name>/<version>")``);
    returns the version. A replaced run's versions go with it (:func:`madpinn.tracking.mlflow_store.purge_runs`)."""
    from mlflow.exceptions import MlflowException

    if not c.search_registered_models(filter_string=f"name = '{name}'"):
        try:
            c.create_registered_model(name, description="madpinn network (docs/reference/tracking.md); one version per run "
                                                        "that trained or installed it")
        except MlflowException:   # created meanwhile by a parallel job
            pass
    return c.create_model_version(name, source=f"models:/{model_id}", run_id=run_id, model_id=model_id).version


def log_logged_model(c, run_id: str, name: str, local: str | Path) -> str:
    """The saved model directory ``local`` as an MLflow 3 logged model named ``name``, an output
    of run ``run_id`` (the experiment's Models tab and the run page list it; load with
    ``mlflow.pytorch.load_model(f"models:/{model_id}")``, the id from
    ``mlflow.search_logged_models(filter_string="name = '<name>'")``); returns its id."""
    from mlflow.entities import LoggedModelOutput, LoggedModelStatus

    exp_id = c.get_run(run_id).info.experiment_id
    model = c.create_logged_model(exp_id, name=name, source_run_id=run_id, model_type="pytorch")
    c.log_model_artifacts(model.model_id, str(local))
    c.finalize_logged_model(model.model_id, LoggedModelStatus.READY)
    c.log_outputs(run_id, [LoggedModelOutput(model.model_id, step=0)])
    return model.model_id


def _stem(job_key: str, source: str) -> str:
    return f"{source}__" + re.sub(r"[^A-Za-z0-9._-]+", "__", job_key)


def pending_path(settings: TrackingSettings, job_key: str, source: str) -> Path:
    return settings.pending_dir / f"{_stem(job_key, source)}.json"


def write_pending(settings: TrackingSettings, record: RunRecord) -> Path:
    """Keep ``record`` (and its model directories) for :func:`flush_pending`; atomic."""
    path = pending_path(settings, record.job_key, record.source)
    path.parent.mkdir(parents=True, exist_ok=True)
    models = {}
    for name, local in record.models.items():
        dest = path.with_name(path.stem + ".models") / name
        if Path(local).resolve() != dest.resolve():
            shutil.rmtree(dest, ignore_errors=True)
            dest.parent.mkdir(parents=True, exist_ok=True)
            shutil.copytree(local, dest)
        models[name] = str(dest)
    data = {**asdict(record), "models": models,
            "artifacts": [str(Path(a).resolve()) for a in record.artifacts]}
    tmp = path.with_suffix(".json.tmp")
    tmp.write_text(json.dumps(data))
    tmp.replace(path)
    return path


def remove_pending(settings: TrackingSettings, job_key: str, source: str) -> None:
    path = pending_path(settings, job_key, source)
    path.unlink(missing_ok=True)
    shutil.rmtree(path.with_name(path.stem + ".models"), ignore_errors=True)


def replay(settings: TrackingSettings, record: RunRecord) -> str | None:
    """Log ``record`` as the job's only run (replacing the others); ``None`` if a later run of the
    job is already in the store. Raises on store errors."""
    c = client(settings)
    exp = experiment_id(c, settings)
    others = job_runs(c, exp, record.job_key, record.source, record.tags.get(RESULTS_TAG))
    if any(r.info.run_id != record.run_id and (r.info.start_time or 0) > record.start_ms for r in others):
        return None
    run_id = c.create_run(exp, start_time=record.start_ms, tags=record.tags, run_name=run_name(record.job_key)).info.run_id
    try:
        log_params(c, run_id, record.params)
        log_metric_rows(c, run_id, record.metrics)
        missing = log_files(c, run_id, record.artifacts, record.models, record.registered)
        if missing:
            c.set_tag(run_id, "madpinn.missing_artifacts", ",".join(missing)[:5000])
        if not record.deferred:
            c.set_tag(run_id, "madpinn.logged_from_pending", "true")
        c.set_terminated(run_id, record.status, end_time=record.end_ms)
    except Exception:
        purge_runs(c, settings, [c.get_run(run_id)])
        raise
    purge_runs(c, settings, others)
    return run_id


def flush_pending(settings: TrackingSettings) -> dict:
    """Log every pending run (oldest first) into the store it was recorded for; return
    ``{logged, dropped, failed, kept}`` counts. A record of another store than ``settings.uri``
    (e.g. a server that was down, while this start uses another URI) is logged into its own store
    when that one is reachable, else kept pending (``kept``): never into a different store. A
    failing record stays pending and is reported on stderr."""
    from dataclasses import replace

    counts = {"logged": 0, "dropped": 0, "failed": 0, "kept": 0}
    reachable: dict[str, bool] = {}
    if not settings.enabled or not settings.pending_dir.is_dir():
        return counts
    files = sorted(settings.pending_dir.glob("*.json"), key=lambda p: p.stat().st_mtime)
    for path in files:
        try:
            record = RunRecord(**json.loads(path.read_text()))
            if record.tags.get("madpinn.experiment_config", settings.experiment) != settings.experiment:
                continue   # another configuration's run: flushed by its own workflow
            target = settings if record.uri in (None, settings.uri) else replace(settings, uri=record.uri)
            if target is not settings and record.uri not in reachable:   # each other store checked once
                try:
                    check_store(target)
                    reachable[record.uri] = True
                except TrackingError:
                    reachable[record.uri] = False
            if target is not settings and not reachable[record.uri]:
                counts["kept"] += 1
                print(f"WARNING: pending MLflow run {path} belongs to {record.uri}, which is unreachable; kept "
                      f"pending (not logged to {settings.uri})", file=sys.stderr)
                continue
            logged = replay(target, record)
        except Exception as exc:  # noqa: BLE001
            counts["failed"] += 1
            print(f"WARNING: pending MLflow run {path} could not be logged to {record.uri or settings.uri}: {exc}",
                  file=sys.stderr)
            continue
        counts["logged" if logged else "dropped"] += 1
        remove_pending(settings, record.job_key, record.source)
    return counts
