# Shared paths, target lists and helpers. Later rule files register what their methods need.
import fcntl
import os
from types import SimpleNamespace

import yaml

from madpinn.config import ConfigError, method_config, study_backend, study_pattern, vf_model_name, write_if_changed
from madpinn.evaluation.conformal_settings import conformal_studies, level_run
from madpinn.evaluation.reproduction import paper_table_numbers
from madpinn.commands import handler_entry
from madpinn.commands.seed_guard import WORKFLOW_ENV
from madpinn.machine import pinned_job_environment, planned_device
from madpinn.marl_hash import is_marl_model, marl_training_hash
from madpinn.output_cache import cache_layers, install as install_output_cache
from madpinn import source_cache
from madpinn.provenance import plugin_module, registry
from madpinn.commands import settings_hash as package_settings_hash
from madpinn.provenance import source_hash as package_source_hash
from madpinn.scenarios import UNIFORM
from snakemake_interface_executor_plugins.settings import ExecMode

# Jobs run `python -m madpinn` with the interpreter that runs this workflow (also on cluster nodes,
# where the job's snakemake parses this file again); `conda:` envs, when used, come first.
os.environ.update(PATH=os.pathsep.join([os.path.dirname(sys.executable), os.environ.get("PATH", "")]))
# Figures carry no build date (matplotlib honours SOURCE_DATE_EPOCH in PDF metadata), so a rerun
# leaves the committed paper_figures/ byte-identical when the numbers are.
os.environ.setdefault("SOURCE_DATE_EPOCH", "0")
# Marks the workflow's own jobs: `evaluate` run by hand refuses protocol seeds without a reason
# (madpinn/commands/seed_guard.py); an environment variable keeps the rules' text unchanged.
os.environ[WORKFLOW_ENV] = "1"
# What follows the machine and not the job is pinned for every job (madpinn/machine.py); a user's
# own setting of a variable wins.
for _var, _value in pinned_job_environment().items():
    os.environ.setdefault(_var, _value)
CONDA_ENV = "../envs/madpinn.yaml"  # relative to workflow/rules/
RESULTS = config["paths"]["results"]
FIGURES = config["paths"]["figures"]
BACKEND = config["sim"]["backend"]
LOGS = f"{RESULTS}/logs"
# Training rules ask the cluster for one GPU when the config asks for CUDA (`device: cuda`).
TRAIN_GPU = {"gpu": 1} if config["device"] == "cuda" else {}
# Evaluation cells run on the device they are keyed under (madpinn.machine.planned_device): a param
# of rule evaluate, so GPU and CPU cells are separate output-cache entries.
CELL_DEVICE = planned_device(config["device"])

# Jobs read the merged, validated config from here. Parsing writes nothing (a dry run beside a
# running workflow must not change its config): the file is written by `onstart` below, i.e. only
# by a real run, after it holds the workflow lock, and only when its content changes. Which jobs a
# config change reruns is decided by each rule's `params` hashes (settings_hash), not by this file.
RESOLVED = f"{RESULTS}/config.resolved.yaml"

TRACKING = f"{RESULTS}/tracking/store.json"

# Snakemake's between-workflow output cache (`--cache`; on in profiles/shipped): evaluation cells
# and oracle bounds are stored under their provenance hash (rule code, params, the bytes of source
# inputs such as the shipped models, recursively the producing jobs) and restored from there when
# the same job comes again, on any machine that has the directory (docs/reference/reliability.md).
# Two layers (madpinn/output_cache.py): the committed paths.output_cache is only read; cells
# computed anew go to the run's own layer, paths.results/output_cache, never onto an existing
# entry (`python -m madpinn publish` copies them into the committed one). $SNAKEMAKE_OUTPUT_CACHE,
# when set, is the one layer instead. Only used when --cache is given.
COMMITTED_CACHE, OUTPUT_CACHE = cache_layers(config["paths"]["output_cache"], RESULTS,
                                             os.environ.get("SNAKEMAKE_OUTPUT_CACHE"))
