"""The whole smoke DAG through real snakemake into a real MLflow store."""

import re
import shutil
from collections import Counter
from pathlib import Path

import pandas as pd
import pytest
from mlflow.tracking import MlflowClient

from conftest import REPO, SMOKE, run_snakemake
from madpinn.machine import planned_device


def _job_counts(workdir: Path) -> Counter:
    client = MlflowClient(f"sqlite:///{workdir / 'mlflow' / 'mlflow.db'}")
    exp = client.get_experiment_by_name("madpinn-smoke")
    runs = client.search_runs([exp.experiment_id], max_results=5000)
    assert all(r.info.status == "FINISHED" for r in runs)
    return Counter(r.data.tags["madpinn.job"] for r in runs)


@pytest.fixture(scope="module")
def smoke_run(tmp_path_factory):
    workdir = tmp_path_factory.mktemp("smoke")
    proc = run_snakemake(workdir, "-j2", "all")
    (workdir / "run_stdout.txt").write_text(proc.stdout)
    return workdir


def _expected_evaluations(cfg) -> int:
    """Cells `all` builds: those of the studies without `in_all: false` (the gap decomposition's are its own target's)."""
    return sum(len(st["runs"]) * len(st["agent_counts"]) * len(st["seeds"]) for st in cfg["studies"].values()
               if st.get("in_all", True))


def test_smoke_dag_produces_tables_and_one_run_per_job(smoke_run, smoke_cfg):
    figs = smoke_run / "results" / "smoke" / "paper_figures"
    for name in ("table_safety_scaling", "table_ours_scaling"):
        for ext in ("csv", "md", "tex"):
            assert (figs / f"{name}.{ext}").stat().st_size > 0
    for name in ("fig_cost_safety", "fig_trajectories"):
        for ext in ("pdf", "png"):
            assert (figs / f"{name}.{ext}").stat().st_size > 1000
    table = pd.read_csv(figs / "table_safety_scaling.csv")
    assert set(table["n_agents"]) == {3, 16}
    assert (table["n_seeds"] == len(smoke_cfg["studies"]["main"]["seeds"])).all()
    oracle = table[table["run"] == "oracle"]
    assert len(oracle) == 2 and (oracle["cost_mean"] > 0).all()
    report = __import__("json").loads((figs / "reproduction.json").read_text())
    assert set(report) == {"table_safety_scaling", "table_ours_scaling", "table_neighbour_ablation",
                           "table_update_ablation", "table_conflict_pairs", "table_conflict_lines",
                           "table_conflict_circle", "table_conflict_crossing", "provenance"}
    assert report["table_conflict_circle"]["madpinn"]["4"]["paper_safety"] is None   # not a table of the paper
    circle = report["table_conflict_circle"]                     # its bound is on the circle-swap scenarios
    assert circle["oracle"]["4"]["cost"] <= circle["nominal"]["4"]["cost_all"] + 1e-4
    assert report["table_safety_scaling"]["madpinn"]["16"]["paper_safety"] == 0.983
    counts = _job_counts(smoke_run)
    evals = [k for k in counts if k.startswith("evaluate/")]
    assert len(evals) == _expected_evaluations(smoke_cfg) and set(counts.values()) == {1}
    assert {"table/table_safety_scaling", "figure/fig_cost_safety", "figure/fig_trajectories"} <= set(counts)


def test_every_cell_and_network_is_in_mlflow_and_committed_outputs_carry_no_commit(smoke_run, smoke_cfg):
    """track_cells saw every cell of `all` (here all computed: their own runs, restored=false, with
    the cell's figures); every trained network is a registered model; the report and claims name no
    commit (it is in results/…/provenance/, with each file's sha256), so a rerun at another commit
    leaves them byte-identical."""
    import hashlib
    import json

    ending = [ln for ln in (smoke_run / "run_stdout.txt").read_text().splitlines() if ln.startswith("madpinn: ")]
    assert [ln.split()[1] for ln in ending] == ["tables", "report", "MLflow"]      # where everything is, at the end
    assert f"ui --backend-store-uri sqlite:///{smoke_run / 'mlflow' / 'mlflow.db'}" in ending[-1]
    marker = json.loads((smoke_run / "results/smoke/tracking/cells.json").read_text())
    assert marker == {"enabled": True, "cells": _expected_evaluations(smoke_cfg), "logged": 0, "tagged": 0}
    client = MlflowClient(f"sqlite:///{smoke_run / 'mlflow' / 'mlflow.db'}")
    exp = client.get_experiment_by_name("madpinn-smoke")
    cells = client.search_runs([exp.experiment_id], "tags.`madpinn.rule` = 'evaluate'", max_results=1000)
    assert len(cells) == marker["cells"] and {r.data.tags["madpinn.restored"] for r in cells} == {"false"}
    assert all({"safety_rate", "safe_scenarios", "cost", "cost_all", "min_separation"} <= set(r.data.metrics) for r in cells)
    assert any("infeasible_share" in r.data.metrics for r in cells if r.data.params["method"] == "madpinn")
    registered = {m.name: m.latest_versions for m in client.search_registered_models()}
    assert {f"madpinn-smoke.{n}" for n in ("vs", "vhat", "safemarl_nominal", "defmarl_n3", "defmarl_n8")} <= set(registered)
    figs = smoke_run / "results" / "smoke" / "paper_figures"
    for job in ("reproduction", "claims"):
        side = json.loads((smoke_run / f"results/smoke/provenance/report__{job}.json").read_text())
        sha = side["commit"].removesuffix("-dirty")
        assert len(sha) == 40 and set(map(lambda f: Path(f).name, side["files"])) == {f"{job}.{e}" for e in ("json", "md", "html")}
        for f, digest in side["files"].items():
            data = (figs / Path(f).name).read_bytes()
            assert hashlib.sha256(data).hexdigest() == digest and sha.encode() not in data


