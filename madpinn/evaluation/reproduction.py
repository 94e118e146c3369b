"""Reproduction report: every paper table, our mean ± std beside the paper's value.

:func:`build_report` turns result files (and oracle cache files) into
``{table: {run: {N: {safety, safety_std, safe_scenarios, safe_scenarios_std, cost, cost_std,
cost_time_avg, cost_time_avg_std, cost_all, cost_all_time_avg, n_seeds, paper_safety,
paper_safety_std, paper_safe_scenarios, paper_safe_scenarios_std, paper_cost}}}}`` plus
``provenance`` (config hash, sha256 of every model file, the deployment settings of our
MAD-PINN runs that the paper does not have) and per-table notes;
:func:`write_report` writes it as ``reproduction.json`` and ``reproduction.md``.

Paper values come from ``paper_values.yaml`` (one transcription, citing the .tex lines). The
paper's costs are compared with our *time-averaged* cost (SPEC §3): "Δ cost" is ours ÷T minus the
paper's. Oracle rows (run ``oracle``) carry only costs. A paper row may name more of our runs
(``also``) that measure the same method with our labelled extensions (e.g. ``madpinn-lookahead``
beside ``madpinn``, the paper's deployment); they show the same paper values.

Uncertainty (issue 47, :mod:`madpinn.evaluation.intervals`): every cell of ours carries a 95 %
interval (``<figure>_ci``: t over seeds for multi-seed cells, the bootstrap over scenarios for
single-seed ones; ``interval`` names which), and every run other than the table's "Ours"
(:func:`reference_run`) its paired difference from Ours on the same scenarios (``vs_ours``:
``{reference, interval, n_seeds, n_pairs, <figure>: {diff, lo, hi}}``). Beside the protocol's
d ≤ r, each cell also reads safety at the disc reading d ≤ 2r (``safety_2r``) and where the
drones' bodies touch, d ≤ 0.12 m (``safety_contact``, :mod:`madpinn.evaluation.contact`).
"""

from __future__ import annotations

import json
import math
import re
from pathlib import Path
from typing import Iterable, Mapping

import pandas as pd
import yaml

from madpinn.checksum import sha256
from madpinn.config import config_hash, method_config, study_pattern
from madpinn.evaluation.contact import contact_distance, with_contact
from madpinn.evaluation.intervals import BOOTSTRAP_METHOD, T_METHOD, interval_method, paired_differences
from madpinn.evaluation.tables import ORACLE_LABEL, ORACLE_RUN, load_results, oracle_summary, load_oracle, summarize

PAPER_VALUES = Path(__file__).with_name("paper_values.yaml")
OURS = "madpinn"
"""the run of the paper's deployment, "Ours" of every paired difference"""
_FROM_AGG = {"safety": "safety_rate_mean", "safety_std": "safety_rate_std", "safe_scenarios": "safe_scenarios_mean",
             "safe_scenarios_std": "safe_scenarios_std", "cost": "cost_mean", "cost_std": "cost_std",
             "cost_time_avg": "cost_time_avg_mean", "cost_time_avg_std": "cost_time_avg_std",
             "cost_all": "cost_all_mean", "cost_all_time_avg": "cost_all_time_avg_mean",
             "safety_2r": "safety_rate_2r_mean", "safe_scenarios_2r": "safe_scenarios_2r_mean",
             "safety_contact": "safety_rate_contact_mean", "safe_scenarios_contact": "safe_scenarios_contact_mean"}
FIGURES = {"safety": "safety_rate", "safe_scenarios": "safe_scenarios", "cost_time_avg": "cost_time_avg",
           "safety_2r": "safety_rate_2r", "safety_contact": "safety_rate_contact"}
"""report figure -> seed figure: each has a 95 % interval ``<figure>_ci`` and a paired difference in ``vs_ours``"""
_OURS = (*_FROM_AGG, *(f"{k}_ci" for k in FIGURES), "interval", "vs_ours")


