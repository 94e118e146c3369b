# Shared paths, target lists and helpers. Later rule files register what their methods need.
import fcntl
import hashlib
import os

import yaml

from madpinn.config import ConfigError, config_hash, job_config, method_config, study_pattern, subtree_hash, write_if_changed
from madpinn.marl_hash import is_marl_model, marl_training_hash
from madpinn.scenarios import UNIFORM

# Jobs run `python -m madpinn` with the interpreter that runs this workflow (also on cluster nodes,
# where the job's snakemake parses this file again); `conda:` envs, when used, come first.
os.environ.update(PATH=os.pathsep.join([os.path.dirname(sys.executable), os.environ.get("PATH", "")]))
# Figures carry no build date (matplotlib honours SOURCE_DATE_EPOCH in PDF metadata), so a rerun
# leaves the committed paper_figures/ byte-identical when the numbers are.
os.environ.setdefault("SOURCE_DATE_EPOCH", "0")
CONDA_ENV = "../envs/madpinn.yaml"  # relative to workflow/rules/
RESULTS = config["paths"]["results"]
FIGURES = config["paths"]["figures"]
BACKEND = config["sim"]["backend"]
LOGS = f"{RESULTS}/logs"
# Training rules ask the cluster for one GPU when the config asks for CUDA (`device: cuda`).
TRAIN_GPU = {"gpu": 1} if config["device"] == "cuda" else {}

# Jobs read the merged, validated config from here. Parsing writes nothing (a dry run beside a
# running workflow must not change its config): the file is written by `onstart` below, i.e. only
# by a real run, after it holds the workflow lock, and only when its content changes. Which jobs a
# config change reruns is decided by each rule's `params` hashes (settings_hash), not by this file.
RESOLVED = f"{RESULTS}/config.resolved.yaml"

TRACKING = f"{RESULTS}/tracking/store.json"

# Snakemake's between-workflow output cache (`--cache`; on in profiles/shipped): evaluation cells
# and oracle bounds are stored under their provenance hash (rule code, params, the bytes of source
# inputs such as the shipped models, recursively the producing jobs) and restored from there when
# the same job comes again, on any machine that has the directory (docs/reliability.md). Only read
# when --cache is given; $SNAKEMAKE_OUTPUT_CACHE, when set, wins over paths.output_cache.
OUTPUT_CACHE = os.environ.setdefault(
    "SNAKEMAKE_OUTPUT_CACHE", os.path.abspath(config["paths"].get("output_cache", f"{RESULTS}/output_cache"))
)

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
    """{name: path} of the trained files run ``wildcards.run`` loads (full run name first, then method).
    Plain strings: a ``rules.X.output`` reference would pin the file's producer to rule X, and the
    shipped overlay (workflow/configs/shipped.yaml) provides it by its install rule instead."""
    models = METHOD_MODELS.get(wildcards.run, METHOD_MODELS.get(wildcards.run.split("-")[0]))
    return {k: str(v) for k, v in models(wildcards).items()} if models else {}


def model_args(wildcards):
    """``--model NAME=PATH`` options of the run's trained files, as a list (``{params.models:q}``
    quotes each item)."""
    return [a for k, v in run_models(wildcards).items() for a in ("--model", f"{k}={v}")]


def cell_key(wildcards):
    """The job's wildcards as a param: the output cache hashes a rule's code and params, not its
    wildcards, so without it every cell of one (study, run) would share one cache entry."""
    checked_cell(wildcards)
    return dict(wildcards.items())


def checked_cell(wildcards):
    """Stop with one line (dry runs too) when an evaluation cell or oracle file asked for by path is
    outside this configuration: unknown study, run or arena, or more agents than the arena holds
    (madpinn.config.check_cell: the checks validate_config makes of the configured cells)."""
    from madpinn.commands.errors import stop_workflow
    from madpinn.config import TargetError, check_cell

    w = dict(wildcards.items())
    try:
        check_cell(config, int(w["n"]), int(w["seed"]), study=w.get("study"), run=w.get("run"), arena=w.get("arena"),
                   pattern=w.get("pattern"))
    except TargetError as exc:
        where = (f"{w['study']}/{w['run']}" if "study" in w else f"{w['arena']}/{w.get('pattern', 'uniform')}")
        stop_workflow(TargetError(f"target {where} n{w['n']}_seed{w['seed']}: {exc}"))


