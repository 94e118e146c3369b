"""An MLflow run per job: opened when the job starts, closed with its real status and duration
(inside a workflow, a job that is not a training keeps it as a record, logged when the workflow
ends: ``TrackingSettings.deferred``).

    with job_run(settings, job_key="train/vhat", rule="train_vhat", wildcards={"kind": "vhat"},
                 params={...}) as run:
        for it in ...:
            run.log_metrics({"loss": x}, step=it)      # buffered, sent every flush_every_s
        ...write the result files...
        run.finish(metrics=summary, artifacts=[files...], models={"model": torch_module})

- Status: ``FINISHED`` (block ends normally), ``KILLED`` (SIGINT/SIGTERM — the handler is
  installed for the block), ``FAILED`` (any other exception, which propagates).
- Replacement: when the run closes, every other run of the same ``job_key``, source
  (``workflow`` or ``manual``, tag ``madpinn.source``) *and results path* (tag
  ``madpinn.results``) is deleted permanently (:func:`madpinn.tracking.mlflow_store.purge_runs`);
  a job started by hand never replaces the workflow's run, and a run of one ``paths.results``
  never replaces another's sharing the store.
- Never raises for tracking: if the store fails at any point the run's whole record (params,
  every metric with its timestamp, result files, model directories) is written as a pending-run
  file, logged by the next workflow start (:mod:`madpinn.tracking.record`).
- ``models``: ``torch.nn.Module`` s saved with the ``mlflow.pytorch`` flavour
  (``mlflow.pytorch.load_model("runs:/<id>/<name>")``, needs ``madpinn`` importable).
"""

from __future__ import annotations

import contextlib
import logging
import shutil
import signal
import sys
import tempfile
import threading
import time
from pathlib import Path
from typing import Callable, Mapping, Sequence

from madpinn.tracking.mlflow_store import (JOB_TAG, RESULTS_TAG, SOURCE_TAG, client, experiment_id, git_commit, job_runs,
                                           purge_runs, run_name)
from madpinn.tracking.record import (RunRecord, log_files, log_metric_rows, log_params, now_ms, remove_pending,
                                     write_pending)
from madpinn.tracking.settings import TrackingSettings

STATUSES = ("FINISHED", "FAILED", "KILLED")


class JobKilled(KeyboardInterrupt):
    """Raised inside a job by SIGTERM (snakemake cancelling it, a cluster's scancel)."""


def flatten(d: Mapping, prefix: str = "") -> dict:
    out = {}
    for k, v in d.items():
        key = f"{prefix}{k}"
        if isinstance(v, Mapping):
            out.update(flatten(v, key + "."))
        else:
            out[key] = str(v)[:6000]
    return out


def _settings(settings_or_cfg) -> TrackingSettings:
    return settings_or_cfg if isinstance(settings_or_cfg, TrackingSettings) else TrackingSettings.from_config(settings_or_cfg)


