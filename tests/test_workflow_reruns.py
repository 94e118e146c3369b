"""Reruns follow exactly what a change affects; dry runs write nothing; the report holds every
table and figure; paths with spaces work. One real tiny run of the whole DAG in a copy of the
repository whose directory and results paths contain spaces, then ``snakemake -n`` / ``--report``
against it; the same DAG through ``profiles/slurm`` on a single-node Slurm cluster gives the same
tables (issue 64)."""

import os
import re
import sqlite3
import subprocess
import time
import zipfile
from collections import Counter
from pathlib import Path

import pytest
import yaml
from mlflow.entities import ViewType
from mlflow.tracking import MlflowClient

from workflow_helpers import (NO_TRACKING, TINY, LocalSlurm, copy_repo, env_for, planned_jobs, run_in, snakemake_cmd,
                              tree_state, write_overlay)

TRAININGS = {"train_vhat", "train_vs"}
TABLES = {"table_safety_scaling", "table_ours_scaling", "table_neighbour_ablation", "table_update_ablation",
          "table_conflict_pairs", "table_conflict_lines", "table_conflict_circle", "table_conflict_crossing"}
FIGURES = {"fig_cost_safety", "fig_trajectories", "fig_value_heatmap", "fig_vs_slices"}
SPACED = {"paths": {"results": "my results", "figures": "my results/fig s"}}   # quoting in every shell line


@pytest.fixture(scope="module")
def done(tmp_path_factory):
    """A copy of the repository (in a directory with a space) after a complete tiny run of ``all``
    into a results directory with a space."""
    copy = copy_repo(tmp_path_factory.mktemp("clone") / "my clone")
    write_overlay(copy / "tiny.yaml", TINY, NO_TRACKING, SPACED)
    run_in(copy, "-j2", "all", configfiles=("smoke.yaml", "tiny.yaml"))
    return copy


def _overlays(copy, *overlays):
    files = ["smoke.yaml", "tiny.yaml"]
    for i, o in enumerate(overlays):
        write_overlay(copy / f"change{i}.yaml", o)
        files.append(f"change{i}.yaml")
    return files


def _dry(copy, *overlays, targets=("all",)):
    return planned_jobs(run_in(copy, "-n", *targets, configfiles=_overlays(copy, *overlays)))


def test_complete_run_has_nothing_left_to_do(done):
    assert _dry(done) == {}


def test_paths_with_spaces_work(done):
    """Training, evaluation, tables and figures all wrote under the spaced paths, nothing elsewhere."""
    figs = done / "my results" / "fig s"
    for stem in TABLES:
        assert (figs / f"{stem}.csv").is_file(), stem
    assert (done / "my results" / "models" / "vhat.pt").is_file()
    assert not (done / "results").exists() and not (done / "my").exists()


def test_training_setting_reruns_that_training_and_its_downstream_only(done):
    jobs = _dry(done, {"value_functions": {"vhat": {"iterations": 31}}})
    # V̂ feeds the madpinn cells (main, both ablations), V̂'s validation and heatmap, and the tables
    # and figures built from those cells; V_s, the nominal cells and V_s's checks stay.
    # The reproduction report lists the models' checksums and every table: it reruns too.
    assert jobs == {"train_vhat": 1, "evaluate": 3, "validate_vhat": 1, "verify_vhat": 1, "fig_value_heatmap": 1,
                    "table_safety_scaling": 1, "table_neighbour_ablation": 1, "table_update_ablation": 1,
                    "fig_cost_safety": 1, "fig_trajectories": 1, "reproduction_report": 1, "claims_table": 1,
                    "track_cells": 1, "all": 1}, jobs   # track_cells: the changed cells' MLflow runs


def test_deployment_and_validation_settings_rerun_no_training(done):
    """With the trained V̂ and V_s in place: a deployment knob reruns the cells, never a training; a
    validation setting reruns its check alone; a training setting does retrain."""
    jobs = _dry(done, {"observation": {"carrot_margin": 0.35}})
    assert not TRAININGS & set(jobs) and jobs.get("evaluate") == 9, jobs
    assert _dry(done, {"value_functions": {"vhat": {"validation": {"samples": 1024}}}}) == {"validate_vhat": 1, "all": 1}
    assert _dry(done, {"value_functions": {"vhat": {"validation": {"scenario": {"samples": 32}}}}}) == {
        "verify_vhat": 1, "all": 1}
    assert _dry(done, {"value_functions": {"vs": {"validation": {"rollout_samples": 500}}}}) == {"validate_vs": 1, "all": 1}
    assert "train_vhat" in _dry(done, {"value_functions": {"vhat": {"iterations": 31}}})


