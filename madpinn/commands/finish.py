"""The one ending of every job: result files first, then one MLflow run (SPEC §11).

A job computes, writes its result files, and hands them here; tracking can never lose them
because it runs only after they exist.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Mapping, Sequence


@dataclass
class JobRecord:
    """What one workflow job reports to MLflow."""

    job_key: str
    """unique key of the job (its MLflow run replaces earlier runs with the same key)"""
    rule: str
    """workflow rule name (MLflow tag)"""
    artifacts: Sequence[str | Path] = ()
    """result files already written; logged as artifacts"""
    wildcards: Mapping[str, Any] = field(default_factory=dict)
    """the rule's wildcards (MLflow tags)"""
    params: Mapping[str, Any] = field(default_factory=dict)
    """settings the result depends on (flattened into MLflow params)"""
    metrics: Mapping[str, Any] = field(default_factory=dict)
    """scalar results"""
    step_metrics: Mapping[str, Sequence[float]] | None = None
    """curves logged with their step index (learning curves)"""


def write_json(path: str | Path, obj: Any) -> Path:
    """Write ``obj`` as indented JSON (parents created)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(obj, indent=2))
    return path


def finish(cfg: Mapping, record: JobRecord, track: bool, echo: Any = None) -> int:
    """End a job whose files are written: check they exist, log one MLflow run unless
    ``track`` is false, print ``echo`` (JSON, or lines for a list of paths); return exit code 0."""
    missing = [str(p) for p in record.artifacts if not Path(p).exists()]
    if missing:
        raise FileNotFoundError(f"job {record.job_key} did not write {missing}")
    if track:
        from madpinn.tracking import log_job

        log_job(cfg, job_key=record.job_key, rule=record.rule, wildcards=dict(record.wildcards),
                params=dict(record.params), metrics=dict(record.metrics), artifacts=list(record.artifacts),
                step_metrics=dict(record.step_metrics) if record.step_metrics else None)
    if echo is not None:
        print("\n".join(map(str, echo)) if isinstance(echo, list) else json.dumps(echo))
    return 0