class JobRun:
    """One job's MLflow run; use through :func:`job_run`. ``run_id`` is ``None`` when tracking is
    off or the store failed (then the run is pending)."""

    def __init__(self, settings: TrackingSettings, job_key: str, rule: str, wildcards: Mapping, params: Mapping | None,
                 tags: Mapping | None = None, defer: bool = False):
        self.settings = settings
        self.enabled = settings.enabled
        self.defer = defer and self.enabled   # kept as a pending record, logged when the workflow ends
        tags = {
            JOB_TAG: job_key, SOURCE_TAG: settings.source, RESULTS_TAG: settings.results, "madpinn.rule": rule,
            "madpinn.config_hash": settings.config_hash, "madpinn.experiment_config": settings.experiment,
            "mlflow.source.git.commit": git_commit() if self.enabled else "", "mlflow.runName": run_name(job_key),
            **{f"wildcard.{k}": str(v) for k, v in wildcards.items()}, **(tags or {}),
        }
        self.record = RunRecord(job_key=job_key, source=settings.source, tags=tags, start_ms=now_ms(),
                                params=flatten(params or {}), uri=settings.uri, deferred=self.defer)
        self._client = None
        self._unsent: list = []
        self._last_flush = time.monotonic()
        self._tmp_models: list[Path] = []
        self.error: Exception | None = None
        self._old_sigterm = None

    @property
    def run_id(self) -> str | None:
        return self.record.run_id if self.live else None

    @property
    def live(self) -> bool:
        return self.enabled and self.error is None and self.record.run_id is not None

    # ---- store calls: any failure switches the run to pending mode --------------------------
    def _try(self, fn) -> None:
        if self.error is not None:
            return
        attempts = 1 if self.settings.is_remote else 4   # SQLite: lock contention between parallel jobs
        for attempt in range(attempts):
            try:
                fn()
                return
            except Exception as exc:  # noqa: BLE001
                if attempt + 1 == attempts:
                    self.error = exc
                    print(f"WARNING: MLflow logging of job '{self.record.job_key}' to {self.settings.uri} failed: "
                          f"{exc}. Result files are kept; the run is logged at the next workflow start.",
                          file=sys.stderr)
                else:
                    time.sleep(0.5 * 2**attempt)

    def _open(self) -> None:
        c = self._client = client(self.settings)
        exp = experiment_id(c, self.settings)
        self.record.run_id = c.create_run(exp, start_time=self.record.start_ms, tags=self.record.tags,
                                          run_name=run_name(self.record.job_key)).info.run_id
        log_params(c, self.record.run_id, self.record.params)

    def _flush(self) -> None:
        rows, self._unsent = self._unsent, []
        self._last_flush = time.monotonic()
        if rows and self.live:
            self._try(lambda: log_metric_rows(self._client, self.record.run_id, rows))

    # ---- the job's API ----------------------------------------------------------------------
    def log_params(self, params: Mapping) -> None:
        flat = flatten(params)
        self.record.params.update(flat)
        if self.live:
            self._try(lambda: log_params(self._client, self.record.run_id, flat))

    def log_metrics(self, metrics: Mapping[str, float], step: int = 0) -> None:
        """Record ``metrics`` at ``step`` with the current time; sent in batches (non-finite dropped)."""
        if not self.enabled:
            return
        self._unsent += self.record.add_metrics(dict(metrics), step)
        if time.monotonic() - self._last_flush >= self.settings.flush_every_s:
            self._flush()

    def curve(self, name: str, every: int = 1, offset: int = 0) -> Callable[[int, float], None]:
        """A callback ``(step, value)`` that logs ``name`` as the mean of each ``every``
        consecutive values, at the window's last step + ``offset`` (per-iteration losses)."""
        window: list[float] = []

        def log(step: int, value: float) -> None:
            window.append(float(value))
            if len(window) >= every:
                self.log_metrics({name: sum(window) / len(window)}, step=step + offset)
                window.clear()
        return log

    def finish(self, metrics: Mapping[str, float] | None = None, artifacts: Sequence[str | Path] = (),
               models: Mapping[str, object] | None = None, step: int = 0, register: Mapping[str, str] | None = None) -> None:
        """After the result files are written: final metrics, the files as artifacts, models
        (``register``: model name -> registry name ``<experiment>.<name>``, a new version)."""
        if not self.enabled:
            return
        if metrics:
            self.log_metrics(metrics, step=step)
        self._flush()
        self.record.artifacts += [str(a) for a in artifacts]
        saved = self._save_models(models or {})
        self.record.models.update(saved)
        registered = {m: f"{self.settings.experiment}.{n}" for m, n in (register or {}).items() if m in saved}
        self.record.registered.update(registered)
        if self.live:
            self._try(lambda: log_files(self._client, self.record.run_id, artifacts, saved, registered))

    def _save_models(self, models: Mapping[str, object]) -> dict:
        if not models:
            return {}   # jobs without models (tables, figures, oracle) do not import torch here
        import mlflow.pytorch
        import torch

        saved = {}
        for name, module in models.items():
            tmp = Path(tempfile.mkdtemp(prefix="madpinn-model-"))
            self._tmp_models.append(tmp)
            try:
                # pickle on purpose: the safe "pt2" format needs an example input to export the
                # graph, which the MARL actors' structured observations do not give. Its warning
                # (unpickling runs code) concerns loading; the result files are the source of truth
                # and load with weights_only=True. Silenced for this call only.
                with _quiet_pickle_warning():
                    mlflow.pytorch.save_model(module, str(tmp / name), serialization_format="pickle",
                                             pip_requirements=[f"torch=={torch.__version__}"])
                saved[name] = str(tmp / name)
            except Exception as exc:  # noqa: BLE001 - the result files hold the model anyway
                print(f"WARNING: model '{name}' of job '{self.record.job_key}' not saved as an MLflow model: {exc}",
                      file=sys.stderr)
        return saved

    # ---- context --------------------------------------------------------------------------
    def __enter__(self) -> "JobRun":
        if not self.enabled:
            return self
        if not self.defer:
            self._try(self._open)
        if threading.current_thread() is threading.main_thread():
            def _killed(signum, frame):
                raise JobKilled(f"signal {signum}")
            self._old_sigterm = signal.signal(signal.SIGTERM, _killed)
        return self

    def __exit__(self, exc_type, exc, tb) -> bool:
        if self._old_sigterm is not None:
            signal.signal(signal.SIGTERM, self._old_sigterm)
        if not self.enabled:
            return False
        self.record.status = ("FINISHED" if exc_type is None else
                              "KILLED" if issubclass(exc_type, KeyboardInterrupt) else "FAILED")
        self.record.end_ms = now_ms()
        self._flush()
        if self.live:
            self._try(self._close)
        try:
            if self.live:
                remove_pending(self.settings, self.record.job_key, self.record.source)
            else:
                path = write_pending(self.settings, self.record)
                if not self.defer:
                    print(f"WARNING: MLflow run of job '{self.record.job_key}' kept as {path}; it is logged at the next "
                          f"workflow start with a reachable store.", file=sys.stderr)
        except Exception as err:  # noqa: BLE001 - never lose the job's own outcome to tracking
            print(f"WARNING: could not record the pending MLflow run of '{self.record.job_key}': {err}", file=sys.stderr)
        finally:
            for tmp in self._tmp_models:
                shutil.rmtree(tmp, ignore_errors=True)
        return False

    def _close(self) -> None:
        c, run_id = self._client, self.record.run_id
        c.set_terminated(run_id, self.record.status, end_time=self.record.end_ms)
        exp = experiment_id(c, self.settings)
        replaced = [r for r in job_runs(c, exp, self.record.job_key, self.record.source, self.settings.results)
                    if r.info.run_id != run_id]
        purge_runs(c, self.settings, replaced)


