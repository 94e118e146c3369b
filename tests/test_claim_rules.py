"""Issue 61: each claim rule's verdict flips on altered report cells; the verdict scale; the paper's
consistency checks flip on altered paper values; one cell is judged alike in every table."""

from __future__ import annotations

import copy
import json

import pytest
import yaml

from conftest import REPO
from madpinn.evaluation.claim_checks import DOES_NOT, HOLDS, UNSTATED, Check, claim_verdict, headline
from madpinn.evaluation.claims import build_claims
from madpinn.evaluation.paper_consistency import check_paper, least_std
from madpinn.evaluation.reproduction import PAPER_VALUES

REPORT = json.loads((REPO / "paper_figures" / "reproduction.json").read_text())
T1, T2, T3, T4 = "table_safety_scaling", "table_ours_scaling", "table_neighbour_ablation", "table_update_ablation"
NS = (3, 8, 12, 16)
BASELINES = ("defmarl-n3", "defmarl-n8", "safemarl", "mppi")


def _fig(rep, table, run, n, key, mean, half=0.005):
    c = rep[table][run][str(n)]
    c[key] = mean
    c[f"{key}_ci"] = [mean - half, mean + half]


def _vs(rep, table, run, n, key, d, half=0.005):
    rep[table][run][str(n)]["vs_ours"][key] = {"diff": d, "lo": d - half, "hi": d + half}


def _verdict(rep, claim):
    return build_claims(rep)["verdicts"][claim]


@pytest.fixture
def rep():
    return copy.deepcopy(REPORT)


def test_scale_and_unstated_readings():
    ok = lambda row, stated=True: Check("e", "o", (), True, reading="s" if stated else "alt", stated=stated, row=row)  # noqa: E731
    bad = lambda row: Check("e", "o", (), False, row=row)  # noqa: E731
    assert claim_verdict([ok("a"), bad("b")]) == "partly (1 of 2)"
    assert claim_verdict([ok("a"), bad("b"), ok("b", stated=False)]) == UNSTATED      # b holds under our reading
    assert claim_verdict([bad("a"), bad("b"), ok("b", stated=False)]) == DOES_NOT     # a holds under none
    core = Check("e", "o", (), False, essential=True, margin=5.0)
    assert headline([Check("e", "o", (), False, margin=-9.0), core]) is core


def test_best_tradeoff_ignores_safer_baselines(rep):
    for n in NS:
        _fig(rep, T1, "madpinn", n, "safety", 0.995)
        for b in BASELINES:
            _vs(rep, T1, b, n, "cost_time_avg", 0.05)
            _vs(rep, T1, b, n, "safety", 0.03)      # safer than Ours: the paper never claims otherwise
    assert _verdict(rep, "best_tradeoff") == HOLDS
    _vs(rep, T1, "mppi", 8, "cost_time_avg", -0.05)
    assert _verdict(rep, "best_tradeoff") == "partly (7 of 8)"


def test_fig2_ordering_per_baseline(rep):
    for n in NS:
        for b in (*BASELINES, "safemarl-layered", "mppi-literal"):
            _vs(rep, T1, b, n, "cost_time_avg", 0.05)
            _vs(rep, T1, b, n, "safety", -0.05)
    assert _verdict(rep, "fig2_ordering") == HOLDS
    _vs(rep, T1, "safemarl", 16, "cost_time_avg", 0.0)
    _vs(rep, T1, "safemarl", 16, "safety", 0.05)
    assert _verdict(rep, "fig2_ordering") == UNSTATED         # the layered filter still never dominates
    _vs(rep, T1, "safemarl-layered", 16, "safety", 0.05)
    _vs(rep, T1, "safemarl-layered", 16, "cost_time_avg", 0.0)
    assert _verdict(rep, "fig2_ordering") == "partly (15 of 16)"


def test_safemarl_costlier_one_verdict_per_run(rep):
    for n in NS:
        for run, d in (("safemarl", 0.1), ("safemarl-layered", 0.1)):
            _vs(rep, T1, run, n, "cost_time_avg", d)
            _vs(rep, T1, run, n, "safety", 0.0)
    assert _verdict(rep, "safemarl_costlier") == HOLDS
    for n in NS:
        _vs(rep, T1, "safemarl", n, "cost_time_avg", -0.1)
    claim = next(c for c in build_claims(rep)["claims"] if c["id"] == "safemarl_costlier")
    assert claim["verdict"] == UNSTATED and claim["readings"]["SafeMARL (layered filter)"] == HOLDS
    assert claim["readings"]["the paper's"] == "partly (4 of 8)"
    assert claim["headline"]["part"] == "cost" and "cheaper" in claim["headline"]["observed"]


