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

    python scripts/cell_recompute.py --results /tmp/rc --at f921a9ab --cells conflict_lines/mppi/n16_seed0

``--results DIR`` (absolute) recomputes into ``DIR/eval/`` instead (``paths.results``), with the
code as committed at HEAD (a temporary git worktree): the protocol's own ``results/`` stays as it
is, and a run in this checkout may go on beside it. ``--at COMMIT`` also
recomputes the same cells with the code and config at COMMIT (a temporary git worktree, its cells in
``DIR/at-<commit>/``) and compares the two recomputations bit for bit: whether a code change moved
a cell, on one machine, apart from what the machine moves (issue 63 item 1).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import re
import subprocess
import sys
import tempfile
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
    candidates = [(f.name[:12], f, f.with_name(f.name.replace("_summary.json", "_parquet.parquet")))
                  for f in entries.get(key, [])]
    return compare_with(parquet, candidates)


def compare_with(parquet: Path, candidates: list[tuple[str, Path, Path]]) -> dict:
    """The cell ``parquet`` (its summary beside it) against the closest of ``candidates``
    (label, summary, frame): bit-equal frames first, then the smallest change of a figure."""
    s = json.loads(parquet.with_suffix(".json").read_text())
    if not candidates:
        return {"cell": str(parquet), "committed": None}
    now = pd.read_parquet(parquet)
    rows = []
    for label, summary, frame in candidates:
        old_s = json.loads(summary.read_text())
        old = pd.read_parquet(frame)
        numeric = [c for c in old.columns if pd.api.types.is_numeric_dtype(old[c]) and c in now.columns]
        differ = int((~(old[numeric].eq(now[numeric]) | (old[numeric].isna() & now[numeric].isna()))).any(axis=1).sum())
        frame_equal = old.equals(now)
        shared = [c for c in old.columns if c in now.columns]
        shared_equal = old[shared].reset_index(drop=True).equals(now[shared].reset_index(drop=True))
        rel = {f: abs(float(s[f]) - float(old_s[f])) / hw if (hw := half_width(old, col)) > 0 else
               (0.0 if s[f] == old_s[f] else math.inf) for f, col in FIGURES.items()}
        rows.append({"cell": f"{s['study']}/{s['run']}/n{s['n_agents']}_seed{s['seed']}", "committed": label,
                     "frame_equal": frame_equal,
                     "shared_columns_equal": shared_equal, "columns_added": sorted(set(now.columns) - set(old.columns)),
                     "columns_removed": sorted(set(old.columns) - set(now.columns)), "figures_equal": all(s[f] == old_s[f] for f in FIGURES),
                     "scenarios": len(now), "scenarios_differing": differ,
                     "delta": {f: float(s[f]) - float(old_s[f]) for f in FIGURES}, "delta_over_half_width": rel,
                     "elapsed_s": s.get("elapsed_s"), "committed_elapsed_s": old_s.get("elapsed_s")})
    return min(rows, key=lambda r: (not r["frame_equal"], max(r["delta_over_half_width"].values())))


def recompute(root: Path, results: Path, targets: list[Path], jobs: int) -> None:
    """Recompute ``targets`` with the workflow of the tree at ``root`` (its code on PYTHONPATH),
    the shipped models, no output cache; cells under ``results`` (``paths.results``)."""
    t0 = time.monotonic()
    cmd = [sys.executable, "-m", "snakemake", f"-j{jobs}", *map(str, targets), "--configfile",
           "workflow/configs/shipped.yaml", "--forcerun", "evaluate"]
    if results != Path("results"):
        cmd += ["--config", f"paths={{results: {results}}}"]
    env = os.environ | {"PYTHONPATH": os.pathsep.join(filter(None, [str(root), os.environ.get("PYTHONPATH")]))}
    subprocess.run(cmd, check=True, cwd=root, env=env)
    print(f"recomputed {len(targets)} cells at {root} in {time.monotonic() - t0:.0f} s wall", file=sys.stderr)


def frame_verdict(row: dict) -> str:
    """"yes"; "no"; or, for frames whose columns differ, whether the columns both have are equal."""
    if row["frame_equal"]:
        return "yes"
    if not (row["columns_added"] or row["columns_removed"]):
        return "no"
    changed = ", ".join([f"+{c}" for c in row["columns_added"]] + [f"−{c}" for c in row["columns_removed"]])
    return f"{'yes' if row['shared_columns_equal'] else 'no'} on the shared columns ({changed})"