LIVE_RULES = "train_"
"""rules whose runs open in the store when their jobs start, also inside a workflow: the trainings
(``train_vhat``, ``train_defmarl``, …), whose curves are watched while they train"""


def job_run(settings, job_key: str, rule: str, wildcards: Mapping | None = None, params: Mapping | None = None,
            tags: Mapping | None = None, track: bool = True, live: bool | None = None) -> JobRun:
    """The run of one job (a context manager). ``settings``: :class:`TrackingSettings` (or the
    config mapping, parsed here); ``track=False`` (``--no-track``) logs nothing. Outside a workflow,
    or when ``live`` (default: a rule of :data:`LIVE_RULES`), the run is opened in the store when the
    job starts; inside one (``settings.deferred``) it is otherwise kept as a pending record and
    logged when the workflow ends, with the same times, status, metrics and files. (Decided here, in
    the tracking glue, so that no job's provenance hash depends on it.)"""
    if live is None:
        live = rule.startswith(LIVE_RULES)
    s = _settings(settings)
    if not track and s.enabled:
        from dataclasses import replace

        s = replace(s, enabled=False)
    return JobRun(s, job_key, rule, wildcards or {}, params, tags, defer=s.deferred and not live)


def log_job(cfg, job_key: str, rule: str, wildcards: Mapping[str, object], params: Mapping | None = None,
            metrics: Mapping[str, float] | None = None, artifacts: Sequence[str | Path] = (),
            step_metrics: Mapping[str, Sequence[float]] | None = None, models: Mapping | None = None) -> str | None:
    """Log a job that has already ended as one run (short jobs: tables, figures). Never raises."""
    with job_run(cfg, job_key=job_key, rule=rule, wildcards=wildcards, params=params) as run:
        for name, values in (step_metrics or {}).items():
            for i, v in enumerate(values):
                run.log_metrics({name: v}, step=i)
        run.finish(metrics=metrics, artifacts=artifacts, models=models)
    return run.run_id


class _PickleWarningFilter(logging.Filter):
    def filter(self, record: logging.LogRecord) -> bool:
        return "Pickle or CloudPickle" not in record.getMessage()


@contextlib.contextmanager
def _quiet_pickle_warning():
    """Drop mlflow.pytorch's pickle-format warning (only that message) inside the block."""
    logger, f = logging.getLogger("mlflow.pytorch"), _PickleWarningFilter()
    logger.addFilter(f)
    try:
        yield
    finally:
        logger.removeFilter(f)