def test_a_second_run_leaves_the_committed_outputs_byte_identical(smoke_run):
    """Rerunning a table, a figure, the report and the claims changes no byte of them."""
    figs = smoke_run / "results" / "smoke" / "paper_figures"
    before = {p.name: p.read_bytes() for p in figs.iterdir() if p.is_file()}
    proc = run_snakemake(smoke_run, "-j2", "table_safety_scaling", "fig_cost_safety", "claims_table",
                         "--forcerun", "table_safety_scaling", "fig_cost_safety", "reproduction_report")
    assert len(re.findall(r"^(local)?rule (table_safety_scaling|fig_cost_safety|reproduction_report|claims_table):",
                          proc.stdout + proc.stderr, re.M)) == 4
    after = {p.name: p.read_bytes() for p in figs.iterdir() if p.is_file()}
    assert set(after) == set(before) and [n for n in before if after[n] != before[n]] == []


def test_rerun_replaces_runs_without_duplicates(smoke_run, smoke_cfg):
    """Forced reruns of finished cells (here the cells of one table, run in parallel) replace
    their MLflow runs: one run per job afterwards, the same set of jobs."""
    before = _job_counts(smoke_run)
    proc = run_snakemake(smoke_run, "-j2", "table_ours_scaling", "--forcerun", "evaluate")
    scaling = smoke_cfg["studies"]["scaling"]
    cells = len(scaling["runs"]) * len(scaling["agent_counts"]) * len(scaling["seeds"])
    assert len(re.findall(r"^(local)?rule evaluate:", proc.stdout + proc.stderr, re.M)) == cells
    after = _job_counts(smoke_run)
    assert after == before and set(after.values()) == {1}


def test_results_are_deterministic_across_reruns(smoke_run, smoke_cfg, tmp_path):
    """A fresh run with 4 parallel writers into a new store gives identical numbers.

    The trained models are copied over (training is covered by the first run) so that this run
    is all evaluation jobs writing to MLflow concurrently: the cells of the large-arena table and
    one small-arena cell of every method (each has its own random streams). The new directory has
    no MLflow store or store marker: creating them must not retrain the finished models.
    """
    models = smoke_run / "results" / "smoke" / "models"
    if models.is_dir():
        shutil.copytree(models, tmp_path / "results" / "smoke" / "models")
    main = smoke_cfg["studies"]["main"]
    cells = [f"results/smoke/eval/{smoke_cfg['sim']['backend']}/main/{run}/n{main['agent_counts'][0]}_seed{main['seeds'][0]}.parquet"
             for run in main["runs"]]
    proc = run_snakemake(tmp_path, "-j4", "table_ours_scaling", *cells)
    assert not re.findall(r"^(local)?rule (train_|tracking_init)", proc.stdout + proc.stderr, re.M)
    fresh = sorted((tmp_path / "results" / "smoke" / "eval").rglob("*.parquet"))
    runs = {f.relative_to(tmp_path / "results" / "smoke" / "eval").parts[1:3] for f in fresh}
    assert {("main", run) for run in main["runs"]} | {("scaling", "madpinn")} <= runs
    for f in fresh:
        pd.testing.assert_frame_equal(pd.read_parquet(f), pd.read_parquet(smoke_run / f.relative_to(tmp_path)))
    assert set(_job_counts(tmp_path).values()) == {1}


def test_single_table_target_rebuilds_alone(smoke_run):
    target = smoke_run / "results" / "smoke" / "paper_figures" / "table_ours_scaling.md"
    target.unlink()
    proc = run_snakemake(smoke_run, "-j1", "table_ours_scaling")
    assert target.is_file()
    assert not re.findall(r"^(local)?rule evaluate:", proc.stdout + proc.stderr, re.M)


def test_dry_run_of_paper_config_lists_the_full_fan_out(tmp_path, paper_cfg):
    proc = run_snakemake(tmp_path, "-n", "-j2", "all", configfiles=())
    out = proc.stdout + proc.stderr
    m = re.search(r"^evaluate\s+(\d+)$", out, re.M)
    assert m and int(m.group(1)) == _expected_evaluations(paper_cfg)
    counts = paper_cfg["studies"]["main"]["agent_counts"] + paper_cfg["studies"]["scaling"]["agent_counts"]
    assert counts == [3, 8, 12, 16, 64, 128, 256]
    for n in counts:
        assert f"n{n}_seed0.parquet" in out
    assert f"--device {planned_device('auto')}" in out   # every cell is keyed under, and runs on, this machine's device
    assert not (tmp_path / "mlflow").exists()


