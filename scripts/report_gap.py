"""Before / after the protocol rerun: every paper cell of two reproduction reports side by side.

    PYTHONPATH=$PWD python scripts/report_gap.py git:b3c6574:paper_figures/reproduction.json \
        paper_figures/reproduction.json [--tables table_safety_scaling ...] [--exclude RUN ...] \
        [--rename OLD=NEW ...]

Each report is a path or ``git:REV:PATH`` (the committed report of an older protocol). Prints, per
cell that the paper reports (its safety is known), the paper's safety and time-averaged cost, ours
before and after, and the mean |ours − paper| safety and safe-scenario rate over the cells both
reports hold (in points), the figure the issues quote ("12.0 points over 34 cells").
"""
from __future__ import annotations

import argparse
import json
import subprocess
import sys


def load(spec: str) -> dict:
    if spec.startswith("git:"):
        _, rev, path = spec.split(":", 2)
        return json.loads(subprocess.run(["git", "show", f"{rev}:{path}"], check=True, capture_output=True,
                                         text=True).stdout)
    with open(spec) as f:
        return json.load(f)


def cells(report: dict, tables: list[str] | None) -> dict[tuple[str, str, str], dict]:
    """``(table, run, N) -> cell`` for the cells with a paper safety value."""
    out = {}
    for table, runs in report.items():
        if table == "provenance" or (tables and table not in tables):
            continue
        for run, by_n in runs.items():
            for n, c in by_n.items():
                if isinstance(c, dict) and c.get("paper_safety") is not None:
                    out[(table, run, n)] = c
    return out


def pct(x) -> str:
    return "–" if x is None else f"{100 * x:.1f}"


def cost(x) -> str:
    return "–" if x is None else f"{x:.2f}"


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("before")
    p.add_argument("after")
    p.add_argument("--tables", nargs="+", help="paper tables to compare (default: all)")
    p.add_argument("--exclude", nargs="+", default=[], help="runs left out of both (e.g. extensions compared "
                   "with a paper row: madpinn-lookahead)")
    p.add_argument("--rename", nargs="+", default=[], metavar="OLD=NEW",
                   help="run names of the first report as the second calls them (e.g. madpinn-measured=madpinn "
                        "for reports before the paper's deployment became `madpinn`)")
    a = p.parse_args(argv)
    rename = dict(r.split("=", 1) for r in a.rename)
    before = {(t, rename.get(r, r), n): c for (t, r, n), c in cells(load(a.before), a.tables).items()
              if r not in rename.values() or r in rename}   # a renamed-onto name of the old report is replaced
    before = {k: c for k, c in before.items() if k[1] not in a.exclude}
    after = {k: c for k, c in cells(load(a.after), a.tables).items() if k[1] not in a.exclude}
    keys = [k for k in before if k in after] + [k for k in after if k not in before]
    print("| table | run | N | paper safety % | before % | after % | paper cost ÷T | before cost ÷T | after cost ÷T |")
    print("|---|---|---|---|---|---|---|---|---|")
    for k in keys:
        b, c = before.get(k, {}), after[k]
        print(f"| {k[0].removeprefix('table_')} | {k[1]} | {k[2]} | {pct(c['paper_safety'])} | {pct(b.get('safety'))} | "
              f"{pct(c['safety'])} | {cost(c.get('paper_cost'))} | {cost(b.get('cost_time_avg'))} | {cost(c.get('cost_time_avg'))} |")
    both = [k for k in keys if k in before]
    for metric, paper in (("safety", "paper_safety"), ("safe_scenarios", "paper_safe_scenarios")):
        pairs = [(before[k], after[k]) for k in both if after[k].get(paper) is not None]
        if not pairs:
            continue
        gap = lambda side: 100 * sum(abs(s[metric] - s[paper]) for s in side) / len(side)   # noqa: E731
        print(f"\nmean |ours − paper| {metric}: before {gap([b for b, _ in pairs]):.1f} points, "
              f"after {gap([c for _, c in pairs]):.1f} points ({len(pairs)} cells in both reports)")
    missing = [k for k in before if k not in after]
    if missing:
        print(f"\n{len(missing)} cells of the first report are not in the second: {missing[:5]} …", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
