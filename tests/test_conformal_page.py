"""The calibrated level's page (issue 62): its settings come from the conformal overlay and refuse a
study without V̂ alone; the cells are paired against V̂ alone; the sentence says where a level reaches
the paper's safety and V̂ alone does not; the speed gap counts collided agents per closing-speed bin
beside the level's ε and δ; the command writes the page and its figure from cell files. Scenario
rows are built with known figures, so every expected value follows by construction."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pandas as pd
import pytest

from conftest import REPO
from madpinn.config import ConfigError, deep_merge, load_config
from madpinn.evaluation.conformal_page import adopted_caveats, cell_rows, speed_gap, uncertified_runs, verdict, write_conformal_page
from madpinn.evaluation.conformal_settings import ConformalSettings, conformal_studies

OVERLAY = REPO / "workflow" / "configs" / "conformal.yaml"
T = 6.0
# per agent of every scenario: encounter speed (m/s) and minimum separation (m); r = 0.1 m
SPEEDS = np.array([1.0, 1.0, 1.0, 1.0, 3.0, 3.0, 5.0, 5.0, 7.0, 7.0])
COLLIDED = np.array([0.05, 0.5, 0.5, 0.5, 0.05, 0.05, 0.5, 0.5, 0.05, 0.5])   # 1/4, 2/2, 0/2, 1/2 per bin


@pytest.fixture(scope="module")
def cfg():
    return load_config([REPO / "config.yaml", OVERLAY])


@pytest.fixture(scope="module")
def settings(cfg):
    return ConformalSettings.from_config(cfg)


def cell(study: str, run: str, n: int, safety: float, cost: float, *, arena: str = "large", scenarios: int = 10) -> pd.DataFrame:
    """``scenarios`` rows of one cell, each with this safety and cost ÷T, and the agents of :data:`SPEEDS`."""
    return pd.DataFrame([{"study": study, "run": run, "n_agents": n, "seed": 100, "scenario": s, "arena": arena,
                          "episode_s": T, "safety_rate": safety, "safe": safety == 1.0, "cost_safe_mean": cost * T,
                          "cost_safe_time_avg": cost, "cost_all_mean": cost * T, "cost_all_time_avg": cost,
                          "agent_encounter_speed": SPEEDS, "agent_min_separation": COLLIDED} for s in range(scenarios)])


def large_cells() -> pd.DataFrame:
    """Table II's setting: V̂ alone at 50 %; ε 0.1 reaches the paper's line at 64 and 128, not 256; the
    governor everywhere; ε 0.05 per bin nowhere."""
    parts = []
    for n, alone, eps10, gov in ((64, 0.5, 0.99, 0.99), (128, 0.5, 0.97, 0.99), (256, 0.5, 0.90, 0.99)):
        parts += [cell("conformal_large", "madpinn", n, alone, 1.0), cell("conformal_large", "madpinn-cpeps10", n, eps10, 1.5),
                  cell("conformal_large", "madpinn-cpeps05bins", n, 0.6, 1.2), cell("conformal_large", "madpinn-carrot05vmaxh", n, gov, 2.0)]
    frame = pd.concat(parts, ignore_index=True).assign(pattern="uniform")
    frame["safety_rate"] -= 0.002 * (frame["scenario"] - 4.5)   # the same zero-mean spread in every run: paired Δ is exact
    return frame


def test_settings_come_from_the_overlay_and_refuse_a_level_study_without_vhat_alone(cfg, settings):
    assert set(settings.studies) == {"conformal_small", "conformal_large", "conformal_circle"}
    assert {lv.run for lv in settings.levels} == {"madpinn-cpeps10", "madpinn-cpeps05", "madpinn-cpeps01",
                                                  "madpinn-cpeps10bins", "madpinn-cpeps05bins"}
    assert settings.others == ("madpinn-carrot05vmaxh",) and settings.speed_edges == (2.0, 4.0, 6.0)
    assert {lv.run: lv.epsilon for lv in settings.levels}["madpinn-cpeps01"] == 0.01
    bad = deep_merge(cfg, {"studies": {"conformal_large": {"runs": ["madpinn-cpeps10"]}}})
    with pytest.raises(ConfigError, match="without 'madpinn'"):
        ConformalSettings.from_config(bad)
    # the protocol's main and scaling carry the adopted level as a row (issue 62): protocol seeds, never this page's;
    # the large arena's frontier (validation seed 100, in `all`) shows level runs beside its governors: its figure's
    protocol = load_config([REPO / "config.yaml"])
    assert "madpinn-cpeps01" in protocol["studies"]["main"]["runs"] and conformal_studies(protocol) == []
    assert min(protocol["studies"]["large_arena_frontier"]["seeds"]) >= 100
    assert {"madpinn-cpeps05", "madpinn-cpeps01"} <= set(protocol["studies"]["large_arena_frontier"]["runs"])
    assert conformal_studies(deep_merge(protocol, {"studies": {"large_arena_frontier": {"in_all": False}}})) == ["large_arena_frontier"]
    with pytest.raises(ConfigError, match="no validation-seed study runs a calibrated level"):
        ConformalSettings.from_config(protocol)


def test_cells_are_paired_against_vhat_alone_and_the_sentence_names_where_a_level_reaches_the_paper(settings):
    rows = cell_rows(large_cells(), settings).set_index(["run", "n_agents"])
    assert rows.at[("madpinn-cpeps10", 64), "d_safety"] == pytest.approx(0.49)
    assert rows.at[("madpinn-cpeps10", 64), "d_safety_lo"] == pytest.approx(0.49)   # zero width: paired per scenario
    assert rows.at[("madpinn-cpeps10", 128), "d_cost_time_avg"] == pytest.approx(0.5)
    assert np.isnan(rows.at[("madpinn", 64), "d_safety"])          # V̂ alone is the reference
    assert rows.at[("madpinn", 256), "paper_safety"] == pytest.approx(0.9625)   # Table II's row
    v = verdict(cell_rows(large_cells(), settings), settings)
    reached = {c["n_agents"]: c["best_reaches"] for c in v["cells"]}
    assert reached == {64: True, 128: True, 256: False}
    assert v["sentence"].startswith("A calibrated level reaches the paper's safety (less 2 points) where V̂ alone does not in 2 of 3 cells")
    assert "Carrot 0.5 m + v_max 0.8 m/s (not in paper) 99.0 % at Δ cost ÷T +1.00" in v["sentence"]
    # the adopted level: most cells at the line (ε 0.1: 2 of 3; ε 0.05 per bin: 0), beating V̂ alone (0)
    a = v["adopted"]
    assert (a["run"], a["reaches"], a["cells"], a["alone_reaches"], a["beats_alone"]) == ("madpinn-cpeps10", 2, 3, 0, True)
    # no level above V̂ alone's line anywhere: the sentence says so
    flat = large_cells()
    flat.loc[flat["run"] == "madpinn-cpeps10", "safety_rate"] = 0.6
    fv = verdict(cell_rows(flat, settings), settings)
    assert fv["sentence"].startswith("No calibrated level reaches")
    # then the tie (0 cells each) goes to the higher mean safety, then the lower cost: ε 0.1 at 0.6 against 0.6 per bin
    # costs 1.5 against 1.2, so the per-bin level is adopted, and it does not beat V̂ alone
    assert (fv["adopted"]["run"], fv["adopted"]["beats_alone"]) == ("madpinn-cpeps05bins", False)
    flat.loc[flat["run"] == "madpinn-cpeps10", "safety_rate"] = 0.61
    assert verdict(cell_rows(flat, settings), settings)["adopted"]["run"] == "madpinn-cpeps10"


def test_the_speed_gap_counts_collided_agents_per_bin_beside_the_levels_epsilon_and_delta(settings):
    report = {"distributions": {"conflict": {
        "pooled": [{"bin_label": "all", "epsilon": 0.1, "beta": 1e-3, "delta": 0.12, "test": {"accepted": 90, "rate": 0.05, "upper_bound": 0.08}}],
        "binned": [{"bin_label": lab, "epsilon": 0.05, "beta": 1e-3, "delta": 0.02 * i,
                    "test": {"accepted": 10 * (i + 1), "rate": 0.01 * i, "upper_bound": 0.04}}
                   for i, lab in enumerate(["< 2 m/s", "2–4 m/s", "4–6 m/s", "≥ 6 m/s"])]}}}
    gap = speed_gap(large_cells(), settings, report).set_index(["run", "bin"])
    alone = gap.loc["madpinn"]
    assert list(alone.index) == ["< 2 m/s", "2–4 m/s", "4–6 m/s", "≥ 6 m/s"]
    assert alone["share"].tolist() == pytest.approx([0.25, 1.0, 0.0, 0.5])
    assert alone["agents"].tolist() == [120, 60, 60, 60]          # 3 cells x 10 scenarios x the bin's agents
    assert (alone["delta"] == 0.0).all() and alone["epsilon"].isna().all()
    pooled = gap.loc["madpinn-cpeps10"]
    assert (pooled["delta"] == 0.12).all() and (pooled["heldout_rate"] == 0.05).all()   # one δ for every bin
    binned = gap.loc["madpinn-cpeps05bins"]
    assert binned["delta"].tolist() == pytest.approx([0.0, 0.02, 0.04, 0.06])
    assert binned.at["4–6 m/s", "heldout_rate"] == pytest.approx(0.02)
    # without a report: the closed-loop shares, no δ for the level runs
    assert speed_gap(large_cells(), settings, None).set_index(["run", "bin"]).loc["madpinn-cpeps10", "delta"].isna().all()


def test_the_command_writes_the_page_the_sentence_and_the_figure(tmp_path, settings):
    paths = []
    for (study, run, n), g in large_cells().drop(columns="pattern").groupby(["study", "run", "n_agents"]):
        p = tmp_path / "eval" / study / run / f"n{n}_seed100.parquet"
        p.parent.mkdir(parents=True, exist_ok=True)
        g.to_parquet(p)
        paths.append(str(p))
    out = tmp_path / "page"
    proc = subprocess.run([sys.executable, "-m", "madpinn", "conformal-page", "--config", str(REPO / "config.yaml"), str(OVERLAY),
                           "--inputs", *paths, "--out-dir", str(out), "--no-track"], capture_output=True, text=True, cwd=REPO)
    assert proc.returncode == 0, proc.stderr[-2000:]
    v = json.loads((out / "conformal.json").read_text())
    assert "2 of 3 cells" in v["sentence"]
    md = (out / "conformal.md").read_text()
    assert v["sentence"] in md and "## What the guarantee covers, and the gap" in md
    for name in ("conformal.csv", "speed_gap.csv", "conformal.html", "fig_conformal.png", "fig_conformal.pdf"):
        assert (out / name).stat().st_size > 0
    # cells of a study without a calibrated level are refused before anything is written
    other = tmp_path / "other.parquet"
    large_cells().drop(columns="pattern").assign(study="law_uniform").to_parquet(other)
    proc = subprocess.run([sys.executable, "-m", "madpinn", "conformal-page", "--config", str(REPO / "config.yaml"), str(OVERLAY),
                           "--inputs", str(other), "--out-dir", str(tmp_path / "none"), "--no-track"], capture_output=True, text=True, cwd=REPO)
    assert proc.returncode != 0 and "cells of studies without a calibrated level" in proc.stderr and "Traceback" not in proc.stderr
    assert not (tmp_path / "none").exists()
    # an unreadable calibration report: one line naming the command that writes it
    proc = subprocess.run([sys.executable, "-m", "madpinn", "conformal-page", "--config", str(REPO / "config.yaml"), str(OVERLAY),
                           "--inputs", *paths, "--calibration", str(tmp_path / "missing.json"), "--out-dir", str(tmp_path / "none"),
                           "--no-track"], capture_output=True, text=True, cwd=REPO)
    assert proc.returncode != 0 and "calibrate-vhat" in proc.stderr and "Traceback" not in proc.stderr
    assert not (tmp_path / "none").exists()
    # V̂ alone's cells only: the page is written, with no paired difference
    alone = [q for q in paths if "/madpinn/" in q]
    proc = subprocess.run([sys.executable, "-m", "madpinn", "conformal-page", "--config", str(REPO / "config.yaml"), str(OVERLAY),
                           "--inputs", *alone, "--out-dir", str(tmp_path / "alone"), "--no-track"], capture_output=True, text=True, cwd=REPO)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert pd.read_csv(tmp_path / "alone" / "conformal.csv")["d_safety"].isna().all()


def test_an_adopted_run_whose_level_was_certified_nowhere_is_named_so_with_its_cost(settings):
    """A level run whose calibration certified no δ in any bin (δ = ∞: V̂ never trusted) is flagged in
    the sentence and in the adoption text, with its cost ÷T against V̂ alone's (by construction 1.5×)."""
    report = {"distributions": {"conflict": {
        "pooled": [{"bin_label": "all", "epsilon": 0.1, "beta": 1e-3, "delta": None, "test": {}}],
        "binned": [{"bin_label": lab, "epsilon": 0.05, "beta": 1e-3, "delta": 0.02, "test": {"accepted": 10, "rate": 0.0, "upper_bound": 0.04}}
                   for lab in ["< 2 m/s", "2–4 m/s", "4–6 m/s", "≥ 6 m/s"]]}}}
    frame = large_cells()
    gap = speed_gap(frame, settings, report)
    never = uncertified_runs(gap)
    assert never == {"madpinn-cpeps10"}                        # the per-bin level has a finite δ everywhere
    assert uncertified_runs(speed_gap(frame, settings, None)) == frozenset()   # no report: nothing is claimed
    rows = cell_rows(frame, settings)
    v = verdict(rows, settings, never)
    assert v["adopted"]["run"] == "madpinn-cpeps10"
    assert "V̂ never trusted where none was certified" in v["sentence"] and "[no level certified: V̂ never trusted]" in v["sentence"]
    caveats = adopted_caveats(v["adopted"], rows, never)
    assert caveats["certified"] is False and caveats["cost_ratio"] == pytest.approx(1.5)
    assert adopted_caveats(v["adopted"], rows, frozenset())["certified"] is True
    assert "V̂ never trusted" not in verdict(rows, settings)["sentence"]