def job_hash(wildcards):
    """Hash of the config an evaluation cell depends on (``madpinn.config.job_config``) and dtype."""
    checked_cell(wildcards)
    return config_hash({**job_config(config, wildcards.study, wildcards.run), "dtype": config["dtype"]})


def _cell_size(wildcards):
    """Agent-steps of one evaluation cell (scenarios × N × steps)."""
    st = config["studies"][wildcards.study]
    steps = config["arenas"][st["arena"]]["episode_s"] / config["sim"]["dt"]
    return int(st["scenarios"]) * int(wildcards.n) * steps


def eval_mem_mb(wildcards):
    """Memory for one cell: 1 GB plus ~50 kB per simulated agent of a scenario batch (MuJoCo state, histories)."""
    st = config["studies"][wildcards.study]
    return 1000 + int(0.05 * min(int(st["scenarios"]), int(config["sim"]["scenario_batch"])) * int(wildcards.n))


def eval_priority(wildcards):
    """Scheduling priority of a cell: ⌊log2(agent-steps)⌋ + 1 (≈ 19 for 3 agents × 100 scenarios,
    24 for 256 agents × 20 in the large arena), so the longest cells start first and do not run
    alone at the end (longest-processing-time-first); always below the trainings' 50 and 100."""
    return min(49, int(_cell_size(wildcards)).bit_length())


def eval_runtime(wildcards):
    """Slurm time limit (min) of one cell: ≤ 200 µs per agent-step (docs/performance.md), ×2 margin."""
    return 10 + int(2 * 200e-6 * _cell_size(wildcards) / 60)


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


# --- what each job depends on: config subtrees and package sources (params -> rerun-triggers) ---

def settings_hash(*keys, extra=None):
    """Hash of the config subtrees a job reads (dotted keys) plus ``extra``; a rule's ``params``
    carries it, so that a change of exactly those settings reruns the job and its dependents."""
    return subtree_hash(config, keys, extra)


PACKAGE = Path(workflow.basedir) / "madpinn"

# Parts of the package (sub-packages or modules under madpinn/) that each job family runs. Editing
# a file there reruns the family's jobs (through their `source` param) and everything downstream;
# the glue (commands, config, tracking, hints, checksums) changes no result and reruns
# nothing. Evaluation cells list their modules of `evaluation/` one by one, so that editing the
# tables, the report or the oracle does not rerun hours of cells (tests/test_workflow_sources.py
# checks every module a family's entry imports is listed).
SOURCES = {
    "value": ["dynamics", "value_functions", "observation.py", "device.py", "settings.py", "atomic.py"],
    "marl": ["dynamics", "marl", "observation.py", "scenarios.py", "device.py", "settings.py", "atomic.py"],
    "evaluate": ["dynamics", "policies/__init__.py", "policies/base.py", "simulation", "evaluation/__init__.py",
                 "evaluation/cell.py", "evaluation/metrics.py", "observation.py", "scenarios.py", "conflicts.py",
                 "device.py", "settings.py"],
    "gap": ["dynamics", "value_functions", "marl", "policies", "simulation", "evaluation/__init__.py",
            "evaluation/cell.py", "evaluation/metrics.py", "evaluation/collisions.py", "evaluation/gap.py",
            "observation.py", "scenarios.py", "conflicts.py", "device.py", "settings.py"],
    "tables": ["evaluation", "figures", "scenarios.py", "conflicts.py"],
    "report": ["evaluation", "scenarios.py", "conflicts.py"],
    "oracle": ["evaluation/oracle.py", "scenarios.py", "conflicts.py"],
    "render": ["simulation", "dynamics", "observation.py", "settings.py"],
}
# Each method's own modules, on top of SOURCES["evaluate"] for its evaluation cells: editing the
# MAD-PINN policy reruns the MAD-PINN cells, not MPPI's or the baselines' (tests/test_workflow_sources.py
# checks each method module's imports are covered). A method missing here gets the safe superset.
# Of value_functions/, a cell runs only loading and inference (VF_INFERENCE); training, the grid
# reference and the verification reach it through the trained model file, its input.
VF_INFERENCE = ["value_functions/__init__.py", "value_functions/model.py", "value_functions/problems.py",
                "value_functions/siren.py", "value_functions/symmetry.py", "value_functions/sampling.py",
                "value_functions/validation.py"]
