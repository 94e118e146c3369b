"""MLflow tracking (SPEC §11): results are files first; tracking never loses a result.

How a job logs (one live run per job, opened when the job starts)::

    from madpinn.tracking import TrackingSettings, job_run

    settings = TrackingSettings.from_config(cfg)          # once, at the top (or pass cfg)
    with job_run(settings, job_key="train/vhat", rule="train_vhat", wildcards={"kind": "vhat"},
                 params={...}, track=not args.no_track) as run:
        ...                                                # the job's work
        run.log_metrics({"loss": 0.12}, step=it)          # curves as they happen (batched sends)
        ...                                                # write the result files FIRST
        run.finish(metrics=summary, artifacts=[out, csv], models={"model": net})

The run closes with the job's real status (FINISHED / FAILED on an exception / KILLED on
SIGINT-SIGTERM) and real start and end times; it replaces earlier runs of the same ``job_key``
from the same source (``workflow`` inside snakemake, ``manual`` otherwise — tag
``madpinn.source``) and deletes them permanently on a database store. A store failure never
raises: the run's record goes to ``<results>/tracking/pending/`` and the next workflow start
logs it (:func:`flush_pending`). Short jobs whose whole output exists at once may call
:func:`log_job` (the same thing in one call).

Modules: ``settings`` (TrackingSettings, URI, source), ``mlflow_store`` (reachability, store and
experiment, permanent purge), ``record`` (run records, pending files), ``live`` (JobRun).
"""

from madpinn.tracking.live import JobKilled, JobRun, job_run, log_job
from madpinn.tracking.mlflow_store import TrackingError, check_store, ensure_store, follow_store, init_store, purge_runs, write_marker
from madpinn.tracking.record import flush_pending
from madpinn.tracking.settings import TrackingSettings, tracking_uri

__all__ = ["JobKilled", "JobRun", "TrackingError", "TrackingSettings", "check_store", "ensure_store", "flush_pending", "follow_store", "init_store",
           "job_run", "log_job", "purge_runs", "tracking_uri", "write_marker"]
