"""One MLflow run per workflow job, in one experiment per workflow configuration.

- Store: ``MLFLOW_TRACKING_URI`` if set, else ``tracking.uri`` from the config, else an embedded
  SQLite store ``mlflow/mlflow.db`` in the working directory (artifacts in ``mlflow/artifacts``).
- :func:`init_store` creates the store and the experiment once, before the fan-out (parallel
  first writers race on SQLite schema creation), and fails early and clearly when a remote
  server cannot be reached.
- :func:`log_job` replaces any earlier run of the same job (tag ``madpinn.job``), retries on
  transient errors (SQLite lock contention), and never raises: a tracking failure is reported
  on stderr and the caller's result files stay the source of truth.
"""

from __future__ import annotations

import math
import os
import subprocess
import sys
import time
from pathlib import Path
from typing import Mapping, Sequence

from madpinn.config import REPO_ROOT, config_hash

JOB_TAG = "madpinn.job"
DEFAULT_DIR = "mlflow"

# Fail fast against an unreachable server instead of MLflow's minutes of exponential backoff.
os.environ.setdefault("MLFLOW_HTTP_REQUEST_MAX_RETRIES", "2")
os.environ.setdefault("MLFLOW_HTTP_REQUEST_BACKOFF_FACTOR", "0.5")
os.environ.setdefault("MLFLOW_HTTP_REQUEST_TIMEOUT", "15")


class TrackingError(RuntimeError):
    """The tracking store cannot be used (e.g. unreachable server)."""


def tracking_uri(cfg: Mapping) -> str:
    env = os.environ.get("MLFLOW_TRACKING_URI")
    if env:
        return env
    uri = (cfg.get("tracking") or {}).get("uri")
    if uri:
        return uri
    return f"sqlite:///{Path.cwd() / DEFAULT_DIR / 'mlflow.db'}"


def _artifact_location(uri: str, experiment: str) -> str | None:
    if uri.startswith("sqlite:///"):
        return (Path(uri[len("sqlite:///"):]).parent / "artifacts" / experiment).as_uri()
    return None  # server decides


def _check_reachable(uri: str) -> None:
    if not uri.startswith(("http://", "https://")):
        return
    import urllib.request

    try:
        with urllib.request.urlopen(uri.rstrip("/") + "/health", timeout=10) as resp:
            if resp.status >= 400:
                raise TrackingError(f"MLflow server {uri} answered HTTP {resp.status}")
    except TrackingError:
        raise
    except Exception as exc:  # noqa: BLE001 - any transport failure means unreachable
        raise TrackingError(
            f"MLflow tracking server {uri} is unreachable ({exc}). Start it, fix MLFLOW_TRACKING_URI, "
            f"or unset it to use the embedded store; set tracking.enabled: false to run without tracking."
        ) from exc


def _client(uri: str):
    import mlflow
    from mlflow.tracking import MlflowClient

    mlflow.set_tracking_uri(uri)
    return MlflowClient(tracking_uri=uri)


def _get_or_create_experiment(client, name: str, uri: str) -> str:
    exp = client.get_experiment_by_name(name)
    if exp is not None:
        if exp.lifecycle_stage == "deleted":
            client.restore_experiment(exp.experiment_id)
        return exp.experiment_id
    return client.create_experiment(name, artifact_location=_artifact_location(uri, name))


def init_store(cfg: Mapping) -> dict:
    """Create the store and the configuration's experiment; return ``{uri, experiment, id}``."""
    uri = tracking_uri(cfg)
    _check_reachable(uri)
    if uri.startswith("sqlite:///"):
        Path(uri[len("sqlite:///"):]).parent.mkdir(parents=True, exist_ok=True)
    try:
        client = _client(uri)
        exp_id = _get_or_create_experiment(client, cfg["experiment"], uri)
    except Exception as exc:  # noqa: BLE001
        raise TrackingError(f"cannot initialise MLflow store {uri}: {exc}") from exc
    return {"uri": uri, "experiment": cfg["experiment"], "experiment_id": exp_id}