def paper_values(path: str | Path = PAPER_VALUES) -> dict:
    """``{table: {"note", "tex_lines", "runs": {run: {"label", "tex_line", "n": {N: {metric: value}}}}}}``."""
    raw = yaml.safe_load(Path(path).read_text())
    out = {}
    for table, t in raw["tables"].items():
        runs = {}
        for run, r in t["runs"].items():
            cells = {}
            for n, v in r["n"].items():
                cells[int(n)] = dict(zip(t["columns"], v)) if isinstance(v, list) else dict(v)
            runs[run] = {"label": r["label"], "tex_line": r["tex_line"], "n": cells, "also": list(r.get("also", []))}
        out[table] = {"note": t.get("note", ""), "tex_lines": t["tex_lines"], "runs": runs}
    return out


def paper_row_of(ref_runs: Mapping[str, dict]) -> dict[str, dict]:
    """Our run -> the paper row it is compared with: each row's own run and the runs it lists in ``also``."""
    rows = {}
    for run, row in ref_runs.items():
        for ours in (run, *row.get("also", [])):
            rows.setdefault(ours, row)
    return rows


def deployment(cfg: Mapping, runs: Iterable[str]) -> dict[str, dict]:
    """The deployment settings of our MAD-PINN runs that are not the paper's: ``{run: {look_ahead,
    safety_filter}}`` (look-ahead τ in s, 0 = the paper's measured state; safety_filter: the CBVF
    extension is on), for every ``madpinn*`` run among ``runs``, read from the run's
    :class:`~madpinn.policies.madpinn.MadPinnSettings`."""
    from madpinn.policies import policy_settings

    out = {}
    for run in sorted(set(runs)):
        if run.partition("-")[0] != "madpinn" or "madpinn" not in cfg["methods"]:
            continue
        method, mcfg = method_config(cfg, run)
        settings = policy_settings(method, mcfg)
        out[run] = {"label": str(mcfg["label"]), "look_ahead": settings.look_ahead,
                    "safety_filter": settings.safety_filter is not None}
    return out


def collision_convention(cfg: Mapping) -> str:
    """The collision reading the report's safety figures were measured under (SPEC §1, issue 38)."""
    r = float(cfg["agents"]["collision_radius"])
    physics = ("contact physics (MuJoCo: CF2X collision cylinders and a floor; double integrator: "
               "collided agents freeze)" if cfg["sim"].get("contacts") else "agents pass through each other")
    return (f"collision counted at centre distance d ≤ r = {r:g} m, {physics}; the disc reading d ≤ 2r "
            f"= {2 * r:g} m and the physical-contact reading d ≤ {contact_distance():g} m (the CF2X bodies touch) "
            "are reported beside it, from the same episodes' minimum separations (docs/reference/collisions.md)")


def reference_run(cfg: Mapping, runs: Iterable[str]) -> str | None:
    """The table's "Ours": :data:`OURS` when among ``runs``, else the first ``madpinn-<variant>`` run
    whose method settings equal the paper's deployment's but for the label (Table III's
    ``madpinn-value``, Table IV's ``madpinn-k5``); None when there is none."""
    runs = list(dict.fromkeys(runs))
    if OURS in runs:
        return OURS
    if OURS not in cfg["methods"]:
        return None
    unlabelled = lambda run: {k: v for k, v in method_config(cfg, run)[1].items() if k != "label"}   # noqa: E731
    base = unlabelled(OURS)
    for run in runs:
        if run.partition("-")[0] == OURS:
            try:
                if unlabelled(run) == base:
                    return run
            except Exception:  # noqa: BLE001 - a result of a run no longer configured is never Ours
                continue
    return None


def _interval(lo, hi) -> list[float] | None:
    lo, hi = _num(lo), _num(hi)
    return None if lo is None or hi is None else [lo, hi]