if workflow.workflow_settings.cache is not None:
    install_output_cache(OUTPUT_CACHE, COMMITTED_CACHE)


def check_output_cache():
    """Stop before any job (dry runs too) when an entry of the output cache is incomplete, a
    symlink, unreadable or, committed, not its committed version: one line naming the entry and
    its fix (madpinn/output_cache.py; issues 50 and 66). Snakemake restores an entry by a symlink
    and checks nothing."""
    from madpinn.commands.errors import stop_workflow
    from madpinn.output_cache import KINDS, check_entries

    try:
        if COMMITTED_CACHE is not None and COMMITTED_CACHE.is_dir():
            check_entries(COMMITTED_CACHE, KINDS)
        if OUTPUT_CACHE.is_dir():   # where another run may be storing an entry file by file
            check_entries(OUTPUT_CACHE, KINDS, complete=False, git=False)
    except Exception as exc:
        stop_workflow(exc)


def check_cache_kinds():
    """The files of one entry of each cached job are madpinn.output_cache.KINDS (what the
    check above and `python -m madpinn publish` take for one entry); called once the rules exist."""
    from madpinn.output_cache import KINDS, member_suffixes

    kinds = [member_suffixes(workflow.get_rule(r)) for r in workflow.workflow_settings.cache if workflow.is_rule(r)]
    if not set(kinds) <= set(KINDS):
        raise RuntimeError(f"the cached rules write {kinds}: update madpinn.output_cache.KINDS ({KINDS})")


if workflow.workflow_settings.cache is not None and workflow.exec_mode == ExecMode.DEFAULT:
    check_output_cache()


def kept(path):
    """An output under paths.figures, where the repository tracks the protocol run's tables and
    figures (paper_figures/): Snakemake's update() flag, so that Snakemake neither deletes it before
    its job runs (the job overwrites it) nor after the job fails (the previous version is restored):
    a failing job never deletes a committed file (issue 50 item 1)."""
    return update(path)

# --- what the rule files add, registered in one place and read lazily (when `all`, the evaluate
# rule and the report build their inputs), so that the order of the includes does not matter ---
#   targets = final outputs `all` builds besides the evaluation cells and the tables;
#   models = run name (`method-variant`, looked up first) or method -> function(wildcards) -> {name: path}
#     of the trained files its policy loads (the evaluate rule depends on them and passes them as
#     `--model NAME=PATH`);
#   tables = table name -> (study, kind), each with its own rule (register_table).
REGISTERED = {"targets": [], "models": {}, "tables": {}}


def register_targets(*paths):
    """Final outputs a rule file adds to `all`."""
    REGISTERED["targets"].extend(str(p) for p in paths)


def register_models(run, models):
    """The trained files run ``run`` (a method, or `method-variant`) loads: ``models(wildcards)`` ->
    {name: path}, written with the training rules' outputs (`rules.train_vs.output.model`)."""
    REGISTERED["models"][run] = models


def register_table(name, study, kind):
    """A table built from ``study``'s cells when the study is configured: its rule ``name``
    (`snakemake -j2 <name>`), a target of `all` and a table of the reproduction report."""
    REGISTERED["tables"][name] = (study, kind)
    if study in config["studies"]:
        table_rule(name, study, kind)


# Sections of the Snakemake report in reading order (the report sorts their names): the comparison
# with the paper and the paper's tables first. Items inside a section are ordered by their first
# label ("Table I", "Fig. 2", ...).
PAPER_TABLE_NUMBERS = paper_table_numbers()   # table name -> the paper's number (I … IV): report order
REPORT_SECTIONS = {
    "reproduction": "1 · Paper vs ours",
    "paper_tables": "2 · Paper tables (I–IV)",
    "paper_figures": "3 · Paper figures",
    "our_tables": "4 · Our tables (not in the paper)",
    "value_functions": "5 · Value-function checks",
}

wildcard_constraints:
    backend=r"[a-z_]+",
    study=r"[a-z][a-z0-9_]*",
    run=r"[a-z][a-z0-9]*(-[a-z0-9]+)?",
    n=r"\d+",
    seed=r"\d+",


