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

# Trained files a run's policy loads: run name (`method-variant`, looked up first) or method ->
# function(wildcards) -> {name: path}, written with the training rules' outputs
# (`rules.train_vs.output.model`); each rule file of a method registers its own. The evaluate
# rule depends on these files and passes them as `--model NAME=PATH`.
METHOD_MODELS = {}

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


def run_models(wildcards):
    """{name: path} of the trained files run ``wildcards.run`` loads (full run name first, then method)."""
    models = METHOD_MODELS.get(wildcards.run, METHOD_MODELS.get(wildcards.run.split("-")[0]))
    return models(wildcards) if models else {}


def model_args(wildcards):
    """``--model NAME=PATH`` options of the run's trained files."""
    import shlex

    return " ".join(f"--model {shlex.quote(f'{k}={v}')}" for k, v in run_models(wildcards).items())


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
