"""Cost and safety against the episode length T (issue 38: the paper never states T).

    python scripts/episode_length_table.py 2=results/episode_2s 3=results/collision_readings 6=results/episode_6s

Each argument is ``T=RESULTS_DIR`` of a run of ``workflow/configs/collision_readings.yaml`` (with an
episode overlay ``workflow/configs/episode_{2,6}s.yaml`` for T ≠ 3 s); the cells' JSON summaries
of every study and run present in all of them are printed as one Markdown table: safety, cost ÷T
over collision-free agents (the paper's definition) and over all agents.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path


def cells(root: Path) -> dict[tuple[str, str, int, int], dict]:
    out = {}
    for f in sorted(root.glob("eval/*/*/*/n*_seed*.json")):
        d = json.loads(f.read_text())
        out[(d["study"], d["run"], int(d["n_agents"]), int(d["seed"]))] = d
    return out


def main(argv: list[str]) -> None:
    runs = {}
    for arg in argv:
        t, _, root = arg.partition("=")
        if not root:
            raise SystemExit(f"expected T=RESULTS_DIR, got '{arg}'")
        runs[float(t)] = cells(Path(root))
    common = sorted(set.intersection(*(set(c) for c in runs.values())))
    if not common:
        raise SystemExit("no cell is present in every results directory")
    ts = sorted(runs)
    head = ["study", "run", "N", "seed"] + [f"{m} (T = {t:g} s)" for m in ("safety", "cost ÷T", "cost ÷T all") for t in ts]
    print("| " + " | ".join(head) + " |")
    print("|" + "---|" * len(head))
    for key in common:
        row = list(map(str, key))
        row += [f"{100 * runs[t][key]['safety_rate']:.1f}%" for t in ts]
        row += [f"{runs[t][key]['cost_time_avg']:.3f}" for t in ts]
        row += [f"{runs[t][key]['cost_all_time_avg']:.3f}" for t in ts]
        print("| " + " | ".join(row) + " |")


if __name__ == "__main__":
    main(sys.argv[1:])
