"""Table II readings (issue 60): the pre-registered scale judges each reading, the claim's verdict
names the readings it rests on, the start/goal law rule reads hazards against the anchor, and the
command writes its page from cell files. Scenario rows are built with known figures, so every
expected check follows by construction."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pandas as pd
import pytest

from conftest import REPO
from madpinn.config import ConfigError, deep_merge, load_config, validate_config
from madpinn.evaluation.paired_effects import paired_effects
from madpinn.evaluation.table_ii_readings import (PaperRow, baseline_reading, claim_verdict, horizons_of, judge, law_reading, law_rule,
                                                  reading_rows)
from madpinn.evaluation.table_ii_settings import ReadingsSettings

PAPER = PaperRow({64: {"safety": 1.0, "safe_scenarios": 1.0, "cost": 1.09},
                  128: {"safety": 0.9875, "safe_scenarios": 0.95, "cost": 1.68},
                  256: {"safety": 0.9625, "safe_scenarios": 0.85, "cost": 2.73}})
T = 6.0


def cell(study: str, run: str, n: int, seed: int, safety: float, cost_int: float, *, scenarios: int = 20,
         load: float = 2.5, pattern: str = "uniform", arena: str = "large", at: dict | None = None) -> pd.DataFrame:
    """``scenarios`` scenario rows of one cell: every scenario with the same safety and costs (so
    the cell's figures are exactly these), ``safe`` true where safety is 1, a fixed load; ``at``:
    {H: (safety, cost_int)} for the ``_at_<H>s`` columns."""
    rows = []
    for s in range(scenarios):
        row = {"study": study, "run": run, "n_agents": n, "seed": seed, "scenario": s, "arena": arena,
               "episode_s": T, "pattern": pattern, "safety_rate": safety, "safe": safety == 1.0,
               "cost_safe_mean": cost_int, "cost_safe_time_avg": cost_int / T,
               "cost_all_mean": cost_int, "cost_all_time_avg": cost_int / T, "encounters_per_agent": load}
        for h, (sa, c) in (at or {}).items():
            row.update({f"safety_rate_at_{h:g}s": sa, f"safe_at_{h:g}s": sa == 1.0, f"cost_safe_mean_at_{h:g}s": c,
                        f"cost_safe_time_avg_at_{h:g}s": c / h, f"cost_all_mean_at_{h:g}s": c,
                        f"cost_all_time_avg_at_{h:g}s": c / h})
        rows.append(row)
    return pd.DataFrame(rows)


def reading(study: str, run: str, safety: dict, cost: dict, **kw) -> pd.DataFrame:
    return pd.concat([cell(study, run, n, 100, safety[n], cost[n], **kw) for n in (64, 128, 256)], ignore_index=True)


PAPER_SAFETY = {n: c["safety"] for n, c in PAPER.cells.items()}
PAPER_COST_INT = {n: c["cost"] for n, c in PAPER.cells.items()}   # the paper's cost read as an integral


def test_a_reading_at_the_paper_values_reproduces_and_one_short_point_fails_one_check():
    rows = reading_rows(pd.concat([
        reading("law_a", "madpinn", {64: 1.0, 128: 1.0, 256: 1.0}, PAPER_COST_INT),
        reading("law_b", "madpinn", {64: 1.0, 128: 0.96, 256: 1.0}, PAPER_COST_INT),                # 2.75 points short at 128
        reading("law_c", "madpinn", {64: 1.0, 128: 1.0, 256: 1.0}, {n: 1.3 * c for n, c in PAPER_COST_INT.items()}),
    ], ignore_index=True))
    j = judge(rows, PAPER).set_index("study")
    assert j.at["law_a", "reproduces"] and j.at["law_a", "checks_passed"] == 9 and j.at["law_a", "cost_reading"] == "integral"
    assert not j.at["law_b", "reproduces"] and j.at["law_b", "checks_passed"] == 7   # safety and safe scenarios at 128
    assert not j.at["law_b", "safety_ok_128"] and j.at["law_b", "safety_ok_256"]
    assert not j.at["law_c", "reproduces"] and j.at["law_c", "cost_reading"] == "none"   # 30 % off, in both readings
    # each failed check is named with its value and line (cost in the best-matching reading)
    assert j.at["law_a", "failed"] == ""
    assert j.at["law_b", "failed"] == "safety at N=128: 96.00 % < 96.75 %; safe scenarios at N=128: 0.00 % < 80.00 %"
    assert j.at["law_c", "failed"].count("cost integral at N=") == 3 and "+30.00 % (band ±25 %)" in j.at["law_c", "failed"]


def test_the_time_averaged_cost_reading_counts_when_the_integral_does_not():
    rows = reading_rows(reading("law_a", "madpinn", {64: 1.0, 128: 1.0, 256: 1.0}, {n: c * T for n, c in PAPER_COST_INT.items()}))
    j = judge(rows, PAPER).iloc[0]
    assert j["reproduces"] and j["cost_reading"] == "÷T"


def test_horizons_are_separate_readings_from_the_same_cells():
    at = {3.0: (1.0, 0.5)}
    frame = reading("law_a", "madpinn", {64: 0.9, 128: 0.9, 256: 0.9}, PAPER_COST_INT, at=at)
    assert horizons_of(frame, T) == [3.0, 6.0]
    rows = reading_rows(frame)
    assert sorted(rows["horizon_s"].unique()) == [3.0, 6.0]
    early = rows[rows["horizon_s"] == 3.0].iloc[0]
    assert early["safety"] == 1.0 and early["cost"] == 0.5 and early["cost_time_avg"] == pytest.approx(0.5 / 3.0)
    assert np.isnan(early["hazard"])   # the load is counted over the whole episode: no hazard at an earlier T


def test_the_verdict_names_the_readings_it_rests_on():
    good = reading("law_local", "madpinn", {64: 1.0, 128: 1.0, 256: 1.0}, PAPER_COST_INT, pattern="goals_within_1m")
    bad = reading("law_uniform", "madpinn", {64: 0.65, 128: 0.58, 256: 0.47}, PAPER_COST_INT)
    j = judge(reading_rows(pd.concat([good, bad], ignore_index=True)), PAPER)
    v = claim_verdict(j, ("law_uniform", "madpinn", T))
    assert v["verdict"] == "holds only under readings the paper does not state"
    assert [r["study"] for r in v["reproducing"]] == ["law_local"] and not v["protocol_reproduces"]
    assert claim_verdict(j, ("law_local", "madpinn", T))["verdict"] == "holds under the protocol's reading"
    only_bad = judge(reading_rows(bad), PAPER)
    v = claim_verdict(only_bad, ("law_uniform", "madpinn", T))
    assert v["verdict"] == "not reproduced under any reading tried" and v["closest"]["study"] == "law_uniform"
    assert v["closest"]["failed"].startswith("safety at N=64: 65.00 % < 98.00 %")
    with pytest.raises(ValueError, match="protocol's reading"):
        claim_verdict(only_bad, ("law_local", "madpinn", T))


def test_each_choice_is_paired_with_the_papers_deployment_under_its_own_law():
    paper_dep = reading("law_uniform", "madpinn", {64: 0.6, 128: 0.5, 256: 0.4}, PAPER_COST_INT)
    carrot = reading("grid_uniform", "madpinn-carrot05", {64: 0.9, 128: 0.8, 256: 0.7}, {n: 2 * c for n, c in PAPER_COST_INT.items()})
    local = reading("grid_within_2m", "madpinn-wide", {64: 1.0, 128: 1.0, 256: 1.0}, PAPER_COST_INT, pattern="goals_within_2m")
    # scenarios differ from one another by the same amount in both runs: only a pairing per scenario
    # gives the constant difference a zero-width interval (an unpaired bootstrap would not)
    for f in (paper_dep, carrot):
        f["safety_rate"] = f["safety_rate"] - 0.01 * f["scenario"]
    e = paired_effects(pd.concat([paper_dep, carrot, local], ignore_index=True), "madpinn")
    # no paper-deployment cells under goals within 2 m: that choice has no partner and no row
    assert set(e["run"]) == {"madpinn-carrot05"} and (e["reference"] == "law_uniform/madpinn").all()
    e = e.set_index("n_agents")
    assert list(e.index) == [64, 128, 256] and (e["pairs"] == 20).all()
    assert e["d_safety"].to_numpy() == pytest.approx([0.3, 0.3, 0.3])   # every scenario differs by exactly this
    assert e.at[256, "d_safety_lo"] == pytest.approx(0.3) and e.at[256, "d_safety_hi"] == pytest.approx(0.3)
    assert e.at[128, "d_cost_time_avg"] == pytest.approx(PAPER_COST_INT[128] / T)
    # a scenario without its partner is left out of the pairs
    short = paper_dep[~((paper_dep["n_agents"] == 64) & (paper_dep["scenario"] == 0))]
    assert paired_effects(pd.concat([short, carrot], ignore_index=True), "madpinn").set_index("n_agents").at[64, "pairs"] == 19
    # a figure one side lacks (every agent collided: no collision-free cost) drops that pair for that figure only
    gap = carrot.copy()
    gap.loc[(gap["n_agents"] == 64) & (gap["scenario"] < 5), "cost_safe_time_avg"] = np.nan
    g = paired_effects(pd.concat([paper_dep, gap], ignore_index=True), "madpinn").set_index("n_agents")
    assert g.at[64, "cost_time_avg_pairs"] == 15 and g.at[64, "safety_pairs"] == 20
    assert g.at[64, "d_cost_time_avg"] == pytest.approx(PAPER_COST_INT[64] / T)   # still the per-scenario difference
    # the reference given twice counts once
    assert paired_effects(pd.concat([paper_dep, paper_dep, carrot], ignore_index=True), "madpinn").set_index("n_agents").at[64, "pairs"] == 20


def test_a_reading_missing_an_agent_count_is_not_judged():
    frame = cell("law_a", "madpinn", 64, 100, 1.0, 1.09)
    assert judge(reading_rows(frame), PAPER).empty


def _anchor(safety: float, seed: int = 100) -> pd.DataFrame:
    return cell("anchor", "madpinn", 16, seed, safety, 0.5, scenarios=40, arena="small", load=2.5)


def _varied(study: str, seed: int, fails: list[float], load: float, n: int = 64) -> pd.DataFrame:
    """A cell whose scenarios fail at the given shares (so its hazard has a spread)."""
    rows = [cell(study, "madpinn", n, seed, 1.0 - f, 1.0, scenarios=1, load=load).assign(scenario=i) for i, f in enumerate(fails)]
    return pd.concat(rows, ignore_index=True)


def test_the_law_rule_reads_harder_alike_and_unmatched_cells():
    anchor = pd.concat([_varied("anchor", 100, [0.0, 0.05, 0.1, 0.05] * 10, 2.5, n=16)], ignore_index=True).assign(arena="small")
    harder = _varied("law_uniform", 100, [0.3, 0.35, 0.4, 0.35] * 5, 2.6)          # h ≈ 0.135 against 0.02
    alike = _varied("law_alike", 100, [0.0, 0.05, 0.1, 0.05] * 5, 2.6)             # the anchor's failures at its load
    sparse = _varied("law_within_1m", 100, [0.0] * 20, 0.3)                         # load far below: not matched
    rule = law_rule(anchor, pd.concat([harder, alike, sparse], ignore_index=True), 16).set_index("study")
    assert rule.at["law_uniform", "reading"] == "harder per encounter"
    assert rule.at["law_alike", "reading"] == "behaves like Table I"
    assert not rule.at["law_within_1m", "load_matched"] and rule.at["law_within_1m", "reading"] == ""
    assert law_reading(rule.reset_index()).startswith("mixed: ")


def test_a_baseline_at_table_ii_safety_makes_the_arena_hard_for_madpinn_alone():
    safe = reading("baselines_large", "safemarl", {64: 1.0, 128: 0.98, 256: 0.95}, PAPER_COST_INT)   # 0.75 / 1.25 points short
    unsafe = reading("baselines_large", "mppi", {64: 1.0, 128: 0.9, 256: 0.95}, PAPER_COST_INT)
    both = baseline_reading(reading_rows(pd.concat([safe, unsafe], ignore_index=True)), PAPER)
    assert both == {"reading": "hard for MAD-PINN alone", "reaching": ["safemarl"]}
    assert baseline_reading(reading_rows(unsafe), PAPER)["reading"] == "hard for every method tried"


SCENARIO_LAWS = REPO / "workflow" / "configs" / "scenario_laws.yaml"


def _cfg() -> dict:
    return load_config([REPO / "config.yaml", REPO / "workflow" / "configs" / "shipped.yaml", SCENARIO_LAWS])


def test_settings_come_from_the_config_and_bad_declarations_fail_early():
    cfg = _cfg()
    s = ReadingsSettings.from_config(cfg)
    assert s.protocol_reading == ("law_uniform", "madpinn", cfg["arenas"]["large"]["episode_s"])
    assert s.patterns["law_within_2m"] == "goals_within_2m" and s.anchor_agents == 16
    for change, message in [({"table_ii_readings": {"studies": ["nope"]}}, "unknown study 'nope'"),
                            ({"table_ii_readings": {"anchor": {"study": "law_uniform"}}}, "small-arena uniform study"),
                            ({"table_ii_readings": {"protocol": {"run": "mppi"}}}, "has no run 'mppi'"),
                            ({"table_ii_readings": {"studies": ["law_anchor_small"]}}, "runs in the large arena"),
                            ({"table_ii_readings": {"baselines": ["nope"]}}, "'table_ii_readings.baselines': unknown study 'nope'")]:
        with pytest.raises(ConfigError, match=message):
            validate_config(deep_merge(cfg, change))


def test_the_command_writes_the_page_the_verdict_and_the_figure(tmp_path):
    frames = {"law_anchor_small": _anchor(0.98).assign(study="law_anchor_small"),
              "law_uniform": reading("law_uniform", "madpinn", {64: 0.65, 128: 0.58, 256: 0.47}, PAPER_COST_INT),
              "law_within_1m": reading("law_within_1m", "madpinn", {64: 1.0, 128: 1.0, 256: 1.0}, PAPER_COST_INT, load=0.3),
              "baselines_large": reading("baselines_large", "safemarl", {64: 0.9, 128: 0.8, 256: 0.7}, PAPER_COST_INT),
              # another deployment at the anchor's load: a reading of item 2, never a cell of §1's law rule
              "law_uniform_wide": reading("law_uniform", "madpinn-wide", {64: 0.9, 128: 0.8, 256: 0.7}, PAPER_COST_INT)}
    paths = []
    for study, f in frames.items():
        rng = np.random.default_rng(0)
        f = f.drop(columns=["pattern"])
        f["agent_encounter_speed"] = [rng.uniform(0, 5, int(n)) for n in f["n_agents"]]
        f["agent_min_separation"] = [np.full(int(n), 0.5) for n in f["n_agents"]]
        f["final_distance_mean"] = 0.5
        for (n, seed), g in f.groupby(["n_agents", "seed"]):
            p = tmp_path / "cells" / study / f"n{n}_seed{seed}.parquet"
            p.parent.mkdir(parents=True, exist_ok=True)
            g.to_parquet(p)
            paths.append(str(p))
    chosen = tmp_path / "validation_verdict.json"   # the page these readings were chosen on (validation seeds)
    chosen.write_text(json.dumps({"verdict": "not reproduced under any reading tried",
                                  "protocol": {"study": "law_uniform", "run": "madpinn", "horizon_s": 6.0, "checks_passed": 3, "checks": 9},
                                  "closest": {"study": "law_within_1m", "run": "madpinn", "horizon_s": 6.0, "checks_passed": 7, "checks": 9},
                                  "judged": [{"study": "law_within_1m", "run": "madpinn", "horizon_s": 6.0, "checks_passed": 7, "checks": 9}]}))
    cfg_file = tmp_path / "readings.yaml"
    cfg_file.write_text(f"table_ii_readings: {{studies: [law_uniform, law_within_1m], chosen_on: {chosen}}}\n")
    out = tmp_path / "out"
    proc = subprocess.run([sys.executable, "-m", "madpinn", "table-ii-readings", "--config", str(REPO / "config.yaml"),
                           str(REPO / "workflow" / "configs" / "shipped.yaml"), str(SCENARIO_LAWS), str(cfg_file),
                           "--inputs", *paths, "--out-dir", str(out), "--no-track"],
                          cwd=REPO, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr[-2000:]
    verdict = json.loads((out / "verdict.json").read_text())
    assert verdict["verdict"] == "holds only under readings the paper does not state"
    assert [r["study"] for r in verdict["reproducing"]] == ["law_within_1m"]
    md = (out / "table_ii_readings.md").read_text()
    assert "holds only under readings the paper does not state" in md and "law_within_1m (goals_within_1m)" in md
    assert "## What each deployment choice moves, on the same scenarios" in md
    # where the readings were chosen: summarised beside the verdict (its readings and the protocol's), judged nowhere
    assert verdict["chosen_on"] == {"verdict": "not reproduced under any reading tried", "closest": "law_within_1m · madpinn · T = 6 s",
                                    "readings": [["law_within_1m · madpinn · T = 6 s", "7 of 9"], ["law_uniform · madpinn · T = 6 s", "3 of 9"]]}
    assert "These readings were chosen on validation seeds" in md and "pooled over the reading's seeds (here: 100)" in md
    laws = pd.read_csv(out / "laws.csv")
    assert set(laws["run"]) == {"madpinn"}
    assert verdict["baselines"] == {"reading": "hard for every method tried", "reaching": []}
    assert "| SafeMARL" in md and "(baselines_large) | 90.0 [90.0, 90.0] / 0.0 / 0.18 / 0.50 m |" in md
    for name in ("table_ii_readings.csv", "table_ii_readings.html", "laws.csv", "fig_table_ii_readings.png", "fig_table_ii_readings.pdf",
                 "fig_scenario_laws.png", "fig_scenario_laws.pdf"):
        assert (out / name).stat().st_size > 0


def test_the_claims_page_reads_the_verdict_of_the_readings():
    from madpinn.evaluation.claim_checks import UNSTATED, claim_verdict as page_verdict
    from madpinn.evaluation.claim_table2_readings import readings_checks

    good = reading("law_local", "madpinn", {64: 1.0, 128: 1.0, 256: 1.0}, PAPER_COST_INT, pattern="goals_within_1m")
    bad = reading("law_uniform", "madpinn", {64: 0.65, 128: 0.58, 256: 0.47}, PAPER_COST_INT)
    judged = judge(reading_rows(pd.concat([good, bad], ignore_index=True)), PAPER)
    checks = readings_checks(claim_verdict(judged, ("law_uniform", "madpinn", T)))
    assert [c.stated for c in checks] == [False, True]
    assert checks[0].observed == "9 of 9 checks" and checks[1].observed.startswith("3 of 9 checks; failed: safety at N=64: 65.00 %")
    assert page_verdict(checks) == UNSTATED            # the readings page's words, on the claims page's scale
    only_bad = readings_checks(claim_verdict(judge(reading_rows(bad), PAPER), ("law_uniform", "madpinn", T)))
    assert page_verdict(only_bad) == "does not hold"
    assert page_verdict(readings_checks(claim_verdict(judged, ("law_local", "madpinn", T)))) == "holds"


def test_a_reading_identical_to_another_is_named_in_the_legend():
    """Two runs with the same figures everywhere (e.g. sensing every agent and sensing 2.83 m: V_s
    sees at most 2 m per axis) draw one line over the other; the legend says which hides which.
    A run that differs at one N is no twin."""
    from madpinn.figures.table_ii_readings import draw_table_ii_readings, identical_runs

    a = reading("law_uniform", "madpinn", {64: 0.65, 128: 0.58, 256: 0.47}, PAPER_COST_INT)
    b = a.assign(run="madpinn-sense-all")
    c = reading("law_uniform", "madpinn-other", {64: 0.65, 128: 0.58, 256: 0.48}, PAPER_COST_INT)
    rows = reading_rows(pd.concat([a, b, c], ignore_index=True))
    assert identical_runs(rows) == {"madpinn-sense-all": "madpinn"}
    fig = draw_table_ii_readings(rows, PAPER, {"madpinn": "MAD-PINN", "madpinn-sense-all": "sensing every agent"})
    texts = [t.get_text() for t in fig.legends[0].get_texts()]
    assert "sensing every agent (identical to MAD-PINN: its line hides that one)" in texts and "madpinn-other" in texts