def _vs_ours(diffs: pd.DataFrame) -> dict[tuple[str, int], dict]:
    """``{(run, N): vs_ours}`` from :func:`~madpinn.evaluation.intervals.paired_differences` rows."""
    out = {}
    for _, d in diffs.iterrows():
        entry = {"reference": str(d["reference"]), "interval": str(d["interval"]), "n_seeds": int(d["n_seeds"]),
                 "n_pairs": int(d["n_pairs"])}
        for k, m in FIGURES.items():
            entry[k] = ({"diff": _num(d[f"{m}_diff"]), "lo": _num(d[f"{m}_diff_lo"]), "hi": _num(d[f"{m}_diff_hi"])}
                        if f"{m}_diff" in d else None)
        out[(str(d["run"]), int(d["n_agents"]))] = entry
    return out


def _num(x) -> float | None:
    return None if x is None or (isinstance(x, float) and math.isnan(x)) else float(x)


def build_report(tables: Mapping[str, Iterable[str | Path]], cfg: dict, oracle_paths: Iterable[str | Path] = (),
                 model_paths: Iterable[str | Path] = (), paper: dict | None = None) -> dict:
    """``tables``: table name -> its result files (.parquet). Runs of the paper that we did not
    run keep their paper values with our figures null; runs we have and the paper lacks get null
    paper values."""
    paper = paper_values() if paper is None else paper
    oracle = load_oracle(oracle_paths) if list(oracle_paths := list(oracle_paths)) else None
    report, notes, seen = {}, {}, set()
    for name, paths in tables.items():
        df = load_results(paths)
        agg = summarize(df, cfg)
        if oracle is not None:   # the bounds of this table's scenarios (uniform, or its conflict pattern)
            patterns = {study_pattern(cfg["studies"].get(st, {})) for st in set(df["study"])}
            mine = oracle[oracle["pattern"].isin(patterns)]
            agg = pd.concat([agg, oracle_summary(mine, df)], ignore_index=True)
        ref = paper.get(name, {"runs": {}, "note": "not a table of the paper", "tex_lines": None})
        notes[name] = {"paper_note": ref["note"], "tex_lines": ref["tex_lines"]}
        rows = paper_row_of(ref["runs"])
        ours = reference_run(cfg, [r for r in agg["run"] if r != ORACLE_RUN])
        vs = _vs_ours(paired_differences(with_contact(df), ours)) if ours else {}
        table: dict = {}
        for _, r in agg.iterrows():
            run, n = str(r["run"]), int(r["n_agents"])
            seen.add(run)
            p = rows.get(run, {}).get("n", {}).get(n, {})
            cell = {k: _num(r.get(col)) for k, col in _FROM_AGG.items()}
            cell.update({f"{k}_ci": _interval(r.get(f"{m}_ci_lo"), r.get(f"{m}_ci_hi")) for k, m in FIGURES.items()})
            cell.update(interval=interval_method(int(r["n_seeds"])) if run != ORACLE_RUN else None,
                        vs_ours=vs.get((run, n)))
            cell.update(label=str(r["label"]), n_seeds=int(r["n_seeds"]), paper_safety=_num(p.get("safety")),
                        paper_safety_std=_num(p.get("safety_std")), paper_safe_scenarios=_num(p.get("safe_scenarios")),
                        paper_safe_scenarios_std=_num(p.get("safe_scenarios_std")), paper_cost=_num(p.get("cost")))
            table.setdefault(run, {})[str(n)] = cell
        for run, pr in ref["runs"].items():   # paper rows we did not run
            for n, p in pr["n"].items():
                if str(n) not in table.get(run, {}):
                    cell = {k: None for k in _OURS}
                    cell.update(label=pr["label"], n_seeds=0, paper_safety=_num(p.get("safety")),
                                paper_safety_std=_num(p.get("safety_std")), paper_safe_scenarios=_num(p.get("safe_scenarios")),
                                paper_safe_scenarios_std=_num(p.get("safe_scenarios_std")), paper_cost=_num(p.get("cost")))
                    table.setdefault(run, {})[str(n)] = cell
        report[name] = _ordered(table, list(rows))
        notes[name]["ours"] = ours
    models = sorted({str(p) for p in model_paths})
    cells = _cell_time(p for paths in tables.values() for p in paths)
    report["provenance"] = {   # no commit and no date: identical inputs, identical bytes (the commit: the job's side file)
        "experiment": cfg.get("experiment"),
        "config_hash": config_hash(cfg),
        "backend": cfg["sim"]["backend"],
        "collisions": collision_convention(cfg),
        "models": {p: sha256(p) for p in models},
        "cells": cells,
        "paper_values": f"madpinn/evaluation/{PAPER_VALUES.name} (from {paper_values_source()})",
        "deployment": deployment(cfg, seen),
        "intervals": f"95 % intervals: {T_METHOD} (Student t over the per-seed figures) for cells with several "
                     f"seeds, {BOOTSTRAP_METHOD} (percentile, 2000 resamples) for single-seed cells; vs_ours: run − the "
                     "table's Ours on the same (arena, N, seed, scenario), t over the per-seed differences or a paired "
                     "bootstrap over scenarios (madpinn/evaluation/intervals.py)",
        "cost_definition": "cost: mean over collision-free agents of ∫‖p−g‖dt + ‖p(T)−g‖ (m·s + m); "
                           "cost_time_avg: the same ÷ episode length T (compared with the paper's cost); "
                           "cost_all*: over all agents; oracle: lone-agent lower bound on the same scenarios",
        "tables": notes,
    }
    return report


