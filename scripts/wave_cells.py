"""Summaries of hand-run validation cells (issues 46/47): one Markdown row per cell JSON under the
given folders — safety, safe scenarios, time-averaged cost, infeasible share, 90th-percentile speed
where stored, wall time — and the paired per-scenario safety difference against a reference cell
of the same N and seed: the ``--ref-tag`` folder's cell of the same run, else of ``--ref-run``.

    python scripts/wave_cells.py validation_cells [--ref-tag base] [--ref-run madpinn]
"""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path

import pandas as pd


def reference_of(rel: Path, cells: dict[Path, pd.DataFrame], ref_tag: str, ref_run: str) -> pd.DataFrame | None:
    """The reference cell of a cell ``<tag>/<study>/<run>/<file>``: the ``ref_tag`` cell of the same
    run and file (same N and seed) in any study, else that of ``ref_run``; None for the reference itself."""
    tag, _, run, name = rel.parts[-4:]
    if tag == ref_tag:
        return None
    for want in (run, ref_run):
        for other, frame in cells.items():
            if other.parts[-4] == ref_tag and other.parts[-2] == want and other.parts[-1] == name:
                return frame
    return None


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("root", help="folder of <tag>/<study>/<run>/n<N>_seed<S>.{json,parquet} cells")
    ap.add_argument("--ref-tag", default="base", help="tag folder holding the reference cells")
    ap.add_argument("--ref-run", default="madpinn", help="reference run where the cell's own run has no reference cell")
    args = ap.parse_args()
    root = Path(args.root)
    rows, cells = [], {}
    for js in sorted(root.rglob("*_seed*.json")):
        rel = js.relative_to(root).with_suffix("")
        cells[rel] = pd.read_parquet(js.with_suffix(".parquet")).sort_values("scenario").reset_index(drop=True)
        rows.append((rel, json.loads(js.read_text())))
    print("| cell | safety % | safe sc. % | cost ÷ T | infeasible | wall s | Δ safety vs ref (pp, ± s.e.) |")
    print("|---|---|---|---|---|---|---|")
    for rel, d in rows:
        frame, ref = cells[rel], reference_of(rel, cells, args.ref_tag, args.ref_run)
        diff = ""
        if ref is not None and len(ref) == len(frame) and (ref["scenario"].to_numpy() == frame["scenario"].to_numpy()).all():
            dd = 100 * (frame["safety_rate"].to_numpy() - ref["safety_rate"].to_numpy())
            se = dd.std(ddof=1) / math.sqrt(len(dd)) if len(dd) > 1 else float("nan")
            diff = f"{dd.mean():+.1f} ± {se:.1f}"
        ps = d.get("policy_stats", {})
        print(f"| {rel} | {100 * d['safety_rate']:.1f} | {100 * d['safe_scenarios']:.0f} | "
              f"{d['cost_time_avg']:.3f} | {ps.get('infeasible_fraction', float('nan')):.3f} | {d['elapsed_s']:.0f} | {diff} |")


if __name__ == "__main__":
    main()
