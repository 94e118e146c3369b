"""Tracking settings, parsed once from the config: where runs go and how they are keyed."""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import Mapping

DEFAULT_DIR = "mlflow"
SOURCE_ENV = "MADPINN_TRACKING_SOURCE"   # "workflow" inside snakemake (set by tracking.smk), else "manual"
SOURCES = ("workflow", "manual")
DEFER_ENV = "MADPINN_TRACKING_DEFER"     # "1" inside snakemake (set by tracking.smk): short jobs' runs logged at its end


def tracking_uri(cfg: Mapping) -> str:
    """``MLFLOW_TRACKING_URI`` if set, else ``tracking.uri``, else the embedded ``mlflow/mlflow.db``."""
    env = os.environ.get("MLFLOW_TRACKING_URI")
    if env:
        return env
    uri = (cfg.get("tracking") or {}).get("uri")
    if uri:
        return uri
    return f"sqlite:///{Path.cwd() / DEFAULT_DIR / 'mlflow.db'}"


def run_source() -> str:
    """Who started the job: ``workflow`` (snakemake) or ``manual``; runs are replaced only within a source."""
    source = os.environ.get(SOURCE_ENV, "manual")
    if source not in SOURCES:
        raise ValueError(f"{SOURCE_ENV}={source!r}: expected one of {SOURCES}")
    return source


@dataclass(frozen=True)
class TrackingSettings:
    enabled: bool
    """``tracking.enabled``: false runs every job without MLflow."""
    uri: str
    """Resolved tracking URI (``sqlite:///…`` or ``http(s)://host:port``)."""
    experiment: str
    """MLflow experiment, one per configuration (``experiment`` key)."""
    pending_dir: Path
    """``<paths.results>/tracking/pending``: runs whose logging failed, logged by the next workflow start."""
    config_hash: str
    """Hash of the whole configuration (tag ``madpinn.config_hash``)."""
    source: str = "manual"
    """``workflow`` or ``manual`` (tag ``madpinn.source``, part of the replacement key)."""
    results: str | None = None
    """Absolute ``paths.results`` (tag ``madpinn.results``): the owner of the runs, replaced only by a
    rerun of the same job for the same results path (never across results paths sharing the store)."""
    flush_every_s: float = 10.0
    """Buffered step metrics are sent at most this often (s) while a job runs."""
    deferred: bool = False
    """Inside a workflow (``MADPINN_TRACKING_DEFER=1``, set by ``workflow/rules/tracking.smk``): a job
    that asks for no live run (all but the trainings) keeps its run as a pending record, which the
    workflow logs when it ends (``onsuccess`` / ``onerror``), ``track-cells`` before it reads the cell
    runs, or else the next start. Saves each such job MLflow's import and store connection (≈ 2.7 s of
    CPU), the larger part of a short job's cost."""

    @classmethod
    def from_config(cls, cfg: Mapping) -> "TrackingSettings":
        from madpinn.config import config_hash

        return cls(
            enabled=bool(cfg["tracking"]["enabled"]),
            uri=tracking_uri(cfg),
            experiment=str(cfg["experiment"]),
            pending_dir=Path(cfg["paths"]["results"]) / "tracking" / "pending",
            config_hash=config_hash(cfg),
            source=run_source(),
            results=str(Path(cfg["paths"]["results"]).resolve()),
            deferred=os.environ.get(DEFER_ENV) == "1",
        )

    @property
    def is_remote(self) -> bool:
        return self.uri.startswith(("http://", "https://"))
