"""Where the time of a workflow run went, job by job, from its MLflow runs.

    python benchmarks/protocol_time.py [--store results/tracking/store.json] [--cores 2] [--since ISO-TIME]
    python benchmarks/protocol_time.py --cells output_cache [--cores 2]

Every workflow job is one MLflow run that opens when the job starts and closes when it ends
(README, "Browse runs in MLflow"), so a run's duration is the job's wall time. This reads the
store and experiment the workflow recorded in ``store.json`` (``results/tracking/store.json`` for
``config.yaml``), keeps the ``FINISHED`` runs made by the workflow (tag ``madpinn.source =
workflow``; ``--since``: started at or after that UTC time) and prints, per rule: jobs, summed job
time (h) and the longest job (min); then the total, and the makespan of a longest-first schedule
of the same jobs on ``--cores`` one-thread workers. That makespan ignores dependencies (trainings
must precede the cells that use them) and the machine's other load, so it is a lower bound on the
wall time these jobs need on that many cores, not a measured wall time. Job times measured while
other work shared the cores are inflated accordingly. The last line is JSON.

``--cells DIR`` reads the evaluation cells' summaries instead (``*_summary.json`` of the output
cache, or the ``n*_seed*.json`` files under ``results/eval``): each cell's process CPU time
``cpu_s`` (cells computed since issue 65; older ones: their wall time ``elapsed_s``), measured
inside the job on the machine that computed it, without the job's start-up (≈ 5 s). The protocol's
cells may come from several machines' runs (profiles/shipped keeps them in ``output_cache/``); this
totals them all, per study and run.
"""

from __future__ import annotations

import argparse
import heapq
import json
from collections import defaultdict
from datetime import datetime, timezone
from pathlib import Path


def longest_first_makespan(durations: list[float], cores: int) -> float:
    """Makespan (same unit as ``durations``) of greedy longest-first list scheduling on ``cores``."""
    load = [0.0] * max(1, cores)
    for d in sorted(durations, reverse=True):
        heapq.heapreplace(load, load[0] + d)
    return max(load)


def workflow_jobs(store: Path, since_ms: int = 0) -> list[dict]:
    """``[{rule, job, seconds, start_ms}]`` of the finished workflow runs of the recorded experiment."""
    from mlflow.tracking import MlflowClient

    rec = json.loads(store.read_text())
    client = MlflowClient(tracking_uri=rec["uri"])
    query = "tags.`madpinn.source` = 'workflow' and attributes.status = 'FINISHED'"
    jobs, token = [], None
    while True:
        page = client.search_runs([rec["experiment_id"]], query, max_results=1000, page_token=token)
        for r in page:
            if r.info.end_time and r.info.start_time >= since_ms:
                jobs.append({"rule": r.data.tags.get("madpinn.rule", "?"), "job": r.data.tags.get("madpinn.job", "?"),
                             "seconds": (r.info.end_time - r.info.start_time) / 1000.0, "start_ms": r.info.start_time})
        token = page.token
        if not token:
            return jobs


def cell_summaries(directory: Path) -> list[dict]:
    """The evaluation cells' summaries under ``directory`` (``*_summary.json`` of the output cache,
    or ``n*_seed*.json`` under ``results/eval``) that record ``elapsed_s``; an unreadable one stops
    the script with its path."""
    cells = []
    for f in sorted([*directory.rglob("*_summary.json"), *directory.rglob("n*_seed*.json")]):
        try:
            s = json.loads(f.read_text())
        except (OSError, json.JSONDecodeError) as exc:
            raise SystemExit(f"unreadable cell summary {f}: {exc}") from exc
        if isinstance(s, dict) and "elapsed_s" in s:
            cells.append(s)
    return cells


def cell_seconds(summary: dict) -> float:
    """A cell's job time (s): its process CPU time ``cpu_s`` where recorded (cells since issue 65;
    a loaded machine inflates it far less than wall time), else its wall time ``elapsed_s``."""
    return float(summary.get("cpu_s", summary["elapsed_s"]))


def cell_jobs(directory: Path) -> list[dict]:
    """``[{rule, job, seconds}]`` of the evaluation cells summarised under ``directory``."""
    return [{"rule": f"evaluate {s['study']}/{s['run']}", "seconds": cell_seconds(s),
             "job": f"evaluate/{s['backend']}/{s['study']}/{s['run']}/n{s['n_agents']}_seed{s['seed']}"}
            for s in cell_summaries(directory)]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--store", type=Path, default=Path("results/tracking/store.json"))
    ap.add_argument("--cores", type=int, default=2)
    ap.add_argument("--since", default=None, help="only runs started at or after this UTC time (ISO 8601)")
    ap.add_argument("--cells", type=Path, default=None, help="evaluation cells' summaries under this directory instead of MLflow")
    args = ap.parse_args()
    since_ms = 0
    if args.since:
        since_ms = int(datetime.fromisoformat(args.since).replace(tzinfo=timezone.utc).timestamp() * 1000)
    jobs = cell_jobs(args.cells) if args.cells else workflow_jobs(args.store, since_ms)
    if not jobs:
        raise SystemExit(f"no finished jobs in {args.cells or args.store}")
    by_rule = defaultdict(list)
    for j in jobs:
        by_rule[j["rule"]].append(j["seconds"])
    print(f"{'rule':<28}{'jobs':>6}{'job time (h)':>14}{'longest (min)':>15}")
    for rule, d in sorted(by_rule.items(), key=lambda kv: -sum(kv[1])):
        print(f"{rule:<28}{len(d):>6}{sum(d) / 3600:>14.2f}{max(d) / 60:>15.1f}")
    total = sum(j["seconds"] for j in jobs)
    makespan = longest_first_makespan([j["seconds"] for j in jobs], args.cores)
    print(f"{'total':<28}{len(jobs):>6}{total / 3600:>14.2f}")
    print(f"longest-first makespan on {args.cores} cores (no dependencies, lower bound): {makespan / 3600:.2f} h")
    print(json.dumps({"jobs": len(jobs), "job_time_h": round(total / 3600, 3), "cores": args.cores,
                      "makespan_lower_bound_h": round(makespan / 3600, 3),
                      "by_rule_h": {r: round(sum(d) / 3600, 3) for r, d in by_rule.items()},
                      "longest_job_min": round(max(j["seconds"] for j in jobs) / 60, 1)}))


if __name__ == "__main__":
    main()
