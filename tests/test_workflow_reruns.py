"""Reruns follow exactly what a change affects; dry runs write nothing; the report holds every
table and figure; paths with spaces work. One real tiny run of the whole DAG in a copy of the
repository whose directory and results paths contain spaces, then ``snakemake -n`` / ``--report``
against it."""

import re
import zipfile
from pathlib import Path

import pytest
import yaml

from workflow_helpers import NO_TRACKING, TINY, copy_repo, planned_jobs, run_in, tree_state, write_overlay

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