def test_unrelated_changes_rerun_nothing(done):
    # a study the targets do not build from
    assert _dry(done, {"studies": {"main": {"scenarios": 3}}},
                targets=("table_update_ablation", "table_ours_scaling", "fig_value_heatmap")) == {}
    # methods no configured study runs, the trainings of unused baselines
    assert _dry(done, {"methods": {"mppi": {"samples": 17}, "safemarl": {"nominal": {"ppo": {"iterations": 4}}},
                                   "defmarl": {"training": {"ppo": {"iterations": 3}}}}}) == {}


def test_study_setting_reruns_that_study_only(done):
    jobs = _dry(done, {"studies": {"ablation_neighbours": {"scenarios": 2}}})
    # its cells, the oracle bounds of the new scenario count, its table, the report and the cells' MLflow runs
    assert jobs == {"evaluate": 1, "oracle": 1, "table_neighbour_ablation": 1, "reproduction_report": 1, "claims_table": 1,
                    "track_cells": 1, "all": 1}, jobs


def _edit_and_dry(copy, rel):
    path = copy / "madpinn" / rel
    original = path.read_text()
    path.write_text(original + "\n# edited by test_workflow_reruns\n")
    try:
        return _dry(copy)
    finally:
        path.write_text(original)


def test_policy_code_change_reruns_that_methods_evaluations_only(done):
    # the MAD-PINN policy: its 3 cells (main, both ablations), not the 6 nominal cells, no training
    jobs = _edit_and_dry(done, "policies/madpinn.py")
    assert jobs.get("evaluate") == 3 and not (TRAININGS & set(jobs)), jobs
    assert {"table_safety_scaling", "table_neighbour_ablation", "table_update_ablation"} <= set(jobs), jobs
    assert "table_ours_scaling" not in jobs and "table_conflict_circle" not in jobs, jobs   # nominal-only tables
    jobs = _edit_and_dry(done, "policies/nominal.py")
    assert jobs.get("evaluate") == 6 and not (TRAININGS & set(jobs)), jobs   # main, scaling, 4 conflict cells
    jobs = _edit_and_dry(done, "policies/base.py")                             # shared by every method
    assert jobs.get("evaluate") == 9 and TABLES <= set(jobs) and {"fig_cost_safety", "fig_trajectories"} <= set(jobs)
    assert _dry(done) == {}  # reverted: nothing again


def test_value_function_code_change_reruns_trainings(done):
    jobs = _edit_and_dry(done, "value_functions/train.py")
    assert TRAININGS <= set(jobs) and jobs.get("evaluate") == 3, jobs   # the madpinn cells; nominal uses no value function


def test_report_or_oracle_code_change_reruns_no_evaluation_cell(done):
    for rel in ("evaluation/reproduction.py", "evaluation/oracle.py", "evaluation/paper_values.yaml"):
        jobs = _edit_and_dry(done, rel)
        assert "reproduction_report" in jobs and "evaluate" not in jobs and not (TRAININGS & set(jobs)), (rel, jobs)


def test_figure_code_change_reruns_figures_only(done):
    # the tables' command does not import the figures (its import closure, madpinn/provenance.py)
    jobs = _edit_and_dry(done, "figures/style.py")
    assert set(jobs) == {"fig_cost_safety", "fig_trajectories", "all"}, jobs
    jobs = _edit_and_dry(done, "evaluation/tables.py")   # read by the tables, the figures and the report
    assert set(jobs) == TABLES | {"fig_cost_safety", "fig_trajectories", "reproduction_report", "claims_table", "all"}, jobs


def test_dry_run_writes_nothing(done):
    """`snakemake -n` with a changed config neither writes the resolved config nor anything else
    (Snakemake's own .snakemake/ bookkeeping aside)."""
    resolved = done / "my results" / "config.resolved.yaml"
    assert yaml.safe_load(resolved.read_text())["value_functions"]["vhat"]["iterations"] == 30
    for change in ({"value_functions": {"vhat": {"iterations": 45}}},
                   {"value_functions": {"vhat": {"iterations": 45}}, "paths": {"results": "elsewhere"}}):
        files = _overlays(done, change)
        before = tree_state(done)
        jobs = planned_jobs(run_in(done, "-n", "all", configfiles=files))
        assert "train_vhat" in jobs
        assert tree_state(done) == before


