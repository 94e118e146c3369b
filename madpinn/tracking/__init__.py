"""MLflow tracking (SPEC §11): results are files first; tracking must never lose a result."""

from madpinn.tracking.mlflow_store import TrackingError, init_store, log_job, tracking_uri

__all__ = ["TrackingError", "init_store", "log_job", "tracking_uri"]
