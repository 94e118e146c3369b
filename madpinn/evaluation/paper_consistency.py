"""The paper's numbers checked against each other (issue 61): arithmetic that every table of
paper_values.yaml must satisfy, computed from that file alone.

Each printed value stands for an interval: ± half a unit of its last printed digit (12.34 % ->
± 0.005 pp). A check fails only when no values inside those intervals satisfy it:

- **safety vs safe scenarios**: a collision involves at least two agents (``collision_agents``), so a
  failing scenario of N agents has between 2 and N collided agents: 2 (1 − f) / N ≤ 1 − s ≤ 1 − f
  (s: safety, f: safe scenarios; linear, so it holds for means over seeds too);
- **scenario counts**: (1 − f) × scenarios is a whole number of failing scenarios;
- **mean ± std over the seeds** within [0, 1], and no smaller than the least std that per-seed
  fractions on the scenario grid allow (each reading of "100 initial conditions across 5 seeds");
- **rows that must agree**: the ``same_cells`` the paper reports in more than one table.
"""

from __future__ import annotations

import math
from pathlib import Path

import yaml

from madpinn.evaluation.reproduction import PAPER_VALUES, paper_table_numbers, paper_values

KEYS = ("safety", "safe_scenarios", "cost")


def raw(path: str | Path = PAPER_VALUES) -> dict:
    return yaml.safe_load(Path(path).read_text())


def half_unit(v: float, scale: float = 100.0) -> float:
    """Half a unit of the last digit ``v`` is printed with (fractions printed as percentages)."""
    text = f"{round(v * scale, 6):g}"
    decimals = len(text.partition(".")[2])
    return 0.5 * 10 ** -decimals / scale


def _box(v: float, scale: float = 100.0) -> tuple[float, float]:
    h = half_unit(v, scale)
    return max(v - h, 0.0), min(v + h, 1.0) if scale == 100.0 else v + h


