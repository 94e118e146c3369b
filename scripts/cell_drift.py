"""How much an evaluation cell moves when it is recomputed: each cell summary under ``--results``
(``<study>/<run>/n<N>_seed<S>.json``) against every other summary of the same (study, run, N,
seed) in ``--cache`` (the output cache keeps the entries of earlier runs, e.g. computed on another
CPU or before a source-hash change that left the method's code as it was).

    python scripts/cell_drift.py --results results/eval/mujoco --cache output_cache [--runs mppi safemarl ...] [--studies scaling ...]

Prints, per run: cells compared, cells bit-identical in their metrics, and the largest and mean
absolute change of safety rate (points), safe scenarios (points) and time-averaged cost. A cell
that changed because its method changed (e.g. a new policy setting) is drift by design: pass
``--runs`` to compare only the runs whose code and settings are the same in both.
"""

from __future__ import annotations

import argparse
import json
from collections import defaultdict
from pathlib import Path

from madpinn.machine import cpu_model

METRICS = ("safety_rate", "safe_scenarios", "cost_time_avg")


def key(summary: dict) -> tuple:
    return summary["study"], summary["run"], int(summary["n_agents"]), int(summary["seed"])


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--results", default="results/eval/mujoco")
    ap.add_argument("--cache", default="output_cache")
    ap.add_argument("--runs", nargs="*", default=None, help="only these runs (default: all)")
    ap.add_argument("--studies", nargs="*", default=None, help="only these studies (default: all)")
    ap.add_argument("--this-cpu", action="store_true",
                    help="only cells whose summary names this machine's CPU (computed here since cells record it)")
    args = ap.parse_args()
    earlier = defaultdict(list)
    for f in Path(args.cache).glob("*_summary.json"):
        earlier[key(json.loads(f.read_text()))].append(f.resolve())
    rows = defaultdict(lambda: {"cells": 0, "identical": 0, **{m: [] for m in METRICS}})
    for f in sorted(Path(args.results).glob("*/*/n*_seed*.json")):
        now = json.loads(f.read_text())
        if (args.runs and now["run"] not in args.runs) or (args.studies and now["study"] not in args.studies):
            continue
        if args.this_cpu and now.get("cpu_model") != cpu_model():
            continue
        # not the cell's own entry: the same file, or its copy under the same cache key (a cell published
        # from results/output_cache/ into output_cache/ keeps its file name, <key>_summary.json)
        others = [json.loads(o.read_text()) for o in earlier.get(key(now), []) if o.name != f.resolve().name]
        if not others:
            continue
        r = rows[now["run"]]
        r["cells"] += 1
        r["identical"] += any(all(o[m] == now[m] for m in METRICS) for o in others)
        for m in METRICS:   # against the closest earlier entry
            r[m].append(min(abs(now[m] - o[m]) for o in others))
    print("| run | cells | identical | max / mean abs Δ safety (pp) | max / mean abs Δ safe sc. (pp) | max / mean abs Δ cost ÷T |")
    print("|---|---|---|---|---|---|")
    for run, r in sorted(rows.items()):
        s, sc, c = r["safety_rate"], r["safe_scenarios"], r["cost_time_avg"]
        print(f"| {run} | {r['cells']} | {r['identical']} | {100 * max(s):.2f} / {100 * sum(s) / len(s):.2f} | "
              f"{100 * max(sc):.1f} / {100 * sum(sc) / len(sc):.1f} | {max(c):.4f} / {sum(c) / len(c):.4f} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