def test_mppi_poor(rep):
    for n in NS:
        _vs(rep, T1, "mppi", n, "cost_time_avg", 0.05)
        _vs(rep, T1, "mppi", n, "safety", -0.05)
    assert _verdict(rep, "mppi_poor") == HOLDS
    _vs(rep, T1, "mppi", 3, "cost_time_avg", -0.05)
    assert _verdict(rep, "mppi_poor") == "partly (7 of 8)"


def test_degrade_is_comparative(rep):
    for run in ("madpinn", "defmarl-n3", "defmarl-n8", "mppi", "mppi-literal"):
        fall = 0.02 if run == "madpinn" else 0.4
        for key in ("safety", "safe_scenarios"):
            _fig(rep, T1, run, 3, key, 0.99)
            _fig(rep, T1, run, 16, key, 0.99 - fall)
    assert _verdict(rep, "defmarl_mppi_degrade") == HOLDS
    _fig(rep, T1, "madpinn", 16, "safe_scenarios", 0.5)          # Ours' safe scenarios fall as much
    assert _verdict(rep, "defmarl_mppi_degrade").startswith("partly")
    _fig(rep, T1, "defmarl-n3", 16, "safety", 0.99)              # no fall at all: essential
    assert _verdict(rep, "defmarl_mppi_degrade") == DOES_NOT


def test_safe_scenarios_high(rep):
    for n in NS:
        for run in ("madpinn", "madpinn-lookahead"):
            _fig(rep, T1, run, n, "safe_scenarios", rep[T1]["madpinn"][str(n)]["paper_safe_scenarios"])
    assert _verdict(rep, "safe_scenarios_high") == HOLDS
    _fig(rep, T1, "madpinn", 16, "safe_scenarios", 0.5)
    assert _verdict(rep, "safe_scenarios_high") == UNSTATED


def test_table2_scales(rep):
    for run in rep[T2]:
        if run.startswith("madpinn"):
            for n, c in rep[T2][run].items():
                for key in ("safety", "safe_scenarios"):
                    _fig(rep, T2, run, n, key, rep[T2]["madpinn"][n][f"paper_{key}"])
                _fig(rep, T2, run, n, "cost_time_avg", rep[T2]["madpinn"][n]["paper_cost"] - 0.1)
    assert _verdict(rep, "table2_scales") == HOLDS
    _fig(rep, T2, "madpinn", 256, "safety", 0.5)
    assert _verdict(rep, "table2_scales") == UNSTATED              # our variants still reach it
    for run in rep[T2]:
        if run.startswith("madpinn"):
            _fig(rep, T2, run, 256, "safety", 0.5)
    assert _verdict(rep, "table2_scales") == DOES_NOT


def test_neighbour_cost_names_its_convention(rep):
    for run in ("madpinn-nearest", "madpinn-random"):
        _vs(rep, T3, run, 12, "cost_time_avg", 0.1)
    claim = next(c for c in build_claims(rep)["claims"] if c["id"] == "neighbour_cost_least")
    assert claim["verdict"] == HOLDS and any("all agents" in r for r in claim["readings"])
    _vs(rep, T3, "madpinn-random", 12, "cost_time_avg", -0.1)
    assert _verdict(rep, "neighbour_cost_least") == "partly (1 of 2)"


def test_update_cost_and_sensitivity(rep):
    ks = [r for r in rep[T4] if r.startswith("madpinn-k")]
    for i, run in enumerate(ks):
        _fig(rep, T4, run, 12, "cost_time_avg", 0.5 + 0.01 * i)
        _fig(rep, T4, run, 12, "safety", 0.99 - 0.06 * i)
    assert _verdict(rep, "update_cost_rises") == HOLDS and _verdict(rep, "update_safety_more_sensitive") == HOLDS
    for i, run in enumerate(ks):
        _fig(rep, T4, run, 12, "cost_time_avg", 0.5 + 0.1 * i)
        _fig(rep, T4, run, 12, "safety", 0.99)
    assert _verdict(rep, "update_safety_more_sensitive") == DOES_NOT
    _fig(rep, T4, ks[-1], 12, "cost_time_avg", 0.3)
    assert _verdict(rep, "update_cost_rises") == DOES_NOT


def test_same_cell_judged_alike():
    values = [r for r in build_claims(REPORT)["values"] if r["figure"] == "safety" and r["n"] == 12
              and r["run"] in ("madpinn", "madpinn-value", "madpinn-k5")]
    assert len(values) == 3 and len({r["reproduces"] for r in values}) == 1
    assert all("t-interval" in r["paper"] for r in values)


def _consistency(tmp_path, edit):
    raw = yaml.safe_load(PAPER_VALUES.read_text())
    edit(raw)
    path = tmp_path / "paper_values.yaml"
    path.write_text(yaml.safe_dump(raw, allow_unicode=True))
    return [r for r in check_paper(path) if not r["holds"]]


