# MLflow (madpinn/tracking): checked at every start, created once, pending runs logged first.
from madpinn.tracking import TrackingError, TrackingSettings, check_store
from madpinn.tracking.settings import SOURCE_ENV

# Jobs started by this workflow tag their runs madpinn.source=workflow; runs started by hand
# (manual) never replace them.
os.environ.update({SOURCE_ENV: "workflow"})   # MADPINN_TRACKING_SOURCE, set here (not required of the user)
TRACKING_SETTINGS = TrackingSettings.from_config(config)

# Every start, dry runs included, stops here when the store is unreachable (read-only check).
try:
    check_store(TRACKING_SETTINGS)
except TrackingError as exc:
    sys.stderr.write(f"\nmadpinn: {exc}\n\n")
    raise SystemExit(1)

# Snakemake keeps one onstart handler: this one runs common.smk's (run lock, config.resolved.yaml)
# first, then logs the runs whose logging failed during an earlier job, once, before any job
# (onstart never runs on a dry run).
_COMMON_ONSTART = workflow._onstart


onstart:
    _COMMON_ONSTART(log)
    if TRACKING_SETTINGS.enabled and TRACKING_SETTINGS.pending_dir.is_dir():
        from madpinn.tracking import flush_pending

        counts = flush_pending(TRACKING_SETTINGS)
        sys.stderr.write(f"madpinn: pending MLflow runs {counts}\n")


# The store and this configuration's experiment are created once, before the fan-out (parallel
# first writers race while creating a SQLite schema); it reruns when the tracking URI changes, and
# when runs are pending: Snakemake calls `onstart` only when some job runs, so a start whose targets
# are all up to date still runs tracking_init and, with it, the flush above (pending_runs: common.smk) (the start after the
# flush reruns it once more, as its pending list changed back).
# Jobs take the marker as ancient(): a new store does not rerun finished jobs.
TRACKING_STORE = TRACKING
TRACKING = ancient(TRACKING_STORE)


rule tracking_init:
    output:
        TRACKING_STORE,
    params:
        config=RESOLVED,
        uri=TRACKING_SETTINGS.uri if TRACKING_SETTINGS.enabled else "disabled",
        pending=" ".join(pending_runs(TRACKING_SETTINGS)),
    resources:
        mem_mb=1000,
        runtime=10,
    conda:
        CONDA_ENV
    log:
        f"{LOGS}/tracking_init.log",
    shell:
        "python -m madpinn tracking-init --config {params.config:q} --out {output:q} 2>&1 | tee {log:q}"
