"""Tables with both costs and oracle rows, and the reproduction report, on a small real run
(nominal PD and smoke-scale MAD-PINN evaluated on the double integrator in a tmp copy)."""

import hashlib
import json
import subprocess
import sys

import pandas as pd
import pytest

from conftest import subprocess_env
from madpinn.commands.evaluate import evaluate
from madpinn.evaluation.oracle import OracleSettings, write_bounds
from madpinn.evaluation.reproduction import paper_values, write_report
from madpinn.evaluation.tables import format_table, load_results, summarize, table_data, write_table
from madpinn.scenarios import Arena

T = 0.5


@pytest.fixture(scope="module")
def small_run(tmp_path_factory):
    from test_madpinn_policy import models_of, tiny_cfg

    tmp = tmp_path_factory.mktemp("repro")
    cfg = tiny_cfg(tmp)
    cfg["arenas"]["small"]["episode_s"] = T
    cfg["sim"]["backend"] = "double_integrator"
    cfg["paths"]["figures"] = str(tmp / "figs")
    cfg["studies"]["main"].update(agent_counts=[3], seeds=[0, 1], scenarios=2, runs=["madpinn", "madpinn-lookahead", "nominal"])
    cfg["studies"]["ablation_update"].update(agent_counts=[3], seeds=[0], scenarios=2, runs=["madpinn-k1", "madpinn-kinf"])
    results = {"main": [], "ablation_update": []}
    for study, st in (("main", cfg["studies"]["main"]), ("ablation_update", cfg["studies"]["ablation_update"])):
        for run in st["runs"]:
            for seed in st["seeds"]:
                out = tmp / "eval" / study / run / f"n3_seed{seed}.parquet"
                evaluate(cfg, study, run, 3, seed, out, models=models_of(cfg), progress=False, track=False)
                results[study].append(out)
    oracle = [write_bounds(tmp / "oracle" / f"n3_seed{s}.parquet", Arena.from_config(cfg, "small"), 3, s, 2, 0.2,
                           OracleSettings(horizon_s=T, u_max=4.0, v_max=4.0, dt=0.025)) for s in (0, 1)]
    return cfg, tmp, results, oracle


def test_tables_show_both_costs_and_the_oracle_row(small_run):
    cfg, tmp, results, oracle = small_run
    agg = table_data(results["main"], cfg, oracle)
    ours = agg[agg["run"] != "oracle"]
    assert ours["cost_time_avg_mean"].to_numpy() == pytest.approx(ours["cost_mean"].to_numpy() / T)
    orc = agg[agg["run"] == "oracle"].iloc[0]
    assert orc["n_seeds"] == 2 and pd.isna(orc["safety_rate_mean"])
    assert (orc["cost_mean"] <= ours["cost_all_mean"] + 1e-4).all()
    table = format_table(agg, "safety_by_n")
    assert list(table.columns) == ["Method", "3 agents · Safety", "3 agents · Safe Sc.", "3 agents · Cost ÷T", "3 agents · Cum. cost",
                                   "3 agents · Cost ÷T all", "3 agents · Infeasible (z_max)"]
    assert table.iloc[-1]["Method"].startswith("Oracle") and table.iloc[-1]["3 agents · Safety"] == "–"
    # MAD-PINN's infeasible share from the cells' summaries (issue 46); none for the nominal run or the oracle
    shares = dict(zip(agg["run"], agg["infeasible_mean"]))
    assert 0.0 <= shares["madpinn"] <= 1.0 and pd.isna(shares["nominal"]) and pd.isna(shares["oracle"])
    assert table.iloc[-1]["3 agents · Infeasible (z_max)"] == "–" and table.iloc[0]["3 agents · Infeasible (z_max)"].endswith("%")
    assert "±" in table.iloc[0]["3 agents · Cost ÷T"]            # two seeds