def test_paper_consistency_flips(tmp_path):
    bad = _consistency(tmp_path, lambda r: None)
    k1 = [r for r in bad if r["run"] == "madpinn-k1"]
    assert [r["check"] for r in k1] == ["safety vs safe scenarios"]      # 99.99 % safety, 99 % safe scenarios
    assert not [r for r in bad if r["table"] == T2]                      # the ¼ at 128 / 256 agents is possible

    def fix(r):
        r["tables"][T4]["runs"]["madpinn-k1"]["n"][12]["safety"] = 0.998
    assert not [r for r in _consistency(tmp_path, fix) if r["run"] == "madpinn-k1"]

    def disagree(r):
        r["tables"][T3]["runs"]["madpinn-value"]["n"][12]["cost"] = 0.55
    assert any(r["check"] == "cost agrees across tables" for r in _consistency(tmp_path, disagree))

    def overflow(r):
        r["tables"][T1]["runs"]["safemarl"]["n"][8][1] = 0.05           # 99.8 % ± 5 % exceeds 100 %
    assert any(r["check"] == "safety: mean ± std in [0, 100 %]" for r in _consistency(tmp_path, overflow))


def test_least_std_on_a_grid():
    assert least_std(0.98, 0.98, 5, 20) == pytest.approx(0.0245, abs=1e-4)   # 1, 1, 1, 0.95, 0.95
    assert least_std(0.98, 0.98, 5, 100) == pytest.approx(0.0, abs=1e-12)
    assert least_std(0.981, 0.981, 5, 20) is None


def test_evaluate_by_hand_refuses_a_protocol_seed(tmp_path):
    """Issue 61 item 4: `python -m madpinn evaluate --seed 0` outside the workflow stops before any
    simulation unless --protocol-seed-reason says why; the workflow's jobs carry MADPINN_WORKFLOW_JOB."""
    import subprocess
    import sys

    from conftest import SMOKE, subprocess_env
    from madpinn.commands.seed_guard import MIN_VALIDATION_SEED, WORKFLOW_ENV, ProtocolSeedError, protocol_seed_reason
    from madpinn.marl.validation import MIN_VALIDATION_SEED as MARL_MIN

    env = {k: v for k, v in subprocess_env().items() if k != WORKFLOW_ENV}
    cmd = [sys.executable, "-m", "madpinn", "evaluate", "--config", str(REPO / "config.yaml"), str(SMOKE), "--study", "main",
           "--run", "nominal", "--n-agents", "3", "--seed", "0", "--out", str(tmp_path / "x.parquet"), "--no-track"]
    proc = subprocess.run(cmd, capture_output=True, text=True, env=env, cwd=tmp_path)
    assert proc.returncode == 2 and "protocol seed" in proc.stderr and "--protocol-seed-reason" in proc.stderr, proc.stderr[-2000:]
    assert list(tmp_path.glob("x*")) == []
    assert MIN_VALIDATION_SEED == MARL_MIN
    with pytest.raises(ProtocolSeedError):
        protocol_seed_reason(4, "  ", environ={})
    assert protocol_seed_reason(0, "reproduce issue 61's figure", environ={}) == "reproduce issue 61's figure"
    assert protocol_seed_reason(0, None, environ={WORKFLOW_ENV: "1"}) is None      # the workflow's own job
    assert protocol_seed_reason(100, None, environ={}) is None                     # a validation seed


def test_the_reason_is_recorded(tmp_path, monkeypatch):
    """The reason lands in the cell's JSON summary (and, as a tag, in its MLflow run)."""
    from conftest import SMOKE
    from madpinn.commands.evaluate import evaluate
    from madpinn.commands.seed_guard import REASON_KEY, WORKFLOW_ENV
    from madpinn.config import load_config

    monkeypatch.delenv(WORKFLOW_ENV, raising=False)
    cfg = load_config([REPO / "config.yaml", SMOKE])
    s = evaluate(cfg, "main", "nominal", 3, 0, tmp_path / "c.parquet", progress=False, track=False,
                 protocol_seed_reason="a test", by_hand=True)
    assert s[REASON_KEY] == "a test" and json.loads((tmp_path / "c.json").read_text())[REASON_KEY] == "a test"


def test_cost_proportional_is_a_reading_of_ours(rep):
    base = rep[T1]["madpinn"]["16"]["cost_time_avg"]
    for n in rep[T2]["madpinn"]:
        _fig(rep, T2, "madpinn", n, "cost_time_avg", 3 * base)
    claim = next(c for c in build_claims(rep)["claims"] if c["id"] == "table2_cost_proportional")
    assert claim["verdict"] == UNSTATED and all(not ch["stated"] for ch in claim["checks"])
    _fig(rep, T2, "madpinn", 256, "cost_time_avg", 6 * base)
    assert _verdict(rep, "table2_cost_proportional") == "partly (2 of 3)"