def test_report_holds_every_table_and_figure_with_captions(done):
    run_in(done, "--report", "report.zip", configfiles=("smoke.yaml", "tiny.yaml"))
    with zipfile.ZipFile(done / "report.zip") as z:
        names = z.namelist()
        html = "".join(z.read(n).decode("utf-8", "replace") for n in names if n.endswith((".html", ".js")))
    for stem in TABLES:   # each table is a page of the report (its .html; csv/md/tex beside it on disk)
        assert any(n.endswith(f"{stem}.html") for n in names), stem
    for stem in FIGURES:
        assert any(n.endswith(f"{stem}.png") for n in names), stem
    for category in ("Paper vs ours", "Paper tables", "Paper figures", "Value-function checks"):
        assert category in html
    assert "99.33" in html and "Table IV" in html  # captions carry the paper's values


def test_shell_lines_quote_every_config_derived_field():
    """Every ``{field}`` in a ``shell:`` string is ``:q``-quoted, except numbers (threads, N, seed)."""
    numeric = {"threads", "wildcards.n", "wildcards.seed", "wildcards.scenarios"}  # digits only (wildcard_constraints)
    repo = Path(__file__).resolve().parents[1]
    for smk in sorted((repo / "workflow" / "rules").glob("*.smk")):
        text = smk.read_text()
        for block in re.findall(r"shell:\n((?:\s+\".*\"\n)+)", text):
            for field in re.findall(r"(?<!\{)\{([^{}]+)\}(?!\})", block):
                name, _, spec = field.partition(":")
                assert spec == "q" or name in numeric, (smk.name, field)


SLURM_TARGETS = ("table_safety_scaling", "fig_cost_safety")
"""what the Slurm test builds: Table I's jobs in the tiny configuration and the cost-safety figure"""
SUBMITTED = re.compile(r"^Job \d+ has been submitted with SLURM jobid (\d+) \(log: (.+)\)\.$", re.M)


def _processes_naming(path: Path) -> list[str]:
    """Command lines of the live processes that name ``path`` (a job step that outlived its job)."""
    found = []
    for cmdline in Path("/proc").glob("[0-9]*/cmdline"):
        try:
            text = cmdline.read_bytes().replace(b"\0", b" ").decode(errors="replace")
        except OSError:      # gone meanwhile
            continue
        if str(path) in text:
            found.append(text[:300])
    return found


def _running_rules(db: Path) -> set[str]:
    """Rules of the jobs whose MLflow run is open (RUNNING) in the SQLite store ``db``, read-only."""
    try:
        with sqlite3.connect(f"file:{db}?mode=ro", uri=True, timeout=5) as con:
            return {r for (r,) in con.execute("SELECT t.value FROM runs r JOIN tags t ON t.run_uuid = r.run_uuid "
                                              "WHERE r.status = 'RUNNING' AND t.key = 'madpinn.rule'")}
    except sqlite3.Error:           # not created yet, or a writer holds it
        return set()


def _cancel_one_job_mid_run(proc, db: Path) -> tuple[str, str]:
    """While the workflow runs: ``scancel`` a Slurm job whose MLflow run is open (a job running
    madpinn, not just queued); returns (rule, Slurm job id) of one whose first attempt ended
    CANCELLED (a job that finished before the cancel reached it is passed over)."""
    tried = set()
    while proc.poll() is None:
        running = {c.removeprefix("rule_"): i for i, c in LocalSlurm.squeue("-t", "R", "-o", "%i|%k")}
        for rule in sorted(_running_rules(db) & set(running) - tried):   # single-job rules: comment rule_<rule>
            tried.add(rule)
            subprocess.run(["scancel", running[rule]], check=True, timeout=60)
            for _ in range(120):
                state = LocalSlurm.squeue("--states=all", "-j", running[rule], "-o", "%T")
                if state and state[0][0] not in ("RUNNING", "COMPLETING", "PENDING"):
                    break
                time.sleep(0.5)
            if state[0][0] == "CANCELLED":
                return rule, running[rule]
        time.sleep(0.2)
    pytest.fail(f"the workflow ended before a job could be cancelled mid-run (tried {sorted(tried)})")