def test_single_seed_table_has_no_spread_and_says_what_rows_are(small_run):
    cfg, tmp, results, oracle = small_run
    files = write_table("table_update_ablation", "summary", results["ablation_update"], cfg, tmp / "t", oracle[:1])
    md = files[1].read_text()
    assert "±" not in md
    assert md.startswith("| Update period k (steps) | Cost ÷T (time-avg.) | Cumulative cost ∫ (m·s) |")
    assert "Oracle (lone-agent lower bound)" in md
    assert "one seed" in files[2].read_text()
    page = files[3].read_text()                                   # the page the Snakemake report shows
    assert files[3].suffix == ".html" and "<th>Update period k (steps)</th>" in page and page.count("<tr>") == md.count("\n") - 1


def test_rows_follow_the_config_order_whatever_the_input_order(small_run):
    """The workflow passes the report its result files sorted by path ('madpinn-filtered/' before
    'madpinn/'); rows must still come in the study's configured run order."""
    cfg, _, results, _ = small_run
    paths = sorted(results["main"], key=str, reverse=True)          # nominal's files first
    assert "nominal" in str(paths[0])
    runs = list(dict.fromkeys(summarize(load_results(paths), cfg)["run"]))
    assert runs == cfg["studies"]["main"]["runs"]


def test_reproduction_report_against_a_small_run(small_run):
    cfg, tmp, results, oracle = small_run
    model = tmp / "results" / "models" / "vhat.pt"
    out = tmp / "figs"
    proc = subprocess.run(
        [sys.executable, "-m", "madpinn", "reproduction", "--config", str(_dump(cfg, tmp)), "--no-track",
         "--tables", "table_safety_scaling=main", "table_update_ablation=ablation_update",
         "--inputs", *map(str, results["main"] + results["ablation_update"]), "--oracle", *map(str, oracle),
         "--models", str(model), "--out-dir", str(out)],
        capture_output=True, text=True, env=subprocess_env(), timeout=600)
    assert proc.returncode == 0, proc.stderr[-3000:]
    rep = json.loads((out / "reproduction.json").read_text())
    cell = rep["table_safety_scaling"]["madpinn"]["3"]
    keys = {"safety", "safety_std", "safe_scenarios", "safe_scenarios_std", "cost", "cost_time_avg",
            "paper_safety", "paper_safe_scenarios", "paper_cost"}
    assert keys <= set(cell)
    assert cell["paper_safety"] == 1.0 and cell["paper_cost"] is None     # Table I: costs only plotted
    assert cell["cost_time_avg"] == pytest.approx(cell["cost"] / T)
    assert 0.0 <= cell["safety"] <= 1.0 and cell["n_seeds"] == 2
    # the paper's deployment ("Ours") first; our look-ahead extension is compared with the same paper row
    ahead = rep["table_safety_scaling"]["madpinn-lookahead"]["3"]
    assert ahead["paper_safety"] == 1.0 and "not in paper" in ahead["label"]
    assert cell["label"].startswith("Ours (paper's deployment)")
    assert list(rep["table_safety_scaling"])[:2] == ["madpinn", "madpinn-lookahead"]
    # paper rows we did not run keep the paper's value and null figures of ours
    mppi = rep["table_safety_scaling"]["mppi"]["16"]
    assert mppi["safety"] is None and mppi["paper_safety"] == pytest.approx(0.488)
    k1 = rep["table_update_ablation"]["madpinn-k1"]
    assert k1["12"]["paper_cost"] == 0.49 and k1["3"]["paper_cost"] is None and k1["3"]["safety_std"] == 0.0
    assert rep["table_safety_scaling"]["oracle"]["3"]["cost"] <= cell["cost_all"] + 1e-4
    # rows in the paper's order (k = 1, 5, …, 500, ∞), runs the paper lacks after them, the oracle last;
    # each run's agent counts ascending
    runs = list(rep["table_update_ablation"])
    assert runs[:3] == ["madpinn-k1", "madpinn-k5", "madpinn-k10"] and runs[7] == "madpinn-kinf" and runs[-1] == "oracle"
    assert all(list(c) == sorted(c, key=int) for t in ("table_safety_scaling", "table_update_ablation")
               for c in rep[t].values())
    prov = rep["provenance"]
    assert prov["models"][str(model)] == hashlib.sha256(model.read_bytes()).hexdigest()
    assert len(prov["config_hash"]) == 12 and "commit" not in prov   # the commit: the job's side file (results/provenance/)
    n_cells = sum(len(v) for v in small_run[2].values())          # every cell once, with its own timing
    assert prov["cells"]["count"] == n_cells and prov["cells"]["time_h"] > 0 and prov["cells"]["devices"] == ["cpu"]
    md = (out / "reproduction.md").read_text()
    assert "## table_update_ablation" in md and "Oracle (lone-agent lower bound)" in md and "sha256" in md
    page = (out / "reproduction.html").read_text()
    assert "<h2>table_update_ablation</h2>" in page and "<li>" in page and "&lt;" not in md and "<table>" in page
    # the look-ahead (not in the paper) is named with the run that uses it; the paper's deployment is not
    deploy = prov["deployment"]
    assert deploy["madpinn"]["look_ahead"] == cfg["methods"]["madpinn"]["look_ahead"] == 0.0
    assert deploy["madpinn-lookahead"]["look_ahead"] > 0 and deploy["madpinn-k1"]["look_ahead"] == 0.0
    assert "nominal" not in deploy
    line = next(l for l in md.splitlines() if l.startswith("- deployment not in the paper"))
    assert "`madpinn-lookahead`" in line and "keep the paper's measured state" in line
    assert "`madpinn`)" in line.split("keep the paper")[0].split(";")[-1] and "`madpinn-k1`)" in line