def _timing(all_pairs_ms, deployment_ms, exponent=(0.5, 0.2, 0.8)):
    rows = [{"arena": "small", "n": n, "all pairs": a, "deployment": d}
            for n, a, d in zip((3, 16, 256), all_pairs_ms, deployment_ms)]
    fit = dict(zip(("exponent", "lo", "hi"), exponent))
    return {"rows": rows, "fit": {"all pairs": fit, "deployment": fit}, "hardware": "test CPU"}


def test_timing_claim_flips():
    from madpinn.evaluation.paper_consistency import raw

    ms = raw()["protocol"]["neighbour_selection_ms"]
    verdict_of = lambda t: build_claims(REPORT, timing=t)["verdicts"]["neighbour_selection_time"]   # noqa: E731
    assert verdict_of(_timing([ms / 2] * 3, [ms / 4] * 3)) == HOLDS
    assert verdict_of(_timing([ms / 2, ms / 2, 3 * ms], [ms / 4] * 3)) == UNSTATED   # only within the sensing radius
    assert verdict_of(_timing([ms / 2] * 3, [ms / 4] * 3, exponent=(2.0, 1.5, 2.5))) == DOES_NOT
    assert "neighbour_selection_time" not in build_claims(REPORT)["verdicts"]


def test_timing_measures_every_agent_count():
    """The workflow's benchmark on a reduced config (three agent counts, one scenario, one repeat)."""
    from madpinn.config import load_config
    from madpinn.evaluation.neighbour_timing import fit_exponent, measure
    from madpinn.value_functions import load_vs

    cfg = load_config([REPO / "config.yaml"])
    cfg["studies"]["main"]["agent_counts"], cfg["studies"]["scaling"]["agent_counts"] = [3, 8], [16]
    out = measure(cfg, load_vs(REPO / "models" / "vs.pt"), count=1, repeats=1)
    assert [r["n"] for r in out["rows"]] == [3, 8, 16] and all(r["deployment"] > 0 and r["all pairs"] > 0 for r in out["rows"])
    assert out["fit"]["deployment"]["exponent"] is not None and out["hardware"]
    fit = fit_exponent([1, 2, 4, 8], [3.0, 6.0, 12.0, 24.0])
    assert fit["exponent"] == pytest.approx(1.0) and fit["lo"] == pytest.approx(1.0)


def test_heatmap_reading_and_its_claim():
    """A synthetic heatmap: cost rising with the distance to the goal, a wall of infeasible cells on
    one agent. The reading finds both; moving the minimum away from the goal flips the claim."""
    import numpy as np

    from madpinn.value_functions.heatmap_reading import heatmap_reading
    from madpinn.value_functions.validation import HEATMAP

    axis = np.linspace(-1, 1, 101)
    xx, yy = np.meshgrid(axis, axis)
    z = np.hypot(xx - HEATMAP["ego_goal"][0], yy - HEATMAP["ego_goal"][1])
    ok = np.ones_like(z, dtype=bool)
    for x, y in HEATMAP["neighbours"]:
        ok &= np.hypot(xx - x, yy - y) > 0.1
    reading = heatmap_reading(axis, z, ok, 0.1)
    assert all(a["infeasible_share"] == 1.0 for a in reading["agents"]) and reading["lowest_to_goal"] < 0.02
    verdict_of = lambda r: build_claims(REPORT, heatmap=r)["verdicts"]["value_heatmap"]   # noqa: E731
    assert verdict_of(reading) == HOLDS
    moved = heatmap_reading(axis, np.hypot(xx - 0.8, yy - 0.8), ok, 0.1)
    assert verdict_of(moved) == "partly (2 of 4)"


def test_findings_block_follows_the_files():
    from madpinn.evaluation.readme_blocks import findings_lines

    claims = json.loads((REPO / "paper_figures" / "claims.json").read_text())
    lines = findings_lines(claims, REPORT)
    assert "Table IV row \"1\"" in lines[1]
    fixed = dict(claims, consistency=[dict(r, holds=True) for r in claims["consistency"]])
    assert findings_lines(fixed, REPORT)[1].startswith("- The paper's own numbers: 0 of") and "Table IV" not in findings_lines(fixed, REPORT)[1]


def test_heatmap_reading_without_a_feasible_cell():
    import numpy as np

    from madpinn.value_functions.heatmap_reading import heatmap_reading

    axis = np.linspace(-1, 1, 21)
    reading = heatmap_reading(axis, np.zeros((21, 21)), np.zeros((21, 21), dtype=bool), 0.1)
    assert reading["median"] is None and reading["lowest_to_goal"] is None
    assert build_claims(REPORT, heatmap=reading)["verdicts"]["value_heatmap"] == "partly (2 of 4)"