def scenario_readings(table: str, proto: dict) -> dict[str, tuple[int, int]]:
    """``{reading: (seeds, scenarios per seed)}`` of ``table``'s cells."""
    if table == "table_ours_scaling":
        return {f"{proto['large_arena_scenarios']} scenarios, one seed": (1, proto["large_arena_scenarios"])}
    seeds, total = proto["seeds"], proto["initial_conditions"]
    return {f"{total} per seed": (seeds, total), f"{total} in all ({total // seeds} per seed)": (seeds, total // seeds)}


def _row(table, run, label, n, check, expected, observed, ok, reading="") -> dict:
    return {"table": table, "run": run, "label": label, "n": n, "check": check, "expected": expected,
            "observed": observed, "holds": ok, "reading": reading}


def collided_share(table, run, label, n, c, m) -> list[dict]:
    """Safety against safe scenarios: 1 − s within [2 (1 − f) / N, 1 − f]."""
    s_lo, s_hi = _box(c["safety"])
    f_lo, f_hi = _box(c["safe_scenarios"])
    ok = (1 - s_hi) <= (1 - f_lo) and (1 - s_lo) >= m * (1 - f_hi) / n
    share = (1 - c["safety"]) / (1 - c["safe_scenarios"]) if c["safe_scenarios"] < 1 else None
    observed = (f"1 − s = {100 * (1 - c['safety']):.4g} %, 1 − f = {100 * (1 - c['safe_scenarios']):.4g} %"
                + (f": {share * n:.3g} collided agents per failing scenario ({share:.3g} of N)" if share is not None else ""))
    expected = f"{m} … {n} collided agents per failing scenario: 1 − s in [{m}(1 − f)/{n}, 1 − f]"
    return [_row(table, run, label, n, "safety vs safe scenarios", expected, observed, ok)]


def counts(table, run, label, n, c, readings) -> list[dict]:
    """(1 − f) × scenarios a whole number (single-seed tables: per seed; else in all)."""
    out = []
    f_lo, f_hi = _box(c["safe_scenarios"])
    for reading, (seeds, per_seed) in readings.items():
        total = seeds * per_seed
        lo, hi = (1 - f_hi) * total, (1 - f_lo) * total
        ok = math.floor(hi + 1e-9) >= math.ceil(lo - 1e-9)
        out.append(_row(table, run, label, n, "whole failing scenarios", f"(1 − f) × {total} a whole number",
                        f"{(1 - c['safe_scenarios']) * total:.3g}", ok, reading))
    return out


def least_std(mean_lo: float, mean_hi: float, seeds: int, grid: int) -> float | None:
    """The least population std of ``seeds`` fractions on the grid 1/``grid`` whose mean lies in
    [mean_lo, mean_hi]; None when no such mean exists."""
    ks = range(math.ceil(seeds * grid * mean_lo - 1e-9), math.floor(seeds * grid * mean_hi + 1e-9) + 1)
    best = None
    for k in ks:
        q, r = divmod(k, seeds)
        vals = [(q + 1) / grid] * r + [q / grid] * (seeds - r)
        mu = sum(vals) / seeds
        sd = math.sqrt(sum((v - mu) ** 2 for v in vals) / seeds)
        best = sd if best is None else min(best, sd)
    return best


def spreads(table, run, label, n, c, readings) -> list[dict]:
    """mean ± std within [0, 1]; std no smaller than the grid of per-seed fractions allows."""
    out = []
    for key, word in (("safety", "safety"), ("safe_scenarios", "safe scenarios")):
        std = c.get(f"{key}_std")
        if std is None:
            continue
        mean, hs = c[key], half_unit(std)
        slack = hs + half_unit(mean)
        out.append(_row(table, run, label, n, f"{word}: mean ± std in [0, 100 %]", "0 ≤ mean − std, mean + std ≤ 100 %",
                        f"{100 * mean:.4g} ± {100 * std:.3g} %", mean - std >= -slack and mean + std <= 1 + slack))
        for reading, (seeds, per_seed) in readings.items():
            grid = per_seed * (n if key == "safety" else 1)
            m_lo, m_hi = _box(mean)
            least = least_std(m_lo, m_hi, seeds, grid)
            ok = least is not None and std + hs >= least - 1e-12
            out.append(_row(table, run, label, n, f"{word}: std reachable on the per-seed grid",
                            f"std ≥ the least std of {seeds} seeds' fractions on a 1/{grid} grid"
                            + (f" ({100 * least:.3g} %)" if least is not None else " (no such mean)"),
                            f"{100 * std:.3g} %", ok, reading))
    return out


def agreement(values: dict, groups: list[list[str]]) -> list[dict]:
    """Each figure given by two or more cells of a group agrees within the printed digits."""
    out = []
    for group in groups:
        cells = {}
        for key in group:
            table, run, n = key.split("/")
            c = values.get(table, {}).get("runs", {}).get(run, {}).get("n", {}).get(int(n))
            if c:
                cells[key] = c
        for fig in KEYS:
            vals = {k: c[fig] for k, c in cells.items() if c.get(fig) is not None}
            if len(vals) < 2:
                continue
            scale = 1.0 if fig == "cost" else 100.0
            los, his = zip(*(_box(v, scale) for v in vals.values()))
            ok = max(los) <= min(his) + 1e-12
            shown = "; ".join(f"{k.split('/')[0]} {v:g}" for k, v in vals.items())
            out.append(_row(" = ".join(sorted({k.split('/')[0] for k in vals})), "", "same cell", "", f"{fig} agrees across tables",
                            "one value within the printed digits", shown, ok))
    return out


def check_paper(path: str | Path = PAPER_VALUES) -> list[dict]:
    """Every consistency check of the paper's tables; ``holds`` False: the numbers cannot all be true."""
    values, r = paper_values(path), raw(path)
    proto = r["protocol"]
    out = []
    for table, t in values.items():
        readings = scenario_readings(table, proto)
        for run, row in t["runs"].items():
            for n, c in sorted(row["n"].items()):
                if c.get("safety") is None or c.get("safe_scenarios") is None:
                    continue
                out += collided_share(table, run, row["label"], n, c, proto["collision_agents"])
                out += counts(table, run, row["label"], n, c, readings)
                out += spreads(table, run, row["label"], n, c, readings)
    out += agreement(values, r.get("same_cells", []))
    numbers = paper_table_numbers(path)
    for row in out:
        row["paper_table"] = " = ".join(f"Table {numbers.get(t, t)}" for t in row["table"].split(" = "))
    return out
