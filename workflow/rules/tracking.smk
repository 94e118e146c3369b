# MLflow (madpinn/tracking): checked at every start, created once, pending runs logged first.
from madpinn.tracking import TrackingSettings, check_store
from madpinn.tracking.settings import DEFER_ENV, SOURCE_ENV
from snakemake_interface_executor_plugins.settings import ExecMode

# Jobs started by this workflow tag their runs madpinn.source=workflow; runs started by hand
# (manual) never replace them.
os.environ.update({SOURCE_ENV: "workflow"})   # MADPINN_TRACKING_SOURCE, set here (not required of the user)
# Only the trainings open their runs in the store when they start (curves while they train); every
# other job keeps its run as a pending record, logged when the workflow ends (onsuccess / onerror:
# common.smk), by track_cells before it reads the cell runs (which it logs live itself), or else at
# the next start: a short job is spared MLflow's import and store connection (≈ 2.7 s of CPU each).
# Trainings: madpinn.tracking.live.LIVE_RULES. (TrackingSettings.deferred; all of it tracking glue,
# outside every provenance hash)
os.environ.update({DEFER_ENV: "1"})
TRACKING_SETTINGS = TrackingSettings.from_config(config)

# Every start, dry runs included, stops here when the store is unreachable (read-only check).
try:
    check_store(TRACKING_SETTINGS)
except Exception as exc:
    stop_workflow(exc)

# The store is brought up to date at the end of the Snakefile, after every parse-time check.


# The store and this configuration's experiment are created once, before the fan-out (parallel
# first writers race while creating a SQLite schema): at a real start by start_tracking (Snakefile);
# tracking_init writes the marker of disabled tracking and stands for the store in dry runs. Jobs
# take the marker as ancient(): a new store does not rerun finished jobs.
# `snakemake --report` lists the outputs of every job of the DAG, and the marker has no Snakemake
# metadata when start_tracking wrote it ("Missing metadata for file …/store.json"): the report needs
# no store, so its DAG leaves the marker out (also when a run is followed by --report-after-run,
# the run's own DAG keeps it).
REPORT_ONLY = any(a == "--report" or a.startswith("--report=") for a in sys.argv[1:]) and "--report-after-run" not in sys.argv
TRACKING_STORE = TRACKING
TRACKING = [] if REPORT_ONLY else ancient(TRACKING_STORE)


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


# Every evaluation cell of `all` one MLflow run, also those restored from the output cache (profile
# shipped), which run no job: after every cell, `track-cells` logs each cell that has no run here
# from its files (the evaluate job's key, params, metrics and artifacts; tag madpinn.restored=true)
# and tags every cell run with its provenance hash (madpinn/commands/cell_runs.py). Files first:
# nothing downstream reads the marker, and a disabled store makes it a no-op.
TRACKED_CELLS = f"{RESULTS}/tracking/cells.json"


rule track_cells:
    input:
        tracking=TRACKING,
        cells=lambda w: [p for s in studies_in_all() for p in study_results(s)],
    output:
        TRACKED_CELLS,
    params:
        config=RESOLVED,
    resources:
        mem_mb=1000,
        runtime=30,
    conda:
        CONDA_ENV
    log:
        f"{LOGS}/track_cells.log",
    shell:
        "(python -c 'import sys; from madpinn.tracking.flush import flush_config; flush_config(sys.argv[1:])'"
        " {params.config:q} && MADPINN_TRACKING_DEFER=0"
        " python -m madpinn track-cells --config {params.config:q} --cells {input.cells:q} --out {output:q}) 2>&1 | tee {log:q}"


register_targets(TRACKED_CELLS)