def _ordered(table: dict, paper_runs: list[str]) -> dict:
    """Runs in the paper's row order (a row's ``also`` runs right after it), then ours the paper lacks (in the order met), the oracle
    last; each run's cells by ascending N."""
    rank = {run: i for i, run in enumerate(paper_runs)}
    met = {run: i for i, run in enumerate(table)}
    runs = sorted(table, key=lambda r: (r == ORACLE_RUN, rank.get(r, len(rank)), met[r]))
    return {r: dict(sorted(table[r].items(), key=lambda kv: int(kv[0]))) for r in runs}


def paper_table_numbers(path: str | Path = PAPER_VALUES) -> dict[str, str]:
    """``{table name: the paper's table number}`` ("I" … "IV"), read from each table's
    ``tex_lines`` ("357-375 (Table I, rows 365-369)")."""
    numbers = {}
    for name, t in paper_values(path).items():
        m = re.search(r"Table ([IVX]+)\b", t["tex_lines"])
        if m:
            numbers[name] = m.group(1)
    return numbers


def paper_values_source() -> str:
    return yaml.safe_load(PAPER_VALUES.read_text())["source"]


def _pct(x, std=None, n_seeds=2, ci=None) -> str:
    """``98.4% ± 1.4% [96.7, 100.0]``: mean, ± std over seeds (several seeds), [95 % interval] when given."""
    if x is None:
        return "–"
    return (f"{100 * x:.1f}%" + (f" ± {100 * std:.1f}%" if std is not None and n_seeds > 1 else "")
            + (f" [{100 * ci[0]:.1f}, {100 * ci[1]:.1f}]" if ci else ""))


def _val(x, std=None, n_seeds=2, ci=None) -> str:
    if x is None:
        return "–"
    return (f"{x:.2f}" + (f" ± {std:.2f}" if std is not None and n_seeds > 1 else "")
            + (f" [{ci[0]:.2f}, {ci[1]:.2f}]" if ci else ""))


def _paired(d: dict | None, pct: bool) -> str:
    """``+1.9 pp [1.0, 2.7]`` (pct) or ``-0.03 [-0.04, -0.02]``: a paired difference with its interval."""
    if not d or d["diff"] is None:
        return "–"
    if pct:
        ci = f" [{100 * d['lo']:+.1f}, {100 * d['hi']:+.1f}]" if d["lo"] is not None else ""
        return f"{100 * d['diff']:+.1f} pp{ci}"
    ci = f" [{d['lo']:+.3f}, {d['hi']:+.3f}]" if d["lo"] is not None else ""
    return f"{d['diff']:+.3f}{ci}"


