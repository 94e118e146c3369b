"""The one ending of every job: result files first, then its MLflow run (SPEC §11).

A job opens its live MLflow run when it starts (:func:`job`: real start time, curves logged
as they happen, closed with the job's real status — FINISHED, FAILED, KILLED), computes,
writes its result files, and hands them to :func:`finish`, which checks they exist and only
then logs them; tracking can never lose them (a store failure leaves a pending run, see
:mod:`madpinn.tracking`).
"""

from __future__ import annotations

import json
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Iterator, Mapping, Sequence


@dataclass
class JobRecord:
    """What one workflow job reports to MLflow."""

    job_key: str
    """unique key of the job (its MLflow run replaces earlier runs with the same key and source)"""
    rule: str
    """workflow rule name (MLflow tag)"""
    artifacts: Sequence[str | Path] = ()
    """result files already written; logged as artifacts"""
    wildcards: Mapping[str, Any] = field(default_factory=dict)
    """the rule's wildcards (MLflow tags)"""
    params: Mapping[str, Any] = field(default_factory=dict)
    """settings the result depends on (flattened into MLflow params, logged when the run opens)"""
    metrics: Mapping[str, Any] = field(default_factory=dict)
    """scalar results (logged at ``step``)"""
    step: int = 0
    """step index of the final metrics (iterations done, for training jobs)"""
    models: Mapping[str, Any] = field(default_factory=dict)
    """``torch.nn.Module`` s logged with the ``mlflow.pytorch`` flavour"""
    register: Mapping[str, str] = field(default_factory=dict)
    """model artifact name -> model name: registered in the Model Registry as ``<experiment>.<name>``"""
    tags: Mapping[str, str] = field(default_factory=dict)
    """extra MLflow tags of the run (e.g. ``madpinn.restored``)"""


def write_json(path: str | Path, obj: Any) -> Path:
    """Write ``obj`` as indented JSON (parents created)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(obj, indent=2))
    return path


def write_commit_record(cfg: Mapping, job_key: str, files: Sequence[str | Path]) -> Path:
    """``<paths.results>/provenance/<job>.json``: the git commit and config hash that wrote
    ``files``, with each file's sha256. The files themselves (committed outputs under
    ``paths.figures``) carry no commit, so identical inputs give identical bytes and a run never
    dirties the repository; the commit is also the job's MLflow tag ``mlflow.source.git.commit``."""
    from madpinn.checksum import sha256
    from madpinn.config import config_hash
    from madpinn.tracking.mlflow_store import git_commit

    out = Path(cfg["paths"]["results"]) / "provenance" / (job_key.replace("/", "__") + ".json")
    return write_json(out, {"job": job_key, "commit": git_commit(), "config_hash": config_hash(cfg),
                            "files": {str(f): sha256(f) for f in files}})


@contextmanager
def job(cfg: Mapping, record: JobRecord, track: bool) -> Iterator[Any]:
    """The job's live MLflow run (:class:`madpinn.tracking.JobRun`; logs nothing when ``track``
    is false or tracking is disabled): wrap the whole job in it, log curves with
    ``run.log_metrics(..., step=i)``, end with :func:`finish`."""
    from madpinn.tracking import job_run

    with job_run(cfg, job_key=record.job_key, rule=record.rule, wildcards=dict(record.wildcards),
                 params=dict(record.params), tags=dict(record.tags), track=track) as run:
        yield run


def finish(run: Any, record: JobRecord, echo: Any = None) -> int:
    """End a job whose files are written: check they exist, log metrics, files and models to
    ``run`` (from :func:`job`), print ``echo`` (JSON, or lines for a list of paths); return 0."""
    missing = [str(p) for p in record.artifacts if not Path(p).exists()]
    if missing:
        raise FileNotFoundError(f"job {record.job_key} did not write {missing}")
    run.finish(metrics=dict(record.metrics), artifacts=list(record.artifacts), models=dict(record.models),
               step=record.step, register=dict(record.register))
    if echo is not None:
        print("\n".join(map(str, echo)) if isinstance(echo, list) else json.dumps(echo))
    return 0