def test_ours_overlay_runs_our_rows_without_baseline_trainings(tmp_path):
    ours = REPO / "workflow" / "configs" / "ours.yaml"
    proc = run_snakemake(tmp_path, "-n", "-j2", "all", configfiles=(ours,))
    out = proc.stdout + proc.stderr
    m = re.search(r"^evaluate\s+(\d+)$", out, re.M)
    # main, scaling (7 runs: + the labelled speed-governor row, the 2.83 m sensing row of issue 47, the
    # conflict-sampled V̂ of issue 61 and issue 62's adopted level), two ablations (seed 0), four conflict
    # studies (3 runs × 2 agent counts)
    assert m and int(m.group(1)) == 3 * 4 * 5 + 7 * 3 + 3 + 8 + 4 * 3 * 2
    assert "train_vhat" in out and "train_vs" in out
    assert "train_safemarl_nominal" not in out and "train_defmarl" not in out and "/mppi/" not in out


def test_invalid_config_fails_before_any_job(tmp_path):
    bad = tmp_path / "bad.yaml"
    bad.write_text("studies:\n  main:\n    scenarios: -3\n")
    proc = run_snakemake(tmp_path, "-j2", "all", configfiles=(SMOKE, bad), check=False)
    assert proc.returncode != 0
    assert "'studies.main.scenarios'" in proc.stderr
    assert not (tmp_path / "results" / "smoke" / "eval").exists()


def test_unreachable_tracking_server_stops_before_the_fan_out(tmp_path):
    proc = run_snakemake(tmp_path, "-j2", "all", env={"MLFLOW_TRACKING_URI": "http://127.0.0.1:9"}, check=False)
    assert proc.returncode != 0
    assert "unreachable" in proc.stdout + proc.stderr
    assert not list((tmp_path / "results" / "smoke").rglob("*.parquet"))


def report_contents(report_zip: Path) -> tuple[dict, dict]:
    """(categories: {section: [file names]}, {file name: labels}) of a `snakemake --report` zip."""
    import json
    import zipfile

    html = zipfile.ZipFile(report_zip).read("report/report.html").decode()
    cats = json.loads(re.search(r"categories = (\{.*?\});?\n", html).group(1))
    results = json.loads(re.search(r"var results = (\{.*?\});?\n", html).group(1))
    sections = {k: [Path(p).name for sub in v.values() for p in sub] for k, v in cats.items()}
    return sections, {v["name"]: v["labels"] for v in results.values()}


def test_report_holds_every_table_and_figure_in_the_papers_order(smoke_run, smoke_cfg):
    """The Snakemake report: the reproduction page first, then Tables I–IV by number, the paper's
    figures, our tables, the value-function checks (fig_vs_grid included); no metadata warning."""
    proc = run_snakemake(smoke_run, "--report", str(smoke_run / "report.zip"))
    assert "Missing metadata" not in proc.stdout + proc.stderr
    sections, labels = report_contents(smoke_run / "report.zip")
    order = sorted(sections)                                     # the report lists sections by name
    assert [s.split(" · ")[1] for s in order] == ["Paper vs ours", "Paper tables (I–IV)", "Paper figures",
                                                  "Our tables (not in the paper)", "Value-function checks"]
    assert sorted(sections[order[0]]) == ["claims.html", "reproduction.html"]   # the claims first (their label)
    assert sorted(sections[order[0]], key=lambda f: labels[f]["Item"])[0] == "claims.html"
    paper = sorted(sections[order[1]], key=lambda f: labels[f]["Item"])   # the report sorts by the first label
    assert [labels[f]["Item"] for f in paper] == ["Table I", "Table II", "Table III", "Table IV"]
    assert paper[0] == "table_safety_scaling.html"
    conflict = {f"table_{s}.html" for s in smoke_cfg["studies"] if s.startswith("conflict_")}
    assert conflict <= set(sections[order[3]])
    assert {"fig_cost_safety.png", "fig_trajectories.png", "fig_value_heatmap.png"} == set(sections[order[2]])
    assert {"fig_vs_grid.png", "fig_vs_slices.png"} <= set(sections[order[4]])
    # no section has a toggle label (the report's rule: a label after the first with two values, each on
    # half the section's items, becomes a toggle; with labels that differ per item the page fails to render)
    for section, files in sections.items():
        labelled = [labels[f] or {} for f in files]
        for key in list(labelled[0])[1:]:
            values = [lab.get(key) for lab in labelled if lab.get(key) is not None]
            assert not (len(set(values)) == 2 and all(2 * values.count(v) == len(files) for v in set(values))), \
                f"report section {section}: label {key!r} would be a toggle"