def _diff(ours, paper, pct: bool) -> str:
    if ours is None or paper is None:
        return "–"
    d = ours - paper
    return f"{100 * d:+.1f} pp" if pct else f"{d:+.2f}"


def _cell_time(parquets: Iterable[str | Path]) -> dict:
    """``{count, time_h, devices}`` of the distinct evaluation cells behind the tables, from each
    cell's summary (``<cell>.json`` beside its Parquet file; ``elapsed_s`` measured in the job on the
    machine that computed it, which for a cell restored from the output cache is an earlier run's)."""
    seconds, devices = {}, set()
    for p in {str(p) for p in parquets}:
        summary = Path(p).with_suffix(".json")
        if summary.exists():
            s = json.loads(summary.read_text())
            seconds[p] = float(s.get("elapsed_s", 0.0))
            devices.add(str(s.get("device", "?")))
    return {"count": len(seconds), "time_h": round(sum(seconds.values()) / 3600, 3), "devices": sorted(devices)}


def _deployment_lines(runs: Mapping[str, dict]) -> list[str]:
    """One line per look-ahead τ > 0 among our MAD-PINN runs (a deployment the paper does not have)."""
    lines = []
    for tau in sorted({d["look_ahead"] for d in runs.values() if d["look_ahead"] > 0}):
        with_tau = [f"`{r}`" for r, d in runs.items() if d["look_ahead"] == tau]
        without = [f"`{d['label']}` (`{r}`)" for r, d in runs.items() if d["look_ahead"] == 0]
        lines.append(f"- deployment not in the paper: runs {', '.join(with_tau)} build V̂'s observation from the own "
                     f"state predicted {1000 * tau:.0f} ms ahead under the last command and the others' at constant "
                     "velocity (actuator-lag look-ahead, `methods.madpinn.look_ahead`)"
                     + (f"; {', '.join(without)} keep the paper's measured state" if without else ""))
    return lines