def short(commit: str) -> str:
    return subprocess.run(["git", "rev-parse", "--short=8", commit], capture_output=True, text=True,
                          check=True).stdout.strip()


def recompute_at(commit: str, results: Path, targets: list[Path], jobs: int) -> None:
    """:func:`recompute` in a temporary git worktree of ``commit`` (the code as committed there):
    it holds its own workflow lock, so a run in this checkout may go on beside it."""
    with tempfile.TemporaryDirectory() as tmp:
        tree = Path(tmp) / "tree"
        subprocess.run(["git", "worktree", "add", "--detach", "-q", str(tree), commit], check=True)
        try:
            recompute(tree, results, targets, jobs)
        finally:
            subprocess.run(["git", "worktree", "remove", "--force", str(tree)], check=False)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--cells", nargs="+", required=True, help="STUDY/RUN/nN_seedS, e.g. main/nominal/n3_seed0")
    ap.add_argument("--backend", default="mujoco")
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--cache", default="output_cache")
    ap.add_argument("--out", default="results/cell_recompute.json")
    ap.add_argument("--compare-only", action="store_true")
    ap.add_argument("--results", type=Path, help="recompute into this absolute directory (paths.results), not results/")
    ap.add_argument("--at", metavar="COMMIT", help="also recompute with the code at COMMIT and compare the two bit for bit")
    args = ap.parse_args()
    bad = [c for c in args.cells if not re.fullmatch(r"[^/\s]+/[^/\s]+/n\d+_seed\d+", c)]
    if bad:
        ap.error(f"--cells: {', '.join(bad)}: not STUDY/RUN/nN_seedS (e.g. main/nominal/n3_seed0)")
    if args.results is not None and not args.results.is_absolute():
        ap.error(f"--results must be an absolute path (got {args.results})")
    if args.at and args.results is None:
        ap.error("--at needs --results (the two recomputations go under it)")
    if args.at and subprocess.run(["git", "cat-file", "-e", f"{args.at}^{{commit}}"], capture_output=True).returncode:
        ap.error(f"--at {args.at}: not a commit of this repository")
    results = args.results or Path("results")
    targets = [results / "eval" / args.backend / f"{c}.parquet" for c in args.cells]
    if not args.compare_only:
        if args.results is None:
            recompute(Path.cwd(), results, targets, args.jobs)
        else:
            recompute_at("HEAD", results, targets, args.jobs)
    entries = committed_entries(Path(args.cache))
    rows = [compare(t, entries) for t in targets]
    if args.at:
        sha = short(args.at)
        at_targets = [results / f"at-{sha}" / t.relative_to(results) for t in targets]
        if not args.compare_only:
            recompute_at(sha, results / f"at-{sha}", at_targets, args.jobs)
        head = f"HEAD ({short('HEAD')})"
        rows += [compare_with(t, [(head, h.with_suffix(".json"), h)]) | {"at": sha} for t, h in zip(at_targets, targets)]
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    Path(args.out).write_text(json.dumps(rows, indent=2, default=str))
    print("| cell | compared with | frame bit-equal | figures bit-equal | scenarios differing | "
          + " | ".join(f"Δ {f} / half-width" for f in FIGURES) + " | elapsed s (committed) |")
    print("|---|---|---|---|---|" + "---|" * len(FIGURES) + "---|")
    for r in rows:
        if r["committed"] is None:
            print(f"| {r['cell']} | none with this job config | | | |" + " |" * len(FIGURES) + " |")
            continue
        cell = f"{r['cell']} (code at {r['at']})" if "at" in r else r["cell"]
        print(f"| {cell} | {r['committed']}{'' if 'at' in r else '…'} | {frame_verdict(r)} | "
              f"{'yes' if r['figures_equal'] else 'no'} | {r['scenarios_differing']} of {r['scenarios']} | "
              + " | ".join(f"{r['delta_over_half_width'][f]:.3g} ({r['delta'][f]:+.2g})" for f in FIGURES)
              + f" | {r['elapsed_s']:.0f} ({r['committed_elapsed_s']:.0f}) |")
    equal = sum(bool(r.get("frame_equal")) for r in rows)
    shared = sum(bool(r.get("shared_columns_equal")) and not r.get("frame_equal") for r in rows)
    print(f"\n{equal} of {len(rows)} comparisons bit-equal; {shared} more bit-equal on the columns both frames have")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
