"""Issue 47: intervals, paired differences, the contact reading, the claims table and the docs that
quote it. The claims are built through the real path (cell Parquet files -> build_report ->
build_claims) on tiny synthetic cells; one changed number flips a verdict."""

from __future__ import annotations

import json
import re

import numpy as np
import pandas as pd
import pytest

from conftest import REPO
from madpinn.config import load_config
from madpinn.evaluation.claims import DOES_NOT, HOLDS, PARTLY, Check, build_claims, verdict
from madpinn.evaluation.contact import contact_distance, with_contact
from madpinn.evaluation.intervals import paired_differences, t_interval
from madpinn.evaluation.reproduction import build_report, reference_run


def _cell_rows(run: str, n: int, seed: int, cost: float, safety: float = 1.0, scenarios: int = 6) -> pd.DataFrame:
    """Scenario rows of one cell, with the columns evaluation cells write (madpinn/evaluation/metrics.py)."""
    rng = np.random.default_rng(seed)
    c = cost + 0.01 * rng.standard_normal(scenarios)
    return pd.DataFrame({
        "seed": seed, "arena": "small", "backend": "double_integrator", "method": run.partition("-")[0], "run": run,
        "study": "main", "scenario": np.arange(scenarios), "n_agents": n, "n_collided": 0,
        "safety_rate": safety, "safe": safety == 1.0, "cost_safe_mean": 3 * c, "cost_all_mean": 3 * c, "episode_s": 3.0,
        "cost_safe_time_avg": c, "cost_all_time_avg": c, "final_distance_mean": 0.0, "min_separation": 0.5,
        "safety_rate_2r": safety, "safe_2r": safety == 1.0,
        "agent_min_separation": [np.full(n, 0.5)] * scenarios, "agent_cost": [np.full(n, 3 * x) for x in c]})


def _claims_of(tmp_path, safemarl_cost: float) -> dict:
    cfg = load_config([REPO / "config.yaml"])
    cfg["studies"]["main"].update(runs=["madpinn", "safemarl"], agent_counts=[3], seeds=[0, 1, 2], scenarios=6)
    paths = []
    for run, cost in (("madpinn", 0.30), ("safemarl", safemarl_cost)):
        for seed in (0, 1, 2):
            p = tmp_path / f"{run}_{seed}_{safemarl_cost}.parquet"
            _cell_rows(run, 3, seed, cost).to_parquet(p)
            paths.append(p)
    report = build_report({"table_safety_scaling": paths}, cfg)
    return json.loads(json.dumps(report)), build_claims(json.loads(json.dumps(report)))


def test_a_changed_cell_flips_a_verdict(tmp_path):
    """SafeMARL's cost in its cells 0.40 -> 0.20: Ours stops being the cheapest (claim 1) and
    SafeMARL stops being the costlier (its claim), through the same code path as the workflow's."""
    report, costly = _claims_of(tmp_path, 0.40)
    _, cheap = _claims_of(tmp_path, 0.20)
    assert costly["verdicts"]["best_tradeoff"] == HOLDS and cheap["verdicts"]["best_tradeoff"] == "partly (1 of 2)"
    assert costly["verdicts"]["safemarl_costlier"] == HOLDS and cheap["verdicts"]["safemarl_costlier"] == "partly (1 of 2)"
    vs = report["table_safety_scaling"]["safemarl"]["3"]["vs_ours"]
    assert vs["reference"] == "madpinn" and vs["interval"] == "t over seeds" and vs["n_seeds"] == 3 and vs["n_pairs"] == 18
    assert vs["cost_time_avg"]["lo"] > 0.05                     # 0.40 − 0.30 ± jitter of 0.01
    cell = report["table_safety_scaling"]["madpinn"]["3"]
    assert cell["cost_time_avg_ci"][0] < cell["cost_time_avg"] < cell["cost_time_avg_ci"][1]
    assert cell["safety_ci"] == [1.0, 1.0] and cell["safety_contact"] == 1.0
    claim = next(c for c in cheap["claims"] if c["id"] == "best_tradeoff")
    assert claim["cells"] == ["table_safety_scaling/madpinn/N=3", "table_safety_scaling/safemarl/N=3"]


def test_verdict_rule():
    ok, bad = (Check("a", "", (), True), Check("b", "", (), False))
    core = Check("c", "", (), False, essential=True)
    assert verdict([ok, ok]) == HOLDS and verdict([ok, bad]) == f"{PARTLY} (1 of 2)" and verdict([bad]) == DOES_NOT
    assert verdict([ok, core]) == DOES_NOT


def test_t_interval_by_hand():
    lo, hi = t_interval([0.0, 1.0, 2.0, 3.0, 4.0])             # 2 ± t(0.975, 4) · √2.5 / √5
    assert lo == pytest.approx(2 - 2.7764 * np.sqrt(0.5), abs=1e-3) and hi == pytest.approx(2 + 2.7764 * np.sqrt(0.5), abs=1e-3)
    assert np.isnan(t_interval([1.0])[0])