def to_markdown(report: dict) -> str:
    prov = report["provenance"]
    lines = [
        "# Reproduction report",
        "",
        "Generated by the workflow (`snakemake -j2 reproduction_report`; madpinn/evaluation/reproduction.py) from the "
        "result files. Ours: mean ± std over seeds and the 95 % interval (single-seed studies: the mean and its interval). Paper: its tables "
        f"({prov['paper_values']}). The paper's cost is compared with our **cost ÷T** (the cumulative cost divided by "
        "the episode length, SPEC §3); **cum.** is the integral ∫‖p−g‖dt + ‖p(T)−g‖ itself. Costs are over "
        "collision-free agents. The oracle row is the lone-agent lower bound on the same scenarios "
        "(madpinn/evaluation/oracle.py). Δ: ours − paper (pp: percentage points).",
        "",
        f"- experiment `{prov['experiment']}`, config hash `{prov['config_hash']}`, "
        f"backend `{prov['backend']}`",
        f"- collisions: {prov.get('collisions', 'collision counted at d ≤ r (not recorded)')}",
    ]
    for path, digest in prov["models"].items():
        lines.append(f"- model `{path}`: sha256 `{digest}`")
    if "cells" in prov:
        c = prov["cells"]
        lines.append(f"- {c['count']} evaluation cells, {c['time_h']:.2f} h of cell time (sum of the cells' `elapsed_s`, "
                     f"one thread each; devices: {', '.join(c['devices']) or 'n/a'})")
    lines += _deployment_lines(prov.get("deployment", {}))
    lines.append(f"- intervals: {prov['intervals']}" if "intervals" in prov else "- intervals: not recorded")
    contact = f"{contact_distance():g} m"
    head = ("Run", "N", "Safety (ours)", "Safety (paper)", "Δ", "Safe sc. (ours)", "Safe sc. (paper)", "Δ",
            "Cost ÷T (ours)", "Cost (paper)", "Δ", "Cum. cost (ours)", "Safety d ≤ 2r (ours)", f"Safety d ≤ {contact} (ours)")
    pair_head = ("Run", "N", "Δ safety", "Δ safe sc.", "Δ cost ÷T", "Δ safety d ≤ 2r", f"Δ safety d ≤ {contact}",
                 "paired on", "interval")
    for name, table in report.items():
        if name == "provenance":
            continue
        note = prov["tables"][name]
        about = (f"Paper: tex lines {note['tex_lines']}. {note['paper_note']}" if note["tex_lines"]
                 else "Not a table of the paper (no paper values).")
        lines += ["", f"## {name}", "", about.strip(), "",
                  "Ours: mean ± std over seeds [95 % interval]; paper: mean ± std.", "",
                  "| " + " | ".join(head) + " |", "|" + "|".join(["---"] * len(head)) + "|"]
        pairs = []
        for run, cells in table.items():
            for n, c in cells.items():
                k = c["n_seeds"]
                row = (c["label"] if run != ORACLE_RUN else f"**{ORACLE_LABEL}**", n,
                       _pct(c["safety"], c["safety_std"], k, c.get("safety_ci")),
                       _pct(c["paper_safety"], c["paper_safety_std"]),
                       _diff(c["safety"], c["paper_safety"], True),
                       _pct(c["safe_scenarios"], c["safe_scenarios_std"], k, c.get("safe_scenarios_ci")),
                       _pct(c["paper_safe_scenarios"], c["paper_safe_scenarios_std"]),
                       _diff(c["safe_scenarios"], c["paper_safe_scenarios"], True),
                       _val(c["cost_time_avg"], c["cost_time_avg_std"], k, c.get("cost_time_avg_ci")), _val(c["paper_cost"]),
                       _diff(c["cost_time_avg"], c["paper_cost"], False), _val(c["cost"], c["cost_std"], k),
                       _pct(c.get("safety_2r"), None, k, c.get("safety_2r_ci")),
                       _pct(c.get("safety_contact"), None, k, c.get("safety_contact_ci")))
                lines.append("| " + " | ".join(map(str, row)) + " |")
                v = c.get("vs_ours")
                if v:
                    pairs.append((c["label"], n, _paired(v["safety"], True), _paired(v["safe_scenarios"], True),
                                  _paired(v["cost_time_avg"], False), _paired(v["safety_2r"], True),
                                  _paired(v["safety_contact"], True), f"{v['n_seeds']} seeds, {v['n_pairs']} scenarios",
                                  v["interval"]))
        if pairs:
            ref = note.get("ours")
            ref_label = next(iter(table.get(ref, {}).values()), {}).get("label", ref)
            lines += ["", f"Paired differences, run − Ours (`{ref}`, {ref_label}) on the same scenarios, "
                          "mean [95 % interval]:", "",
                      "| " + " | ".join(pair_head) + " |", "|" + "|".join(["---"] * len(pair_head)) + "|"]
            lines += ["| " + " | ".join(map(str, row)) + " |" for row in pairs]
    return "\n".join(lines) + "\n"


def write_report(out_dir: str | Path, tables: Mapping[str, Iterable[str | Path]], cfg: dict, **kwargs) -> list[Path]:
    """Write ``reproduction.json``, ``reproduction.md`` and ``reproduction.html`` (the page the
    Snakemake report shows) into ``out_dir``; kwargs: :func:`build_report`."""
    from madpinn.evaluation.html import markdown_page

    report = build_report(tables, cfg, **kwargs)
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    js, md = out_dir / "reproduction.json", out_dir / "reproduction.md"
    js.write_text(json.dumps(report, indent=2, ensure_ascii=False))
    md.write_text(to_markdown(report))
    page = out_dir / "reproduction.html"
    page.write_text(markdown_page(md.read_text(), "Reproduction report"))
    return [js, md, page]