def test_paper_values_cite_the_tex_and_cover_tables_one_to_four():
    pv = paper_values()
    assert set(pv) == {"table_safety_scaling", "table_ours_scaling", "table_neighbour_ablation", "table_update_ablation"}
    assert set(pv["table_safety_scaling"]["runs"]) == {"madpinn", "defmarl-n3", "defmarl-n8", "safemarl", "mppi"}
    assert pv["table_ours_scaling"]["runs"]["madpinn"]["n"][256] == {"cost": 2.73, "safety": 0.9625, "safe_scenarios": 0.85}
    assert pv["table_safety_scaling"]["runs"]["madpinn"]["n"][16]["safe_scenarios_std"] == 0.027
    assert all(isinstance(r["tex_line"], int) for t in pv.values() for r in t["runs"].values())


def _dump(cfg, tmp):
    import yaml

    p = tmp / "cfg.yaml"
    p.write_text(yaml.safe_dump(cfg))
    return p


def test_figures_from_the_small_run(small_run):
    """Both figures draw from the small run's files (their look was checked by eye)."""
    import matplotlib.pyplot as plt

    from madpinn.figures.cost_safety import plot_cost_safety
    from madpinn.figures.trajectories import plot_trajectories

    cfg, tmp, results, oracle = small_run
    files = plot_cost_safety(results["main"], cfg, tmp / "f" / "fig_cost_safety", oracle)
    assert all(f.stat().st_size > 1000 for f in files)
    traj = [p.with_name(p.stem + "_traj.npz") for p in results["main"] if p.stem.endswith("seed0")]
    files = plot_trajectories(traj, [p.parent.name for p in traj], tmp / "f" / "fig_trajectories")
    assert all(f.stat().st_size > 1000 for f in files)
    plt.close("all")


def test_figures_are_byte_identical_when_redrawn(small_run):
    """A rerun of the workflow must leave the committed paper_figures/ unchanged when the numbers
    are: the PDF carries no creation date (it would differ on every run)."""
    import matplotlib.pyplot as plt

    from madpinn.figures.cost_safety import plot_cost_safety

    cfg, tmp, results, oracle = small_run
    first = [f.read_bytes() for f in plot_cost_safety(results["main"], cfg, tmp / "a" / "fig", oracle)]
    second = [f.read_bytes() for f in plot_cost_safety(results["main"], cfg, tmp / "b" / "fig", oracle)]
    assert b"/CreationDate" not in first[0]
    assert first == second
    plt.close("all")
