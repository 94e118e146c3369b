"""Recompute committed evaluation cells on this machine and compare them with their entries in
``output_cache/`` (issue 66 item 2: how reproducible is a cell across machines).

    python scripts/cell_recompute.py --cells main/nominal/n3_seed0 main/mppi/n3_seed0 ... [--jobs 2]

Run from the root of a clone, as the README's shipped run: the named cells are recomputed by the
workflow with the shipped models (``--configfile workflow/configs/shipped.yaml``, no output cache,
``--forcerun evaluate``: the cells land in ``results/eval/`` as files; committed files are not
touched). Each is compared with the committed entry of the same cell and job config
(``job_config_hash`` of its summary). Prints a Markdown table: per cell whether the per-scenario
frame and the summary's figures are equal bit for bit, how many scenarios differ, and for each
figure the change against the cell's own 95 % interval half-width (1.96 × the scenarios' standard
deviation / √scenarios, from the committed frame): 0 = bit-equal, 1 = a change as large as the
interval. ``--compare-only`` compares cells already in ``results/eval/`` (from an earlier call).
"""

from __future__ import annotations

import argparse
import json
import math
import subprocess
import sys
import time
from pathlib import Path

import pandas as pd

FIGURES = {   # summary figure -> the per-scenario column it is the mean of
    "safety_rate": "safety_rate",
    "safe_scenarios": "safe",
    "cost_all_time_avg": "cost_all_time_avg",
}


def committed_entries(cache: Path) -> dict[tuple, list[Path]]:
    """(backend, study, run, n, seed, job_config_hash) -> the committed summaries of that cell."""
    out: dict[tuple, list[Path]] = {}
    for f in cache.glob("*_summary.json"):
        s = json.loads(f.read_text())
        key = (s["backend"], s["study"], s["run"], int(s["n_agents"]), int(s["seed"]), s.get("job_config_hash"))
        out.setdefault(key, []).append(f)
    return out


def half_width(frame: pd.DataFrame, column: str) -> float:
    x = frame[column].astype(float)
    return 1.96 * float(x.std(ddof=1)) / math.sqrt(len(x)) if len(x) > 1 else float("nan")


def compare(parquet: Path, entries: dict[tuple, list[Path]]) -> dict:
    """The recomputed cell ``parquet`` against the closest committed entry of the same cell."""
    s = json.loads(parquet.with_suffix(".json").read_text())
    key = (s["backend"], s["study"], s["run"], int(s["n_agents"]), int(s["seed"]), s.get("job_config_hash"))
    candidates = entries.get(key, [])
    if not candidates:
        return {"cell": str(parquet), "committed": None}
    now = pd.read_parquet(parquet)
    rows = []
    for summary in candidates:
        old_s = json.loads(summary.read_text())
        old = pd.read_parquet(summary.with_name(summary.name.replace("_summary.json", "_parquet.parquet")))
        numeric = [c for c in old.columns if pd.api.types.is_numeric_dtype(old[c]) and c in now.columns]
        differ = int((~(old[numeric].eq(now[numeric]) | (old[numeric].isna() & now[numeric].isna()))).any(axis=1).sum())
        frame_equal = old.equals(now)
        rel = {f: abs(float(s[f]) - float(old_s[f])) / hw if (hw := half_width(old, col)) > 0 else
               (0.0 if s[f] == old_s[f] else math.inf) for f, col in FIGURES.items()}
        rows.append({"cell": f"{s['study']}/{s['run']}/n{s['n_agents']}_seed{s['seed']}", "committed": summary.name[:12],
                     "frame_equal": frame_equal, "figures_equal": all(s[f] == old_s[f] for f in FIGURES),
                     "scenarios": len(now), "scenarios_differing": differ,
                     "delta": {f: float(s[f]) - float(old_s[f]) for f in FIGURES}, "delta_over_half_width": rel,
                     "elapsed_s": s.get("elapsed_s"), "committed_elapsed_s": old_s.get("elapsed_s")})
    return min(rows, key=lambda r: (not r["frame_equal"], max(r["delta_over_half_width"].values())))


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--cells", nargs="+", required=True, help="STUDY/RUN/nN_seedS, e.g. main/nominal/n3_seed0")
    ap.add_argument("--backend", default="mujoco")
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--cache", default="output_cache")
    ap.add_argument("--out", default="results/cell_recompute.json")
    ap.add_argument("--compare-only", action="store_true")
    args = ap.parse_args()
    targets = [f"results/eval/{args.backend}/{c}.parquet" for c in args.cells]
    if not args.compare_only:
        t0 = time.monotonic()
        cmd = [sys.executable, "-m", "snakemake", f"-j{args.jobs}", *targets, "--configfile",
               "workflow/configs/shipped.yaml", "--forcerun", "evaluate"]
        subprocess.run(cmd, check=True)
        print(f"recomputed {len(targets)} cells in {time.monotonic() - t0:.0f} s wall", file=sys.stderr)
    entries = committed_entries(Path(args.cache))
    rows = [compare(Path(t), entries) for t in targets]
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    Path(args.out).write_text(json.dumps(rows, indent=2))
    print("| cell | committed entry | frame bit-equal | figures bit-equal | scenarios differing | "
          + " | ".join(f"Δ {f} / half-width" for f in FIGURES) + " | elapsed s (committed) |")
    print("|---|---|---|---|---|" + "---|" * len(FIGURES) + "---|")
    for r in rows:
        if r["committed"] is None:
            print(f"| {r['cell']} | none with this job config | | | |" + " |" * len(FIGURES) + " |")
            continue
        print(f"| {r['cell']} | {r['committed']}… | {'yes' if r['frame_equal'] else 'no'} | "
              f"{'yes' if r['figures_equal'] else 'no'} | {r['scenarios_differing']} of {r['scenarios']} | "
              + " | ".join(f"{r['delta_over_half_width'][f]:.3g} ({r['delta'][f]:+.2g})" for f in FIGURES)
              + f" | {r['elapsed_s']:.0f} ({r['committed_elapsed_s']:.0f}) |")
    equal = sum(bool(r.get("frame_equal")) for r in rows)
    print(f"\n{equal} of {len(rows)} cells bit-equal to their committed entry")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
