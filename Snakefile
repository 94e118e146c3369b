# madpinn workflow: train value functions and baselines, evaluate every (study, run, N, seed)
# cell, log every job to MLflow, assemble the paper's tables and figures.
#
#   snakemake -j2 all                                            # paper protocol (config.yaml)
#   snakemake -j2 all --configfile workflow/configs/smoke.yaml   # smoke run
#   snakemake -j2 table_safety_scaling                           # one output alone
import sys
from pathlib import Path

sys.path.insert(0, workflow.basedir)  # the package, also when not pip-installed

from madpinn.commands.errors import stop_workflow
from madpinn.config import WorkingDirectoryError, load_yaml, validate_config
from snakemake_interface_executor_plugins.settings import ExecMode

DEFAULT_CONFIG = Path(workflow.basedir) / "config.yaml"

# Every relative path (results/, models/, output_cache/, the profiles' config files) is taken from
# the working directory: `snakemake -s <clone>/Snakefile` run elsewhere would plan the whole protocol
# into that directory's results/. Run from the repository root, or name the directory on purpose
# with --directory (a cluster job's own process is started in place by snakemake).
_ELSEWHERE = (workflow.exec_mode == ExecMode.DEFAULT and Path.cwd().resolve() != Path(workflow.basedir).resolve()
              and not any(a.startswith(("--directory", "-d")) for a in sys.argv[1:]))
if _ELSEWHERE:
    from madpinn.run_log import remove_own_logfile

    remove_own_logfile(workflow)   # Snakemake's log of this start in .snakemake/log/: nothing stays behind
    stop_workflow(WorkingDirectoryError(f"snakemake runs in {Path.cwd()}, not in the repository {workflow.basedir}: "
                                        f"every output would go under {Path.cwd()} (results/ …)"))

# Snakemake's YAML error names neither file nor line: parse with madpinn's loader first, which
# does (file:line:column). Files given by --configfile are parsed by snakemake's command line
# before this Snakefile runs (docs/reference/reliability.md).
try:
    for _path in [DEFAULT_CONFIG, *workflow.configfiles]:
        load_yaml(_path)
except Exception as exc:
    stop_workflow(exc)   # an expected error: its one line, as the commands print it (madpinn/commands/errors.py)


configfile: str(DEFAULT_CONFIG)


try:
    validate_config(config)   # the one validator (also validate-config's and every job's): schema, cross-field
    #                           rules, and paths.results / paths.figures can be written (nothing is written here)
except Exception as exc:
    stop_workflow(exc)


report: "workflow/report/workflow.rst"


include: "workflow/rules/common.smk"
include: "workflow/rules/tracking.smk"
include: "workflow/rules/tables.smk"  # rule files register tables, models and targets (common.smk): any order
include: "workflow/rules/evaluate.smk"
include: "workflow/rules/oracle.smk"
include: "workflow/rules/train.smk"
include: "workflow/rules/validation.smk"
include: "workflow/rules/mujoco.smk"
include: "workflow/rules/safemarl.smk"
include: "workflow/rules/defmarl.smk"
include: "workflow/rules/shipped.smk"  # shipped checkpoints instead of training (workflow/configs/shipped.yaml)
include: "workflow/rules/figures.smk"
include: "workflow/rules/madpinn.smk"
include: "workflow/rules/conflicts.smk"  # structured-conflict tables, after the paper's
include: "workflow/rules/report.smk"
include: "workflow/rules/readings.smk"  # collision readings table, when contact studies are configured (issue 38)
include: "workflow/rules/gap.smk"  # gap_decomposition target, not part of all (issue 14)
include: "workflow/rules/agent_models.smk"  # table_agent_models target, not part of all (issue 63)


if workflow.workflow_settings.cache is not None:
    check_cache_kinds()   # the cache entries' files checked in common.smk are those the cached rules write
# Last, after every parse-time check has passed (a failed check writes nothing): a real start (not
# a dry run, not a cluster job's own process) brings the MLflow store marker up to date before any
# job. The marker is written when missing (fresh clone, or a deleted store: finished results are
# not recomputed) or follows a changed URI, and the runs whose logging failed during an earlier job
# are logged, once. Done here and not in `onstart`, which Snakemake skips when every target is up
# to date, and not by rerunning tracking_init, which would hide the jobs downstream of it from that
# start (an ancient() input's producer masks its consumers in Snakemake 9's needrun pass). The
# store itself is created in `onstart`, when jobs are about to run: a target refused while the DAG
# is built creates none. A dry run writes nothing. (start_tracking, open_store: common.smk; the
# settings: tracking.smk)
if not workflow.output_settings.dryrun and workflow.exec_mode == ExecMode.DEFAULT:
    start_tracking(TRACKING_SETTINGS, TRACKING_STORE)
    # The terminal output of a real run fits on a screen: progress every 10 % of the jobs, warnings
    # and errors; each job's block and output stay in its log (madpinn/run_log.py; MADPINN_LOG=full
    # or --verbose: Snakemake's complete output). Ctrl-C ends with one line: the same command resumes.
    from madpinn.run_log import install_interrupt_line, install_summary

    if not workflow.output_settings.verbose:
        install_summary()
    install_interrupt_line()


rule all:
    default_target: True
    input:
        all_targets,   # common.smk: called after every rule file registered its outputs
