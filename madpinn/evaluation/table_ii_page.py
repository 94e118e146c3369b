"""The Table II readings page (issue 60): ``table_ii_readings.{csv,md,html}``, ``verdict.json`` and
the start/goal laws' rule (``laws.csv``), from the cells of ``table_ii_readings.studies`` and its
anchor (:mod:`madpinn.evaluation.table_ii_readings` computes, this module writes)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Iterable, Mapping

import numpy as np
import pandas as pd

from madpinn.evaluation.encounter_hazard import hazard_by_speed
from madpinn.evaluation.paired_effects import paired_effects
from madpinn.evaluation.table_ii_readings import (SCALE, PaperRow, baseline_reading, claim_verdict, judge, law_reading, law_rule,
                                                  reading_rows)
from madpinn.evaluation.table_ii_settings import ReadingsSettings
from madpinn.evaluation.tables import load_results, to_markdown

SPEED_EDGES = (0.0, 1.0, 2.0, 3.0, 4.0, 6.0)
"""m/s: the bins of the collided share by encounter speed (the first pass's, docs/findings/2026-11-29-scenario-laws-first-pass.md)"""
PLAN = "docs/findings/2026-11-28-table-ii-readings-preregistered.md"


def load_frames(result_paths: Iterable[str | Path], settings: ReadingsSettings) -> tuple[pd.DataFrame, pd.DataFrame, pd.DataFrame]:
    """(anchor, readings, baselines) scenario rows of the given cells, each with its study's ``pattern``."""
    df = load_results(result_paths)
    unknown = sorted(set(df["study"]) - set(settings.patterns))
    if unknown:
        raise ValueError(f"cells of studies outside table_ii_readings: {unknown}")
    df["pattern"] = df["study"].map(settings.patterns)
    return (df[df["study"] == settings.anchor].copy(), df[df["study"].isin(settings.studies)].copy(),
            df[df["study"].isin(settings.baselines)].copy())


def verdict_of(rows: pd.DataFrame, paper: PaperRow, settings: ReadingsSettings) -> tuple[pd.DataFrame, dict]:
    """The judged readings and the claim's verdict; with no reading at every N, the verdict says so."""
    judged = judge(rows, paper)
    if judged.empty:
        return judged, {"verdict": "not judged: no reading has a cell at each of Table II's agent counts",
                        "readings_judged": 0}
    return judged, claim_verdict(judged, settings.protocol_reading)


def _pct(x: float) -> str:
    return "–" if not np.isfinite(x) else f"{100 * x:.1f}"


def _safety_text(c) -> str:
    """A cell's safety % with its 95 % interval and its safe scenarios %."""
    return f"{_pct(c['safety'])} [{_pct(c['safety_lo'])}, {_pct(c['safety_hi'])}] / {_pct(c['safe_scenarios'])}"


def _reading_name(r, settings: ReadingsSettings) -> str:
    return f"{r['study']} ({r['pattern']}) · {settings.labels.get(r['run'], r['run'])} · T = {r['horizon_s']:g} s"


def readings_display(rows: pd.DataFrame, judged: pd.DataFrame, paper: PaperRow, settings: ReadingsSettings) -> pd.DataFrame:
    """One display row per reading: per N safety [95 % CI] / safe sc. / cost ∫ / cost ÷T, and its checks."""
    checks = {(r["study"], r["run"], r["horizon_s"]): f"{r['checks_passed']}/{r['checks']}" + (" ✔" if r["reproduces"] else "")
              for _, r in judged.iterrows()}
    out = []
    for key, g in rows.groupby(["study", "run", "horizon_s"], sort=False):
        g = g.set_index("n_agents")
        row = {"reading": _reading_name({**g.iloc[0], "study": key[0], "run": key[1], "horizon_s": key[2]}, settings)}
        for n in sorted(set(paper.cells) | set(g.index)):
            if n not in g.index:
                row[f"N={n}"] = "–"
                continue
            c = g.loc[n]
            row[f"N={n}"] = f"{_safety_text(c)} / {c['cost']:.2f} / {c['cost_time_avg']:.2f}"
        row["checks"] = checks.get(key, "not every N")
        out.append(row)
    return pd.DataFrame(out)


def effects_display(effects: pd.DataFrame, settings: ReadingsSettings) -> pd.DataFrame:
    """One display row per deployment choice: per N Δ safety (points) [95 % CI] / Δ cost ÷T [95 % CI]."""
    out = []
    for (study, run), g in effects.groupby(["study", "run"], sort=False):
        row = {"choice": f"{settings.labels.get(run, run)} ({study}, {g['pattern'].iloc[0]})", "against": g["reference"].iloc[0]}
        for r in g.itertuples():
            row[f"N={r.n_agents}"] = (f"{100 * r.d_safety:+.1f} [{100 * r.d_safety_lo:+.1f}, {100 * r.d_safety_hi:+.1f}] / "
                                      f"{r.d_cost_time_avg:+.2f} [{r.d_cost_time_avg_lo:+.2f}, {r.d_cost_time_avg_hi:+.2f}]")
        out.append(row)
    return pd.DataFrame(out).fillna("–")


def laws_display(rule: pd.DataFrame) -> pd.DataFrame:
    """The §1 rule's cells for the page."""
    return pd.DataFrame({
        "cell": [f"{r.study} ({r.pattern}) · {r.run} · N={r.n_agents} · seed {r.seed}" for r in rule.itertuples()],
        "encounters / agent": [f"{x:.2f}" for x in rule["encounters_per_agent"]],
        "safety %": [_pct(x) for x in rule["safety"]],
        "h [95 % CI]": [f"{r.hazard:.3f} [{r.hazard_lo:.3f}, {r.hazard_hi:.3f}]" for r in rule.itertuples()],
        "anchor h [95 % CI]": [f"{r.anchor_hazard:.3f} [{r.anchor_lo:.3f}, {r.anchor_hi:.3f}]" for r in rule.itertuples()],
        "load-matched": ["yes" if m else "no" for m in rule["load_matched"]],
        "rule": [r or "–" for r in rule["reading"]],
    })


def speed_display(large: pd.DataFrame, settings: ReadingsSettings) -> pd.DataFrame:
    """Collided share by encounter speed, per study (all its runs and cells pooled)."""
    out = []
    for study, g in large.groupby("study", sort=False):
        for r in hazard_by_speed(g, SPEED_EDGES, settings.collision_radius).itertuples():
            out.append({"study": study, "speed (m/s)": f"{r.speed_low:g}–{r.speed_high:g}" if np.isfinite(r.speed_high) else f"≥ {r.speed_low:g}",
                        "agents": r.agents, "collided": r.collided,
                        "share [95 % Wilson]": "–" if not r.agents else f"{r.hazard:.3f} [{r.low:.3f}, {r.high:.3f}]"})
    return pd.DataFrame(out)


def reading_name(r: Mapping) -> str:
    """A reading's name (its study, run and horizon), as the page, its verdict and the claims page write it."""
    return f"{r['study']} · {r['run']} · T = {r['horizon_s']:g} s"


def chosen_on_summary(verdict: dict) -> dict:
    """Of the readings page (validation seeds) a page's readings were chosen on: its verdict, the reading it
    found closest, and each reading's checks passed (``[name, "k of n"]`` pairs: its judged readings and the
    protocol's, most passed first)."""
    readings = list(verdict.get("judged") or [])
    proto = verdict.get("protocol")
    if proto and reading_name(proto) not in {reading_name(r) for r in readings}:
        readings.append(proto)
    readings.sort(key=lambda r: -r["checks_passed"] / r["checks"])
    closest = verdict.get("closest")
    return {"verdict": verdict.get("verdict"), "closest": reading_name(closest) if closest else None,
            "readings": [[reading_name(r), f"{r['checks_passed']} of {r['checks']}"] for r in readings]}   # a list: kept in order


def chosen_on_line(verdict: dict) -> str:
    """The page's line on where its readings were chosen ("" when they were not chosen on a readings page)."""
    ch = verdict.get("chosen_on")
    if not ch:
        return ""
    shown = "; ".join(f"{r}: {k}" for r, k in ch["readings"])
    return (f"These readings were chosen on validation seeds, where the readings page said \"{ch['verdict']}\" and found "
            f"{ch['closest']} closest (checks passed per reading: {shown}).")


def verdict_sentence(verdict: dict) -> str:
    """The verdict in one plain sentence, naming the readings it rests on."""
    v = verdict["verdict"]
    if not verdict.get("readings_judged"):
        return f"**{v}.**"
    text = f"**Table II {v}.** The protocol's reading ({reading_name(verdict['protocol'])}) passes {verdict['protocol']['checks_passed']} of {verdict['protocol']['checks']} checks."
    if verdict["reproducing"]:
        text += " Readings that reproduce it: " + "; ".join(f"{reading_name(r)} (cost reading {r['cost_reading']})" for r in verdict["reproducing"]) + "."
    else:
        c = verdict["closest"]
        text += f" The closest reading: {reading_name(c)}, {c['checks_passed']} of {c['checks']} checks"
        text += f"; it fails {c['failed']}." if c.get("failed") else "."
    if not verdict["protocol_reproduces"] and verdict["protocol"].get("failed") and verdict.get("closest") != verdict["protocol"]:
        text += f" The protocol's reading fails {verdict['protocol']['failed']}."
    return text


def baselines_display(rows: pd.DataFrame, protocol: pd.DataFrame, paper: PaperRow, settings: ReadingsSettings) -> pd.DataFrame:
    """The baselines' rows and the protocol's reading beside them: per N safety [95 % CI] / safe sc. / cost ÷T /
    mean goal distance at the episode's end (m)."""
    out = []
    for (study, run), g in pd.concat([protocol, rows], ignore_index=True).groupby(["study", "run"], sort=False):
        g = g[g["horizon_s"] == g["horizon_s"].max()].set_index("n_agents")
        row = {"method": f"{settings.labels.get(run, run)} ({study})"}
        for n in sorted(set(paper.cells) | set(g.index)):
            c = g.loc[n] if n in g.index else None
            row[f"N={n}"] = "–" if c is None else f"{_safety_text(c)} / {c['cost_time_avg']:.2f} / {c['goal_distance']:.2f} m"
        out.append(row)
    return pd.DataFrame(out)


def write_table_ii_readings(anchor: pd.DataFrame, large: pd.DataFrame, rows: pd.DataFrame, baselines: pd.DataFrame,
                            settings: ReadingsSettings, paper: PaperRow, out_dir: str | Path,
                            chosen_on: dict | None = None) -> list[Path]:
    """From :func:`load_frames`' scenario rows and the readings' :func:`reading_rows` ``rows``, write ``table_ii_readings.csv`` (one row per reading
    and N), ``.md`` / ``.html`` (the verdict, the readings, the law rule, the speed bins),
    ``verdict.json`` and ``laws.csv``; returns the paths. ``chosen_on``: the ``verdict.json`` of the readings
    page these readings were chosen on (config ``table_ii_readings.chosen_on``), summarised beside the verdict."""
    from madpinn.evaluation.html import markdown_page

    judged, verdict = verdict_of(rows, paper, settings)
    effects = paired_effects(large, settings.protocol[1])
    # §1 reads the start/goal laws under the paper's deployment: the protocol's run only (the grid's other
    # deployments are readings of item 2, not loads of item 1)
    paper_deployment = large[large["run"] == settings.protocol[1]]
    rule = law_rule(anchor, paper_deployment, settings.anchor_agents) if len(anchor) and len(paper_deployment) else pd.DataFrame()
    verdict["law_rule"] = law_reading(rule) if len(rule) else "no anchor cells"
    base_rows = reading_rows(baselines) if len(baselines) else pd.DataFrame()
    if len(base_rows):
        verdict["baselines"] = baseline_reading(base_rows, paper)
    if chosen_on:
        verdict["chosen_on"] = chosen_on_summary(chosen_on)
    seeds = " ".join(str(int(x)) for x in sorted(large["seed"].unique())) if "seed" in large else "–"
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    csv, laws, js, md = out / "table_ii_readings.csv", out / "laws.csv", out / "verdict.json", out / "table_ii_readings.md"
    rows.merge(judged[["study", "run", "horizon_s", "checks_passed", "checks", "reproduces", "cost_reading"]]
               if len(judged) else pd.DataFrame(columns=["study", "run", "horizon_s"]),
               on=["study", "run", "horizon_s"], how="left").to_csv(csv, index=False)
    rule.to_csv(laws, index=False)
    js.write_text(json.dumps(verdict, indent=2, sort_keys=True) + "\n")
    paper_line = " · ".join(f"N={n}: {_pct(c['safety'])} % / {_pct(c['safe_scenarios'])} % / {c['cost']:.2f}"
                            for n, c in sorted(paper.cells.items()))
    text = [
        "# Table II under the readings the paper leaves open (issue 60; not in the paper)", "",
        verdict_sentence(verdict), "", *([chosen_on_line(verdict), ""] if verdict.get("chosen_on") else []),
        f"Scale, fixed before the cells ran ({PLAN} §3): at each N safety ≥ the paper's − {100 * SCALE.safety_points:g} points,",
        f"safe scenarios ≥ the paper's − {100 * SCALE.safe_points:g} points, and cost within ±{100 * SCALE.cost_relative:g} % of the paper's at every N",
        "in one cost reading (∫ over [0, T], or ∫ ÷ T; collision-free agents). A reading is a large-arena study",
        "(its start/goal law), a run (the deployment) and a horizon T read from the same episodes. Scenarios are",
        f"pooled over the reading's seeds (here: {seeds}); intervals are 95 % bootstraps over scenarios.", "",
        f"Paper (Table II, safety % / safe scenarios % / cost): {paper_line}.", "",
        "## Readings", "",
        "Per N: safety % [95 % CI] / safe scenarios % / cost ∫ / cost ÷T; checks passed of 3 per N (✔: reproduces).", "",
        to_markdown(readings_display(rows, judged, paper, settings)), "",
        "## What each deployment choice moves, on the same scenarios", "",
        f"Each run against the paper's deployment ({settings.protocol[1]}) under the same start/goal law, paired per scenario",
        "(same law, arena, N, seed and scenario index: the same layout, madpinn/scenarios.py), seeds pooled, at the",
        "episode's end: Δ safety in points [95 % paired bootstrap] / Δ cost ÷T over collision-free agents [95 %]. Not part",
        "of the scale (added after the cells ran): it says what each choice the paper leaves open buys and costs.", "",
        (to_markdown(effects_display(effects, settings)) if len(effects) else "No run besides the paper's deployment."), "",
        f"## The start/goal law at Table I's load ({PLAN} §1)", "",
        f"Rule: {verdict['law_rule']}. h = (1 − safety) / straight-line encounters per agent; the anchor is "
        f"{settings.anchor} at {settings.anchor_agents} agents, the same seed; load-matched = within ±{100 * SCALE.load_window:g} %.", "",
        to_markdown(laws_display(rule)) if len(rule) else "No anchor cells.", "",
        *(["## The baselines in the large arena (labelled rows the paper does not report)", "",
            f"Rule (fixed before the cells): {verdict['baselines']['reading']}"
            + (f" (reaching Table II's safety at every N: {', '.join(verdict['baselines']['reaching'])})" if verdict["baselines"]["reaching"] else "")
            + ". Per N: safety % [95 % CI] / safe scenarios % / cost ÷T / mean distance to the goal at T (m); the protocol's MAD-PINN reading first.",
            "The goal distance at T is not part of the rule (it was added after the cells ran): it tells safety kept while",
            "travelling from safety kept by not travelling (compare it with the trips' length: `python scripts/scenario_layout.py`).", "",
            to_markdown(baselines_display(base_rows, rows[(rows["study"] == settings.protocol[0]) & (rows["run"] == settings.protocol[1])],
                                          paper, settings)), ""] if len(base_rows) else []),
        "## Collided share by encounter speed", "",
        "Each agent's relative speed to its nearest agent at its first collision, else at its closest approach.", "",
        to_markdown(speed_display(large, settings)),
    ]
    md.write_text("\n".join(text))
    page = out / "table_ii_readings.html"
    page.write_text(markdown_page(md.read_text(), "table_ii_readings"))
    return [csv, md, page, js, laws]