def test_paired_differences_pair_by_scenario():
    """B = A + 0.1 on every scenario, scenarios varying widely: the paired difference is exactly 0.1
    whatever the row order (an unpaired interval would be wide)."""
    a = _cell_rows("madpinn", 3, 0, 0.3, scenarios=20)
    a["cost_safe_time_avg"] = np.linspace(0.1, 2.0, 20)
    b = a.assign(run="safemarl", cost_safe_time_avg=a["cost_safe_time_avg"] + 0.1).iloc[::-1]
    d = paired_differences(pd.concat([a, b]), "madpinn", metrics=("cost_time_avg",)).iloc[0]
    assert d["interval"] == "bootstrap over scenarios" and d["n_pairs"] == 20
    assert d["cost_time_avg_diff"] == pytest.approx(0.1) and d["cost_time_avg_diff_lo"] == pytest.approx(0.1)
    assert d["cost_time_avg_diff_hi"] == pytest.approx(0.1)


def test_reference_is_the_papers_deployment():
    cfg = load_config([REPO / "config.yaml"])
    assert reference_run(cfg, ["madpinn-nearest", "madpinn-value", "madpinn-random"]) == "madpinn-value"
    assert reference_run(cfg, ["madpinn-k1", "madpinn-k5"]) == "madpinn-k5"
    assert reference_run(cfg, ["mppi", "madpinn-lookahead", "madpinn"]) == "madpinn"
    assert reference_run(cfg, ["mppi", "madpinn-lookahead"]) is None


def test_contact_reading_counts_bodies_touching():
    from madpinn.simulation.mujoco.model import COLLISION_CYLINDER

    assert contact_distance() == pytest.approx(2 * COLLISION_CYLINDER[0]) == pytest.approx(0.12)
    df = pd.DataFrame({"agent_min_separation": [np.array([0.11, 0.125, 0.5]), np.array([0.2, 0.3, 0.4])]})
    out = with_contact(df)
    assert out["safety_rate_contact"].tolist() == pytest.approx([2 / 3, 1.0]) and out["safe_contact"].tolist() == [0.0, 1.0]
    assert with_contact(pd.DataFrame({"x": [1]}))["safety_rate_contact"].isna().all()   # old results: no separations


def test_docs_numbers_follow_config_and_cells():
    """Stale doc lines of issue 47: the V̂ sample budget against config.yaml, the Table II speeds
    against the committed cells' trajectories, and no retired run name in the results docs."""
    cfg = load_config([REPO / "config.yaml"])
    v = cfg["value_functions"]["vhat"]
    ratio = 65_536 * 100_000 / ((v["iterations"] + v["fine_tune"]["iterations"]) * v["batch_size"])
    assert f"≈ 1/{round(ratio)} of the paper's samples" in (REPO / "docs" / "reference" / "value_functions.md").read_text()
    policy = (REPO / "docs" / "reference" / "madpinn_policy.md").read_text()
    speeds = (REPO / "docs" / "findings" / "2026-11-25-large-arena-speed-limit.md").read_text()
    for doc in (policy, speeds, (REPO / "README.md").read_text()):   # the retired run is named only as the previous run's
        assert all("previous" in para for para in re.split(r"\n\s*\n|\n- ", doc) if "`madpinn-measured`" in para)
    cache = REPO / "output_cache"
    report = json.loads((REPO / "paper_figures" / "reproduction.json").read_text())
    reported = {int(n): c["safety"] for n, c in report["table_ours_scaling"]["madpinn"].items()}
    medians = {}
    for summary in cache.glob("*_summary.json"):   # the cache also keeps earlier protocols' cells:
        s = json.loads(summary.read_text())        # read the ones the committed report rests on
        if (s.get("study") == "scaling" and s.get("run") == "madpinn" and s.get("seed") == 0
                and int(s["n_agents"]) in reported
                and s.get("safety_rate") == pytest.approx(reported[int(s["n_agents"])], abs=1e-12)):
            z = np.load(summary.with_name(summary.name.replace("_summary.json", "_traj.npz")))
            speed = np.linalg.norm(np.diff(z["positions"], axis=0), axis=-1) / np.diff(z["times"])[:, None]
            medians[int(s["n_agents"])] = (np.median(speed), np.quantile(speed, 0.9))
    if not medians:
        pytest.skip("no committed Table II cells in output_cache/")
    ns = sorted(medians)
    line = (f"the median speed is {' / '.join(f'{medians[n][0]:.1f}' for n in ns)} m/s at {' / '.join(map(str, ns))} agents, "
            f"the 90th\npercentile {' / '.join(f'{medians[n][1]:.1f}' for n in ns)} m/s")
    assert line in speeds, line


