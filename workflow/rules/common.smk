# Shared paths, target lists and helpers. Later rule files register what their methods need.
import yaml

from madpinn.config import config_hash, job_config, write_if_changed

PY = sys.executable
RESULTS = config["paths"]["results"]
FIGURES = config["paths"]["figures"]
BACKEND = config["sim"]["backend"]
LOGS = f"{RESULTS}/logs"

# Jobs read the merged, validated config from here (written only when it changes).
RESOLVED = f"{RESULTS}/config.resolved.yaml"
write_if_changed(RESOLVED, yaml.safe_dump(config, sort_keys=False))

TRACKING = f"{RESULTS}/tracking/store.json"

# method -> files its policy loads (trained models); rule files of each method add theirs.
METHOD_INPUTS = {}

# table name -> (study, kind); a table is built when its study is configured.
TABLES = {
    "table_safety_scaling": ("main", "safety_by_n"),
    "table_ours_scaling": ("scaling", "summary"),
}

wildcard_constraints:
    backend=r"[a-z_]+",
    study=r"[a-z_]+",
    run=r"[a-z][a-z0-9]*(-[a-z0-9]+)?",
    n=r"\d+",
    seed=r"\d+",


def eval_path(study, run, n, seed, backend=BACKEND):
    return f"{RESULTS}/eval/{backend}/{study}/{run}/n{n}_seed{seed}.parquet"


def study_results(study):
    st = config["studies"][study]
    return [eval_path(study, run, n, seed) for run in st["runs"] for n in st["agent_counts"] for seed in st["seeds"]]


def method_inputs(wildcards):
    """Files a run's policy loads: registered by full run name first, then by method."""
    return METHOD_INPUTS.get(wildcards.run, METHOD_INPUTS.get(wildcards.run.split("-")[0], []))


def job_hash(wildcards):
    return config_hash(job_config(config, wildcards.study, wildcards.run))


def table_targets():
    return [
        f"{FIGURES}/{name}.{ext}"
        for name, (study, _) in TABLES.items()
        if study in config["studies"]
        for ext in ("csv", "md", "tex")
    ]


def all_targets():
    evals = [p for study in config["studies"] for p in study_results(study)]
    return evals + table_targets()


# Rule files included later may extend this list (figures, validation outputs).
EXTRA_TARGETS = []