def git_commit() -> str:
    try:
        sha = subprocess.run(
            ["git", "-C", str(REPO_ROOT), "rev-parse", "HEAD"], capture_output=True, text=True, timeout=10
        ).stdout.strip()
        dirty = subprocess.run(
            ["git", "-C", str(REPO_ROOT), "status", "--porcelain", "--untracked-files=no"],
            capture_output=True, text=True, timeout=10,
        ).stdout.strip()
        return (sha or "unknown") + ("-dirty" if dirty else "")
    except Exception:  # noqa: BLE001
        return "unknown"


def _flat(d: Mapping, prefix: str = "") -> dict:
    out = {}
    for k, v in d.items():
        key = f"{prefix}{k}"
        if isinstance(v, Mapping):
            out.update(_flat(v, key + "."))
        else:
            out[key] = v
    return out


def _log_once(cfg, uri, job_key, tags, params, metrics, artifacts, step_metrics) -> str:
    from mlflow.entities import Metric, Param, RunTag

    client = _client(uri)
    exp_id = _get_or_create_experiment(client, cfg["experiment"], uri)
    for old in client.search_runs([exp_id], filter_string=f"tags.`{JOB_TAG}` = '{job_key}'", max_results=1000):
        client.delete_run(old.info.run_id)
    run = client.create_run(exp_id, run_name=job_key, tags={JOB_TAG: job_key, **tags})
    run_id = run.info.run_id
    try:
        now = int(time.time() * 1000)
        plist = [Param(k, str(v)[:6000]) for k, v in _flat(params).items()]
        mlist = [Metric(k, float(v), now, 0) for k, v in metrics.items() if v is not None and math.isfinite(float(v))]
        for name, values in (step_metrics or {}).items():
            mlist += [Metric(name, float(v), now, i) for i, v in enumerate(values) if math.isfinite(float(v))]
        for i in range(0, max(len(plist), len(mlist)), 500):
            client.log_batch(run_id, metrics=mlist[i : i + 500], params=plist[i : i + 500], tags=[])
        for path in artifacts:
            if Path(path).is_file():
                client.log_artifact(run_id, str(path))
        client.set_terminated(run_id, "FINISHED")
    except Exception:
        client.set_terminated(run_id, "FAILED")
        raise
    return run_id


def log_job(
    cfg: Mapping,
    job_key: str,
    rule: str,
    wildcards: Mapping[str, object],
    params: Mapping | None = None,
    metrics: Mapping[str, float] | None = None,
    artifacts: Sequence[str | Path] = (),
    step_metrics: Mapping[str, Sequence[float]] | None = None,
    attempts: int | None = None,
) -> str | None:
    """Log one job as one run (replacing earlier runs of the same job). Never raises.

    Retries cover SQLite lock contention between parallel jobs; an HTTP store is tried once
    (MLflow's client already retries HTTP requests).
    """
    if not (cfg.get("tracking") or {}).get("enabled", True):
        return None
    uri = tracking_uri(cfg)
    if attempts is None:
        attempts = 1 if uri.startswith(("http://", "https://")) else 4
    tags = {
        "madpinn.rule": rule,
        "madpinn.config_hash": config_hash(cfg),
        "madpinn.experiment_config": cfg["experiment"],
        "mlflow.source.git.commit": git_commit(),
        **{f"wildcard.{k}": str(v) for k, v in wildcards.items()},
    }
    last = None
    for attempt in range(attempts):
        try:
            return _log_once(cfg, uri, job_key, tags, params or {}, metrics or {}, artifacts, step_metrics)
        except Exception as exc:  # noqa: BLE001
            last = exc
            if attempt + 1 < attempts:
                time.sleep(0.5 * 2**attempt)
    print(
        f"WARNING: MLflow logging of job '{job_key}' to {uri} failed after {attempts} attempts: {last}. "
        f"The job's result files are complete; re-run the job to log it.",
        file=sys.stderr,
    )
    return None