def test_the_dag_on_a_single_node_slurm_cluster_gives_the_same_tables(done, tmp_path):
    """``scripts/local_slurm.sh`` starts munged, slurmctld and slurmd (Debian's packages); the tiny
    DAG of :data:`SLURM_TARGETS` (both trainings, MAD-PINN and nominal cells, an oracle bound, a
    table, a figure, each its own sbatch job; the validation, report and claims jobs of ``all`` run
    through Slurm in no test: they run locally in the tiny DAG fixture) runs through
    ``profiles/slurm`` (job states from ``squeue``: no slurmdbd), every job an sbatch job with its
    Slurm log; one job is cancelled (``scancel``) mid-run and retried (the profile's ``retries: 1``).
    Then: every output is one the local run of ``all`` wrote, its table equals the local one byte for
    byte, every job is one finished MLflow run; the daemons are gone and no system file is left
    behind. Not skipped in CI (CI=true): .ci/run installs the packages. (The DAG of ``all`` on Slurm
    cost 223 s of CPU in CI, every job a second snakemake inside its sbatch job; each rule's own
    sbatch request is checked by ``tests/test_workflow_profiles.py``.)"""
    why = LocalSlurm.unavailable()
    if why:
        (pytest.fail if os.environ.get("CI") == "true" else pytest.skip)(f"single-node Slurm: {why}")
    system_before = LocalSlurm.system_files()
    slurm = LocalSlurm(tmp_path / "slurm").start()
    try:
        copy = copy_repo(tmp_path / "clone")
        write_overlay(copy / "tiny.yaml", TINY)
        files = ("smoke.yaml", "tiny.yaml")
        planned = planned_jobs(run_in(copy, "-n", *SLURM_TARGETS, configfiles=files))
        assert {"train_vhat", "train_vs", "evaluate", "oracle", "table_safety_scaling", "fig_cost_safety"} <= set(planned)
        out = tmp_path / "snakemake.out"
        cmd = snakemake_cmd("--profile", "profiles/slurm", "--slurm-no-account", "--slurm-status-command", "squeue",
                            "--slurm-init-seconds-before-status-checks", "1", *SLURM_TARGETS,
                            "--configfile", "config.yaml", *files)
        with open(out, "w") as fh:
            proc = subprocess.Popen(cmd, cwd=copy, stdout=fh, stderr=subprocess.STDOUT,
                                    env=env_for(copy, {"MADPINN_LOG": "full"}))
            try:
                rule, cancelled = _cancel_one_job_mid_run(proc, copy / "mlflow" / "mlflow.db")
                assert proc.wait(timeout=2400) == 0, out.read_text()[-6000:]
            finally:
                if proc.poll() is None:
                    proc.kill()
    finally:
        slurm.stop()
    text = out.read_text()

    # every job went through sbatch, with its Slurm log; the cancelled one twice
    submitted = SUBMITTED.findall(text)
    logs = Counter(Path(log).parent for _, log in submitted)
    jobs = sum(n for r, n in planned.items() if r != "tracking_init")   # the start creates the store
    assert len(logs) == jobs and all(Path(log).is_file() for _, log in submitted), text[-4000:]
    assert {d.name if d.name.startswith("rule_") else d.parent.name for d in logs} == \
        {f"rule_{r}" for r in planned if r != "tracking_init"}
    retried = [d for d, n in logs.items() if n == 2]
    assert [d.name for d in retried] == [f"rule_{rule}"] and sum(logs.values()) == jobs + 1
    assert cancelled in {i for i, _ in submitted}

    # every output is one the local run of `all` wrote; the table equals the local one byte for byte
    local, here = done / "my results", copy / "results" / "smoke"
    def outputs(root: Path, figs: str) -> set[str]:
        return {str(p.relative_to(root)).replace(figs, "FIGS", 1) for p in root.rglob("*") if p.is_file()
                and not p.relative_to(root).parts[0] in ("logs", "tracking")}
    assert {"models/vhat.pt", "models/vs.pt", "FIGS/fig_cost_safety.png"} <= outputs(here, "paper_figures") \
        <= outputs(local, "fig s")
    tables = sorted((local / "fig s").glob("table_safety_scaling.*"))
    assert len(tables) >= 3
    for t in tables:
        assert (here / "paper_figures" / t.name).read_bytes() == t.read_bytes(), t.name

    # every job one finished MLflow run (the cancelled job's first run replaced)
    c = MlflowClient(f"sqlite:///{copy / 'mlflow' / 'mlflow.db'}")
    runs = c.search_runs([c.get_experiment_by_name("madpinn-smoke").experiment_id], run_view_type=ViewType.ALL,
                         max_results=1000)
    per_job = Counter(r.data.tags["madpinn.job"] for r in runs)
    assert set(per_job.values()) == {1} and {r.info.status for r in runs} == {"FINISHED"}
    assert Counter(r.data.tags["madpinn.rule"] for r in runs)["evaluate"] == planned["evaluate"]
    assert rule in {r.data.tags["madpinn.rule"] for r in runs}

    # the daemons and every process of the run's jobs are gone, and no system file is left behind
    assert not [p for p in slurm.pids if Path(f"/proc/{p}").exists()]
    assert not _processes_naming(copy)
    assert LocalSlurm.system_files() == system_before