METHOD_SOURCES = {
    "nominal": ["policies/nominal.py"],
    "madpinn": ["policies/madpinn.py", "policies/look_ahead.py", "policies/neighbours.py", "policies/z_search.py",
                "policies/safety_filter.py", "policies/cbvf_qp.py", *VF_INFERENCE],
    "mppi": ["policies/mppi.py"],
    "safemarl": ["policies/safemarl.py", "policies/safety_filter.py", "policies/cbvf_qp.py", *VF_INFERENCE, "marl"],
    "defmarl": ["policies/defmarl.py", "marl"],
}
ANY_METHOD_SOURCES = ["policies", "value_functions", "marl"]
_SOURCE_HASHES = {}


def eval_source_hash(wildcards):
    """An evaluation cell's source param: the shared evaluation code and its method's own modules."""
    method = wildcards.run.partition("-")[0]
    return f"{source_hash('evaluate')}-{source_hash(f'method:{method}')}"


SOURCE_SUFFIXES = (".py", ".yaml", ".yml", ".json", ".csv", ".xml")   # code and package data (not caches or editor files)


def _is_source(path):
    """A file of the package that a job runs or reads (``SOURCE_SUFFIXES``)."""
    return path.is_file() and path.suffix in SOURCE_SUFFIXES and "__pycache__" not in path.parts


def source_hash(family):
    """sha256 (12 hex) over the path and bytes of every file of ``SOURCES[family]`` (or, for
    ``method:<m>``, of ``METHOD_SOURCES[m]``): the .py files and the package data beside them
    (e.g. evaluation/paper_values.yaml), never caches (read only)."""
    if family not in _SOURCE_HASHES:
        if family.startswith("method:"):
            parts = METHOD_SOURCES.get(family.removeprefix("method:"), ANY_METHOD_SOURCES)
        else:
            parts = SOURCES[family]
        h = hashlib.sha256()
        for part in parts:
            root = PACKAGE / part
            files = sorted(f for f in root.rglob("*") if _is_source(f)) if root.is_dir() else [root]
            for f in files:
                h.update(b"%s\0%s\0" % (str(f.relative_to(PACKAGE)).encode(), f.read_bytes()))
        _SOURCE_HASHES[family] = h.hexdigest()[:12]
    return _SOURCE_HASHES[family]


# --- one real run at a time; recovery after kill -9 with the plain command ---
# Snakemake's own lock files survive a kill -9 and then block every later run (LockException) until
# `--unlock`; the default profile therefore sets `nolock: true` and the workflow holds an OS lock
# instead (flock on .snakemake/madpinn.lock), which the kernel releases when the process dies.
_RUN_LOCK = []


onstart:
    fh = try_run_lock()
    if fh is None:
        sys.stderr.write(f"\nmadpinn: another snakemake run is active in {os.getcwd()} (it holds {RUN_LOCK_PATH}); "
                         "wait for it to finish or stop it.\n\n")
        raise SystemExit(1)
    _RUN_LOCK.append(fh)
    if workflow.workflow_settings.cache is not None:
        os.makedirs(OUTPUT_CACHE, exist_ok=True)   # a cache entry is written after each cached job
    write_if_changed(RESOLVED, yaml.safe_dump(config, sort_keys=False))


# --- helpers of the rule files, kept here (`snakemake --lint` wants functions apart from rules) ---

def start_tracking(settings, marker):
    """At a real start, under the run lock (skipped when another run holds it: this start then
    stops in `onstart`): the store follows a changed URI, and pending runs are logged once."""
    from madpinn.tracking import flush_pending, follow_store

    if not settings.enabled:
        return
    fh = try_run_lock()
    if fh is None:
        return
    with fh:
        if follow_store(settings, marker):
            sys.stderr.write(f"madpinn: MLflow store {settings.uri} (experiment {settings.experiment}) created\n")
        if settings.pending_dir.is_dir():
            sys.stderr.write(f"madpinn: pending MLflow runs {flush_pending(settings)}\n")


RUN_LOCK_PATH = Path(".snakemake") / "madpinn.lock"


