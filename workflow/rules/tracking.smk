# MLflow (madpinn/tracking): checked at every start, created once, pending runs logged first.
from madpinn.tracking import TrackingError, TrackingSettings, check_store
from madpinn.tracking.settings import SOURCE_ENV
from snakemake_interface_executor_plugins.settings import ExecMode

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

# A real start (not a dry run, not a cluster job's own process) brings the store up to date while
# the workflow is parsed, before any job: the store is created when its marker is missing (fresh
# clone, or a deleted store: finished results are not recomputed), follows a changed URI, and the runs
# whose logging failed during an earlier job are logged, once. Done here and not in `onstart`,
# which Snakemake skips when every target is up to date, and not by rerunning tracking_init, which
# would hide the jobs downstream of it from that start (an ancient() input's producer masks its
# consumers in Snakemake 9's needrun pass). A dry run writes nothing. (start_tracking: common.smk)
if not workflow.output_settings.dryrun and workflow.exec_mode == ExecMode.DEFAULT:
    start_tracking(TRACKING_SETTINGS, TRACKING)


# The store and this configuration's experiment are created once, before the fan-out (parallel
# first writers race while creating a SQLite schema): at a real start by start_tracking above;
# tracking_init writes the marker of disabled tracking and stands for the store in dry runs. Jobs
# take the marker as ancient(): a new store does not rerun finished jobs.
TRACKING_STORE = TRACKING
TRACKING = ancient(TRACKING_STORE)


rule tracking_init:
    output:
        TRACKING_STORE,
    params:
        config=RESOLVED,
    resources:
        mem_mb=1000,
        runtime=10,
    conda:
        CONDA_ENV
    log:
        f"{LOGS}/tracking_init.log",
    shell:
        "python -m madpinn tracking-init --config {params.config:q} --out {output:q} 2>&1 | tee {log:q}"