def eval_path(study, run, n, seed, backend=None):
    """An evaluation cell's Parquet file; ``backend`` defaults to the study's (its sim.backend, else sim.backend)."""
    return f"{RESULTS}/eval/{backend or study_backend(config, study)}/{study}/{run}/n{n}_seed{seed}.parquet"


def study_results(study):
    st = config["studies"][study]
    return [eval_path(study, run, n, seed) for run in st["runs"] for n in st["agent_counts"] for seed in st["seeds"]]


def studies_results(studies):
    """Every cell of ``studies`` (each once, sorted): the result files a page over those studies reads."""
    return sorted({p for s in studies for p in study_results(s)})


def studies_in_all():
    """The studies whose cells `all` builds (all but those with `in_all: false`, e.g. the gap decomposition's)."""
    return [s for s, st in config["studies"].items() if st["in_all"]]


def run_models(wildcards):
    """{name: path} of the trained files run ``wildcards.run`` loads (full run name first, then method).
    Plain strings: a ``rules.X.output`` reference would pin the file's producer to rule X, and the
    shipped overlay (workflow/configs/shipped.yaml) provides it by its install rule instead."""
    registered = REGISTERED["models"]
    models = registered.get(wildcards.run, registered.get(wildcards.run.split("-")[0]))
    return {k: str(v) for k, v in models(wildcards).items()} if models else {}