def try_run_lock():
    """The kernel lock of one real run at a time, taken without waiting: the open lock file
    (held until it is closed or the process dies), or None when another process holds it."""
    RUN_LOCK_PATH.parent.mkdir(parents=True, exist_ok=True)
    fh = open(RUN_LOCK_PATH, "a")
    try:
        fcntl.flock(fh, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        fh.close()
        return None
    return fh


def stem_of(key):
    """A params function: the named output's path without its extension (figure stems)."""
    return lambda wildcards, output: os.path.splitext(output[key])[0]


def out_dir_of(key):
    """A params function: the directory of the named output."""
    return lambda wildcards, output: os.path.dirname(output[key])


def init_model(kind):
    """The model a ``value_functions.<kind>.init_from`` fine-tuning run starts from (or nothing)."""
    path = config["value_functions"][kind].get("init_from")
    if not path:
        return []
    return [path if os.path.isabs(path) else f"{RESULTS}/{path}"]


def init_arg(kind):
    """``--model init=PATH`` when the run fine-tunes a trained model (a list: ``{params.init:q}``)."""
    return [a for p in init_model(kind) for a in ("--model", f"init={p}")]


def train_settings(kind):
    """Everything the trained weights and their summary depend on (the job's params hash)."""
    return settings_hash(f"value_functions.{kind}", "value_functions.seed", "agents", "observation", "dtype")


def train_runtime(kind):
    """Slurm time limit (min): ~1.7 min per 1000 iterations of 4 096 samples on one core, ×2 margin."""
    v = config["value_functions"][kind]
    its = int(v["iterations"]) + int((v.get("fine_tune") or {}).get("iterations", 0))
    return 10 + int(3.5 * its * int(v["batch_size"]) / 4.096e6)


def defmarl_train_hash(wildcards):
    return marl_training_hash(config, f"defmarl_{wildcards.variant}")


def safemarl_train_hash():
    return marl_training_hash(config, "safemarl_nominal")


def traj_inputs(wildcards=None):
    st = config["studies"][TRAJ["study"]]
    return [eval_path(TRAJ["study"], run, TRAJ["n_agents"], TRAJ["seed"]).replace(".parquet", "_traj.npz") for run in st["runs"]]


def run_labels(study):
    """Labels the tables and figures print for a study's runs (part of their params hash)."""
    return {run: method_config(config, run)[1].get("label", run) for run in config["studies"][study]["runs"]}


# --- oracle (oracle.smk) and reproduction report (report.smk) helpers ---

ORACLE_DIR = f"{RESULTS}/oracle"


def oracle_inputs(study):
    """Oracle files of a study: scenarios 0..S-1 of each (arena, N, seed) cell, S the study's count
    (studies with the same cells and count share them; another count is another file, so a change
    of one study's scenario count reruns nothing of another study)."""
    st = config["studies"][study]
    pattern = study_pattern(st)
    where = st["arena"] if pattern == UNIFORM else f"{st['arena']}/{pattern}"
    return [f"{ORACLE_DIR}/{where}/n{n}_seed{seed}_s{st['scenarios']}.parquet"
            for n in st["agent_counts"] for seed in st["seeds"]]


def study_models(study):
    """Model files the runs of a study load (for checksums in the report); plain strings, so that
    the shipped overlay's install rule may provide them."""
    from types import SimpleNamespace

    return sorted({str(m) for run in config["studies"][study]["runs"]
                   for m in run_models(SimpleNamespace(run=run)).values()})


def shipped_sha256(wildcards):
    """The manifest's sha256 of shipped model ``wildcards.name`` (install_shipped_model's param: a
    re-shipped model reruns its install and what uses it, nothing else)."""
    from madpinn.value_functions.shipping import read_manifest

    entry = read_manifest(SHIPPED["dir"])["models"].get(wildcards.name) or {}
    return entry.get("sha256", "missing")   # install-shipped then stops with the manifest's error


def check_shipped_models(shipped):
    """Stop before any job (dry runs included) when a shipped model (V̂, V_s or a MARL policy) is
    missing, unreadable, of another kind (V̂ and V_s swapped), not the manifest's bytes (sha256), or
    trained for another configuration than this one (madpinn.value_functions.shipping.check_shipped)."""
    from madpinn.commands.errors import stop_workflow
    from madpinn.value_functions.build import KINDS, training_hash
    from madpinn.value_functions.shipping import check_shipped

    try:
        check_shipped(shipped["dir"], {name: training_hash(config, name) if name in KINDS
                                       else marl_training_hash(config, name) if is_marl_model(name) else None
                                       for name in shipped["names"]})
    except Exception as exc:
        stop_workflow(exc)