def test_table_iis_claim_shows_where_its_readings_were_chosen_and_judges_only_the_final_ones(tmp_path):
    """A readings page with ``chosen_on`` (the final readings on seed 0, chosen on validation seeds): the claim
    judges the page's own readings; the validation page's summary is shown beside it and counts for nothing."""
    from madpinn.evaluation.claims_page import to_markdown

    report, _ = _claims_of(tmp_path, 0.40)
    reading = lambda study, k: {"study": study, "run": "madpinn", "horizon_s": 6.0, "checks_passed": k, "checks": 9,   # noqa: E731
                                "reproduces": k == 9, "pattern": "uniform", "failed": ""}
    final = {"protocol": reading("scaling", 3), "judged": [reading("law_within_1m", 8), reading("scaling", 3)]}
    shown = {**final, "chosen_on": {"verdict": "not reproduced under any reading tried", "closest": "law_within_1m · madpinn · T = 6 s",
                                    "readings": [["law_within_1m · madpinn · T = 6 s", "9 of 9"]]}}   # a pass there changes nothing
    plain, beside = build_claims(report, readings=final), build_claims(report, readings=shown)
    claim = lambda c: next(x for x in c["claims"] if x["id"] == "table2_readings")   # noqa: E731
    assert claim(plain)["verdict"] == claim(beside)["verdict"] == DOES_NOT and claim(beside)["checks"] == claim(plain)["checks"]
    assert "chosen_on" not in claim(plain) and claim(beside)["chosen_on"]["closest"] == "law_within_1m · madpinn · T = 6 s"
    md = to_markdown(beside)
    assert "These readings were chosen on validation seeds" in md and "Shown, not judged." in md
    assert "These readings were chosen" not in to_markdown(plain)


def test_the_protocols_claims_read_the_published_readings_verdict(tmp_path):
    """``claims.table_ii_verdict`` (config.yaml: the published page) reaches the claims job from any
    working directory; a named file that does not exist stops the plan in one line, before any job;
    an overlay that builds the readings page itself hands its own verdict instead."""
    from conftest import run_snakemake

    published = REPO / "paper_figures" / "table_ii_final" / "table_ii_readings" / "verdict.json"   # the final readings, seed 0
    assert load_config([REPO / "config.yaml"])["claims"]["table_ii_verdict"] == "paper_figures/table_ii_final/table_ii_readings/verdict.json"
    proc = run_snakemake(tmp_path, "-n", "-j1", "claims_table", configfiles=())   # the protocol's config
    assert f"--table-ii-verdict {published}" in proc.stdout + proc.stderr
    missing = tmp_path / "missing.yaml"
    missing.write_text("claims: {table_ii_verdict: paper_figures/none/verdict.json}\n")   # over the smoke overlay
    proc = run_snakemake(tmp_path, "-n", "-j1", "claims_table", configfiles=(missing,), check=False)   # smoke + a missing page
    assert proc.returncode != 0 and "'claims.table_ii_verdict': no file" in proc.stderr and "Traceback" not in proc.stderr
    proc = run_snakemake(tmp_path, "-n", "-j1", "claims_table",
                         configfiles=(missing, REPO / "workflow" / "configs" / "scenario_laws.yaml"))
    assert "--table-ii-verdict results/scenario_laws/paper_figures/table_ii_readings/verdict.json" in proc.stdout + proc.stderr


def test_every_page_the_protocols_claims_read_is_committed():
    """Each ``claims.*`` file config.yaml names is tracked by git: a clean clone validates the protocol's
    config only if the published page travelled with it (paper_figures/.gitignore ignores by default)."""
    import subprocess

    import yaml

    named = [p for p in yaml.safe_load((REPO / "config.yaml").read_text())["claims"].values() if p]
    if not (REPO / ".git").exists():
        pytest.skip("not a git checkout")
    for path in named:
        proc = subprocess.run(["git", "ls-files", "--error-unmatch", path], cwd=REPO, capture_output=True, text=True)
        assert proc.returncode == 0, f"{path} is named by config.yaml claims: but not committed (git add -f it)"


def test_rows_the_paper_lacks_are_listed_apart_and_judged_by_no_claim():
    """Issue 62: the calibrated level's rows (and every other row of ours in a paper table) appear on the
    claims page as rows "not in the paper", with their intervals; no paper row is among them."""
    from madpinn.evaluation.claim_values import rows_not_in_paper
    from madpinn.evaluation.claims_page import to_markdown
    from madpinn.evaluation.reproduction import paper_values

    report = json.loads((REPO / "paper_figures" / "reproduction.json").read_text())
    rows = rows_not_in_paper(report)
    paper_runs = {(t, r) for t, v in paper_values().items() for r in v["runs"]}
    assert rows and not [r for r in rows if (r["table"], r["run"]) in paper_runs]
    level = [r for r in rows if r["run"] == "madpinn-cpeps01" and r["table"] == "table_ours_scaling"]
    assert {r["n"] for r in level} == {64, 128, 256} and all("[" in r["safety"] and "pp" in r["vs_ours"] for r in level)
    md = to_markdown(build_claims(report))
    assert "## Rows not in the paper (not claims)" in md and f"| {level[0]['label']} | 64 |" in md