def cell_models(wildcards):
    """The evaluate rule's input function (:func:`run_models` of a cell), so the first thing
    Snakemake asks of a cell: a cell outside the configuration stops here with one line, before
    any param reads its study."""
    checked_cell(wildcards)
    return run_models(wildcards)


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
    outside this configuration: unknown study, run, backend or arena, or more agents than the arena holds
    (madpinn.config.check_cell: the checks validate_config makes of the configured cells)."""
    from madpinn.commands.errors import stop_workflow
    from madpinn.config import TargetError, check_cell

    w = dict(wildcards.items())
    try:
        check_cell(config, int(w["n"]), int(w["seed"]), study=w.get("study"), run=w.get("run"), arena=w.get("arena"),
                   pattern=w.get("pattern"), backend=w.get("backend"))
    except TargetError as exc:
        where = (f"{w['study']}/{w['run']}" if "study" in w else f"{w['arena']}/{w.get('pattern', 'uniform')}")
        stop_workflow(TargetError(f"target {where} n{w['n']}_seed{w['seed']}: {exc}"))


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
    """Slurm time limit (min) of one cell: ≤ 200 µs per agent-step (docs/reference/performance.md), ×2 margin."""
    return 10 + int(2 * 200e-6 * _cell_size(wildcards) / 60)


def configured_tables():
    """Registered tables whose study is configured: name -> study."""
    return {name: study for name, (study, _) in REGISTERED["tables"].items() if study in config["studies"]}


def report_studies():
    """The studies of the configured tables (the reproduction report's)."""
    return sorted(set(configured_tables().values()))


def reading_tables():
    """Configured tables whose study also has a `<study>_contacts` collision reading (issue 38,
    readings.smk): name -> base study."""
    from madpinn.evaluation.contact_studies import CONTACTS_SUFFIX

    return {n: s for n, s in configured_tables().items() if f"{s}{CONTACTS_SUFFIX}" in config["studies"]}


def reading_studies():
    """The base studies of :func:`reading_tables` and their contact readings."""
    from madpinn.evaluation.contact_studies import CONTACTS_SUFFIX

    return sorted({st for s in reading_tables().values() for st in (s, f"{s}{CONTACTS_SUFFIX}")})


def all_targets(wildcards=None):
    """Every final output: the evaluation cells, the tables and the registered targets (an input
    function of `all`: called after every rule file has registered its part)."""
    evals = [p for study in studies_in_all() for p in study_results(study)]
    tables = [f"{FIGURES}/{name}.{ext}" for name in configured_tables() for ext in ("csv", "md", "tex")]
    return evals + tables + REGISTERED["targets"]


# --- what each job depends on: the config it reads and the package code it runs (params -> rerun-triggers) ---
# A rule's `settings` param hashes the part of the config its command's jobs read, said once by the
# package (each command's `reads`, declared beside its parser, madpinn/commands/reads.py: a trained model's own training hash, an evaluation cell's
# job_config, the subtrees a check or an output reads): a change of exactly that reruns the job and
# everything downstream; a deployment knob or a validation setting never reruns a training.

def settings_hash(command, *wildcard_names, **job):
    """The `settings` param of the jobs of `python -m madpinn <command>`, with job arguments ``job``
    (a callable one is called when the job is built) and, by name, arguments taken from each job's
    wildcards (with either, the param is a function)."""
    if wildcard_names or any(callable(v) for v in job.values()):
        return lambda wildcards: package_settings_hash(
            config, command, **{k: v() if callable(v) else v for k, v in job.items()},
            **{n: getattr(wildcards, n) for n in wildcard_names})
    return package_settings_hash(config, command, **job)


# A rule's `source` param hashes the package code its command runs, computed from the import graph
# (madpinn/provenance.py: the static closure of the command's handler, lazy imports included):
# editing a module a job imports reruns the job and everything downstream, nothing else. The glue
# (commands, config, tracking, checksums) changes no result and reruns nothing. Policies are loaded
# by name (the registry `_MODULES` of madpinn/policies/base.py), so a cell hashes its own method's
# policy module on top of the evaluate command: editing the MAD-PINN policy reruns the MAD-PINN
# cells, not MPPI's or the baselines' (tests/test_workflow_sources.py). A run's own overrides are
# applied the same way (the registry of madpinn/evaluation/cell.py, keyed by the override's config
# key): the speed governor's module is hashed into the cells of runs with an `agents` override only.
POLICY_REGISTRY = "madpinn.policies.base"
CELL_REGISTRY = "madpinn.evaluation.cell"
# Kept between snakemake starts under the digest of the package's files (madpinn/source_cache.py):
# a start (a dry run, a Slurm job step) of an unchanged package reads them instead of computing them.
_PACKAGE_DIGEST = source_cache.package_digest()
_SOURCE_HASHES = source_cache.load(_PACKAGE_DIGEST)


def source_hash(command, *methods, plugins=()):
    """sha256 (12 hex) of the package files `python -m madpinn <command>` runs, with the policy
    modules of ``methods`` (a method the registry lacks: every policy) and the ``plugins`` modules."""
    key = " ".join((command, *methods, *plugins))
    if key not in _SOURCE_HASHES:
        policies = [plugin_module(POLICY_REGISTRY, m) for m in methods]
        if None in policies:
            policies = list(registry(POLICY_REGISTRY).values())
        _SOURCE_HASHES[key] = package_source_hash(handler_entry(command), *policies, *plugins)
        source_cache.save(_PACKAGE_DIGEST, _SOURCE_HASHES)
    return _SOURCE_HASHES[key]


def eval_source_hash(wildcards):
    """An evaluation cell's source param: the evaluate command, its run's method's policy and the
    modules of the run's own overrides (e.g. `agents`: madpinn/evaluation/run_overrides.py)."""
    try:
        run_cfg = method_config(config, wildcards.run)[1]
    except ConfigError:   # an unknown run: the job itself says so in one line
        run_cfg = {}
    overrides = tuple(module for key, module in sorted(registry(CELL_REGISTRY).items()) if run_cfg.get(key))
    return source_hash("evaluate", wildcards.run.partition("-")[0], plugins=overrides)


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
        os.makedirs(OUTPUT_CACHE, exist_ok=True)   # the run's own layer: a new entry after each computed cell
    write_if_changed(RESOLVED, yaml.safe_dump(config, sort_keys=False))
    open_store(TRACKING_SETTINGS, TRACKING_STORE)


# A run that ran jobs logs the runs its short jobs kept (TrackingSettings.deferred), then ends with
# where its outputs are, one line each (Snakemake skips these hooks when there was nothing to do).
# A failed run logs them too: the jobs that finished, and the failed job's FAILED run.
onsuccess:
    log_pending_runs(TRACKING_SETTINGS)
    print_where_outputs(TRACKING_SETTINGS)


onerror:
    log_pending_runs(TRACKING_SETTINGS)


# --- helpers of the rule files, kept here (`snakemake --lint` wants functions apart from rules) ---


def start_tracking(settings, marker):
    """At a real start, under the run lock (skipped when another run holds it: this start then
    stops in `onstart`): the store marker follows a changed URI, and pending runs are logged once.
    The store itself is created by `onstart` (open_store), once the DAG is built: a refused target
    creates none."""
    from madpinn.tracking import follow_store

    if not settings.enabled:
        return
    fh = try_run_lock()
    if fh is None:
        return
    with fh:
        follow_store(settings, marker)
        log_pending_runs(settings)


def log_pending_runs(settings):
    """Under the run lock, at a start and at the end of a run: log the pending run records (kept by
    the short jobs, settings.deferred, or after a store failure). Routine, so said only when some stay
    pending; a store that fails here keeps them for the next start; never raises."""
    from madpinn.tracking import flush_pending

    if settings.enabled and settings.pending_dir.is_dir():
        try:
            counts = flush_pending(settings)
        except Exception as exc:  # noqa: BLE001 - the run's own outcome stands; the next start retries
            sys.stderr.write(f"madpinn: pending MLflow runs stay pending ({exc})\n")
            return
        if counts["failed"] or counts["kept"]:
            sys.stderr.write(f"madpinn: pending MLflow runs {counts}\n")


def open_store(settings, marker):
    """In `onstart` (jobs are about to run; under the run lock): the store and the experiment,
    created when missing and announced only then."""
    from madpinn.commands.errors import stop_workflow
    from madpinn.tracking import ensure_store

    try:
        created = ensure_store(settings, marker)
    except Exception as exc:
        stop_workflow(exc)
    if created:
        sys.stderr.write(f"madpinn: MLflow store {settings.uri} (experiment {settings.experiment}) created\n")


def print_where_outputs(settings):
    """Three lines: the tables, the report, and the command that opens the MLflow UI on this store
    (with the URL of the experiment's paper view when the store marker names the experiment)."""
    from madpinn.tracking.mlflow_store import read_marker, view_url

    mlflow_bin = os.path.relpath(os.path.join(os.path.dirname(sys.executable), "mlflow"))
    exp_id = read_marker(TRACKING_STORE).get("experiment_id")
    base = settings.uri if settings.is_remote else "http://127.0.0.1:5000"
    page = view_url(base, exp_id) if exp_id else base
    ui = (f"open {page}" if settings.is_remote else
          f"{mlflow_bin if not mlflow_bin.startswith('..') else 'mlflow'} ui --backend-store-uri {settings.uri}"
          f"  (then {page}, experiment {settings.experiment})")
    print(f"madpinn: tables  {FIGURES}/table_*.{{md,csv,tex,html}} (all beside the paper: {FIGURES}/reproduction.md)\n"
          f"madpinn: report  {FIGURES}/reproduction.html and {FIGURES}/claims.md (Snakemake's report: add --report report.zip)\n"
          f"madpinn: MLflow  {ui if settings.enabled else 'tracking disabled (tracking.enabled: false)'}", flush=True)


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


def claims_page_input(key, section, own):
    """The claims page's input of a validation-seed page: ``[own]`` (the page this run builds) when its
    overlay configures ``section``, else the published file ``claims.<key>`` names, else nothing."""
    if config[section]:
        return [own]
    from madpinn.config.paths import in_repository

    return [str(in_repository(config["claims"][key]))] if config["claims"][key] else []


def init_model(kind, variant=None):
    """The model a ``value_functions.<kind>.init_from`` fine-tuning run (of V̂ variant ``variant``:
    its merged settings) starts from (or nothing)."""
    from madpinn.config import with_vf_variant

    path = with_vf_variant(config, kind, variant)["value_functions"][kind]["init_from"]
    if not path:
        return []
    return [path if os.path.isabs(path) else f"{RESULTS}/{path}"]


def init_arg(kind, variant=None):
    """``--model init=PATH`` when the run fine-tunes a trained model (a list: ``{params.init:q}``)."""
    return [a for p in init_model(kind, variant) for a in ("--model", f"init={p}")]


def vhat_variants_used():
    """The V̂ variants (value_functions.vhat_variants) that a configured study's MAD-PINN run loads:
    only their trainings are planned."""
    return vf_variants_used("vhat")


def vf_variants_used(kind):
    """The variants of value function ``kind`` (vhat | vs: value_functions.<kind>_variants) that a
    configured study's MAD-PINN run loads (`<kind>: <name>`), and those a fine-tune among them starts
    from (its ``init_from`` names ``models/<kind>_<name>.pt``): only their trainings are planned."""
    from madpinn.config import split_vf_model

    used = {run_vf_variant(kind, run) for st in config["studies"].values() for run in st["runs"]
            if run.partition("-")[0] == "madpinn"} - {None}
    todo = list(used)
    while todo:
        for path in init_model(kind, todo.pop()):
            start = split_vf_model(os.path.splitext(os.path.basename(path))[0])
            if start and start[0] == kind and start[1] and start[1] not in used:
                used.add(start[1])
                todo.append(start[1])
    return sorted(used)


def run_vhat_variant(run):
    """The V̂ variant (value_functions.vhat_variants) a MAD-PINN run loads; None for the base V̂."""
    return run_vf_variant("vhat", run)


def run_vf_variant(kind, run):
    """The variant of value function ``kind`` (vhat | vs) a MAD-PINN run loads; None for the base one."""
    from madpinn.config import run_vhat, run_vs, split_vf_model

    return split_vf_model({"vhat": run_vhat, "vs": run_vs}[kind](config, run))[1]


def madpinn_models(wildcards):
    """The trained files a MAD-PINN run loads: its V̂ and V_s (the base ones, or the variants its
    settings name: `vhat: <name>`, `vs: <name>`, e.g. those of a study's 3-D model); a run that deploys
    a calibrated level (`conformal`, issue 62) also the calibrate-vhat report of its V̂ (rule
    calibrate_vhat), so its cells depend on the calibration. Plain strings (run_models)."""
    variant, vs_variant = run_vhat_variant(wildcards.run), run_vf_variant("vs", wildcards.run)
    vhat = (str(rules.train_vhat_variant.output.model).format(variant=variant) if variant
            else str(rules.train_vhat.output.model))
    vs = (str(rules.train_vs_variant.output.model).format(variant=vs_variant) if vs_variant
          else str(rules.train_vs.output.model))
    models = {"vhat": vhat, "vs": vs}
    if run_conformal(wildcards.run):
        models["calibration"] = calibration_report(vf_model_name("vhat", variant))
    return models


def run_conformal(run):
    """The calibrated level a MAD-PINN run deploys (`conformal`: issue 62), or None (the paper's δ = 0)."""
    try:
        return level_run(config, run)
    except ConfigError:   # an unknown run: the job itself says so in one line
        return None


def calibration_report(vhat):
    """The calibrate-vhat report (JSON) of V̂ model ``vhat`` (``vhat`` or ``vhat_<variant>``)."""
    return str(rules.calibrate_vhat.output.report).format(vhat=vhat)


def conformal_page_calibration(wildcards):
    """The one calibration the conformal page reads (checked when the page is planned, not for every target)."""
    vhats = conformal_vhats()
    if len(vhats) != 1:
        raise ValueError(f"madpinn: the calibrated levels deploy {len(vhats)} V̂ models ({vhats}); the conformal page "
                         "reads one calibration: give every level run the same V̂")
    return calibration_report(vhats[0])   # rules.calibrate_vhat


def conformal_vhats():
    """The V̂ models a configured study's run deploys a calibrated level with (their calibrations are targets)."""
    return sorted({vf_model_name("vhat", run_vhat_variant(run)) for st in config["studies"].values() for run in st["runs"]
                   if run_conformal(run)})



BUDGET_STUDIES = [st for st in ("vhat_budget", "vhat_budget_small", "vhat_budget_circle") if st in config["studies"]]
"""fig_vhat_budget's panels (issue 46): Table II's and Table I's settings and the converging crowd."""


def budget_runs():
    return list(dict.fromkeys(run for st in BUDGET_STUDIES for run in config["studies"][st]["runs"]))


def budget_vhat_args(wildcards):
    """``RUN=PATH`` of the V̂ each run of the budget studies loads (fig_vhat_budget: its training samples)."""
    return [f"{run}={madpinn_models(SimpleNamespace(run=run))['vhat']}" for run in budget_runs()]


def budget_verify_args(wildcards):
    """``RUN=PATH`` of the verify-vhat report of the V̂ each run of the budget studies loads."""
    pattern = str(rules.verify_vhat.output.report)
    return [f"{run}={pattern.format(vhat=vf_model_name('vhat', run_vhat_variant(run)))}" for run in budget_runs()]

def train_runtime(kind, variant=None):
    """Slurm time limit (min): ~1.7 min per 1000 iterations of 4 096 samples on one core, ×2 margin."""
    from madpinn.config import with_vf_variant
    from madpinn.value_functions.train_settings import TrainSettings, stage_iterations

    vf = with_vf_variant(config, kind, variant)["value_functions"]
    v = vf[kind]
    its = stage_iterations(TrainSettings.from_config(v, vf["seed"]), v["fine_tune"])   # every stage, to its stop_at
    return 10 + int(3.5 * its * int(v["batch_size"]) / 4.096e6)


def traj_inputs(wildcards=None):
    st = config["studies"][TRAJ["study"]]
    return [eval_path(TRAJ["study"], run, TRAJ["n_agents"], TRAJ["seed"]).replace(".parquet", "_traj.npz") for run in st["runs"]]


# --- tables (register_table): one rule per table, defined where the table is registered ---

def table_section(name):
    """The report section of table ``name``: the paper's tables, or ours."""
    return REPORT_SECTIONS["paper_tables" if name in PAPER_TABLE_NUMBERS else "our_tables"]


def table_labels(name, study):
    """The report labels of table ``name`` (items sort by the first: "Table I" … "Table IV")."""
    return {"Item": f"Table {PAPER_TABLE_NUMBERS[name]}" if name in PAPER_TABLE_NUMBERS else name, "Study": study}


def table_rule(name, study, kind):
    """Define the rule ``name`` that builds table ``name`` (csv, md, tex, and html, the report's page)
    of ``kind`` from ``study``."""

    rule:
        name:
            name
        input:
            tracking=TRACKING,
            results=study_results(study),
            oracle=oracle_inputs(study),
        output:
            csv=kept(f"{FIGURES}/{name}.csv"),
            md=kept(f"{FIGURES}/{name}.md"),
            tex=kept(f"{FIGURES}/{name}.tex"),
            html=report(kept(f"{FIGURES}/{name}.html"), caption=f"../report/{name}.rst", category=table_section(name),
                        labels=table_labels(name, study)),
        params:
            config=RESOLVED,
            name=name,
            kind=kind,
            settings=settings_hash("table", study=study),
            source=source_hash("table"),
            out_dir=out_dir_of("csv"),
        resources:
            mem_mb=1000,
            runtime=10,
        conda:
            CONDA_ENV
        log:
            f"{LOGS}/{name}.log",
        shell:
            "python -m madpinn table --config {params.config:q} --name {params.name:q} --kind {params.kind:q}"
            " --inputs {input.results:q} --oracle {input.oracle:q} --out-dir {params.out_dir:q} 2>&1 | tee {log:q}"


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
    from madpinn.provenance import model_training_hash
    from madpinn.value_functions.shipping import check_shipped

    try:
        check_shipped(shipped["dir"], {name: marl_training_hash(config, name) if is_marl_model(name)
                                       else model_training_hash(config, name)   # V̂, V_s, V̂ variants; else None
                                       for name in shipped["names"]})
    except Exception as exc:
        stop_workflow(exc)
