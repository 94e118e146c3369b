"""Summaries of hand-run validation cells (issues 46/47): one Markdown row per cell JSON under the
given folders — safety, safe scenarios, time-averaged cost, infeasible share, 90th-percentile speed
where stored, wall time — and the paired per-scenario safety difference against a reference cell
of the same study, N and seed (``--ref TAG``: the folder name whose cells are the reference).

    python scripts/wave_cells.py results/wave [--ref fairness]
"""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path

import pandas as pd


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("root")
    ap.add_argument("--ref-run", default="madpinn", help="reference run of the same study, N, seed and tag folder")
    args = ap.parse_args()
    rows = []
    for js in sorted(Path(args.root).rglob("*_seed*.json")):
        d = json.loads(js.read_text())
        frame = pd.read_parquet(js.with_suffix(".parquet")).sort_values("scenario").reset_index(drop=True)
        rows.append((js, d, frame))
    print("| cell | safety % | safe sc. % | cost ÷ T | infeasible | wall s | Δ safety vs ref (pp, ± s.e.) |")
    print("|---|---|---|---|---|---|---|")
    for js, d, frame in rows:
        rel = js.relative_to(args.root)
        ref = None
        for js2, d2, f2 in rows:
            if (js2.parent.parent == js.parent.parent and js2.parent.name == args.ref_run and js2.name == js.name
                    and js2 != js):
                ref = f2
        diff = ""
        if ref is not None and len(ref) == len(frame):
            dd = 100 * (frame["safety_rate"].to_numpy() - ref["safety_rate"].to_numpy())
            se = dd.std(ddof=1) / math.sqrt(len(dd)) if len(dd) > 1 else float("nan")
            diff = f"{dd.mean():+.1f} ± {se:.1f}"
        ps = d.get("policy_stats", {})
        print(f"| {rel.parent}/{rel.stem} | {100 * d['safety_rate']:.1f} | {100 * d['safe_scenarios']:.0f} | "
              f"{d['cost_time_avg']:.3f} | {ps.get('infeasible_fraction', float('nan')):.3f} | {d['elapsed_s']:.0f} | {diff} |")


if __name__ == "__main__":
    main()
