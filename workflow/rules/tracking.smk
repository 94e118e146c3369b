# MLflow (madpinn/tracking): checked at every start, created once, pending runs logged first.
import os

from madpinn.tracking import TrackingError, TrackingSettings, check_store

# Jobs started by this workflow tag their runs madpinn.source=workflow; runs started by hand
# (manual) never replace them.
os.environ["MADPINN_TRACKING_SOURCE"] = "workflow"
TRACKING_SETTINGS = TrackingSettings.from_config(config)

# Every start, dry runs included, stops here when the store is unreachable (read-only check).
try:
    check_store(TRACKING_SETTINGS)
except TrackingError as exc:
    sys.stderr.write(f"\nmadpinn: {exc}\n\n")
    raise SystemExit(1)


# Runs whose logging failed during an earlier job are logged once, before any job (not on a dry run).
onstart:
    from madpinn.tracking import flush_pending

    if TRACKING_SETTINGS.enabled and TRACKING_SETTINGS.pending_dir.is_dir():
        counts = flush_pending(TRACKING_SETTINGS)
        print(f"madpinn: pending MLflow runs {counts}", file=sys.stderr)


# The store and this configuration's experiment are created once, before the fan-out (parallel
# first writers race while creating a SQLite schema); it reruns when the tracking URI changes.
# Jobs take the marker as ancient(): a new store does not rerun finished jobs.
TRACKING_STORE = TRACKING
TRACKING = ancient(TRACKING_STORE)


rule tracking_init:
    output:
        TRACKING_STORE,
    params:
        uri=TRACKING_SETTINGS.uri if TRACKING_SETTINGS.enabled else "disabled",
    log:
        f"{LOGS}/tracking_init.log",
    shell:
        "{PY} -m madpinn tracking-init --config {RESOLVED} --out {output} 2>&1 | tee {log}"
