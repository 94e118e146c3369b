"""Table II's final readings on protocol seed 0 (issue 60), by the pre-registered rule of
docs/findings/2026-12-01-table-ii-final-readings-plan.md: from the validation readings page's verdict,
the overlay that runs every kept reading once on seed 0 and judges them beside the protocol's own row.

    python scripts/final_readings_overlay.py paper_figures/table_ii_readings/verdict.json \
        workflow/configs/scenario_laws.yaml > workflow/configs/table_ii_final.yaml

Kept (the plan's words): the protocol's reading (the protocol's `scaling` study and its `madpinn` row:
no cells of its own), every reading that reproduces Table II, and the closest reading. Each kept
reading other than the protocol's runs in its own validation study, redefined by the overlay (the schema
names every study) with seed 0, 20 scenarios and the kept runs only: its law (`pattern`), the large arena
at 64 / 128 / 256 agents, T = 6 s, in its own results directory (results/table_ii_final/); the
overlay's `table_ii_readings` section judges them and the protocol's row against Table II with Table I's
16-agent `main` cells of seed 0 as the anchor, and the baselines in the large arena (`baselines_large`)
run on seed 0 too (issue 60 item 4). Readings at another horizon than the episode's are
refused (the plan fixes T = 6 s), as is a verdict without a protocol reading.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import yaml

PROTOCOL_STUDY, PROTOCOL_RUN = "scaling", "madpinn"
BASELINES = "baselines_large"
AGENT_COUNTS, SEEDS, SCENARIOS, EPISODE_S = [64, 128, 256], [0], 20, 6.0


def kept_readings(verdict: dict) -> list[dict]:
    """The plan's kept readings besides the protocol's: the reproducing ones and the closest, once each."""
    if "protocol" not in verdict:
        raise SystemExit("the verdict has no protocol reading (was it written by `madpinn table-ii-readings`?)")
    key = lambda r: (r["study"], r["run"], float(r["horizon_s"]))   # noqa: E731
    out = {}
    for r in [*verdict.get("reproducing", []), *([verdict["closest"]] if verdict.get("closest") else [])]:
        if key(r) != key(verdict["protocol"]):
            out.setdefault(key(r), r)
    for r in out.values():
        if float(r["horizon_s"]) != EPISODE_S:
            raise SystemExit(f"kept reading {r['study']} · {r['run']} is read at T = {r['horizon_s']:g} s; the plan fixes "
                             f"T = {EPISODE_S:g} s: write its study by hand")
    return list(out.values())


def overlay(verdict: dict, laws: dict, chosen_on: str | None = None) -> dict:
    """The overlay of the kept readings (``laws``: the validation overlay that defined their studies;
    ``chosen_on``: the verdict's file, relative to the repository, which the final page summarises)."""
    studies = {}
    for r in kept_readings(verdict):
        if r["study"] not in laws.get("studies", {}):
            raise SystemExit(f"kept reading {r['study']} · {r['run']}: {r['study']} is not a study of the validation overlay given")
        source = laws["studies"][r["study"]]
        if source.get("arena") != "large":
            raise SystemExit(f"kept reading {r['study']} is not a large-arena study")
        study = studies.setdefault(r["study"], {"arena": "large", **({"pattern": source["pattern"]} if source.get("pattern") else {}),
                                                "agent_counts": AGENT_COUNTS, "seeds": SEEDS, "scenarios": SCENARIOS,
                                                "in_all": False, "runs": []})
        study["runs"].append(r["run"])
    return {"experiment": "madpinn-table-ii-final",
            # the validation overlay's own run variants (e.g. sensall), which a kept reading may name
            **({"methods": laws["methods"]} if laws.get("methods") else {}),
            "paths": {"results": "results/table_ii_final", "figures": "results/table_ii_final/paper_figures"},
            "table_ii_readings": {"studies": [PROTOCOL_STUDY, *studies], "baselines": [BASELINES],
                                  "anchor": {"study": "main", "n_agents": 16},
                                  "protocol": {"study": PROTOCOL_STUDY, "run": PROTOCOL_RUN},
                                  **({"chosen_on": chosen_on} if chosen_on else {})},
            # the protocol's reading and Table I's anchor: the paper's deployment alone, seed 0 (cells of the rerun;
            # main keeps 8 agents for figures.trajectories, the anchor reads its 16)
            "studies": {PROTOCOL_STUDY: {"runs": [PROTOCOL_RUN]}, "main": {"agent_counts": [8, 16], "seeds": SEEDS, "runs": [PROTOCOL_RUN]},
                        # issue 60 item 4: the baselines in the large arena, "on the validation seeds and then seed 0"
                        BASELINES: {**{k: v for k, v in laws["studies"][BASELINES].items() if k not in ("seeds", "scenarios")},
                                    "seeds": SEEDS, "scenarios": SCENARIOS},
                        **studies}}


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if len(argv) != 2:
        raise SystemExit(__doc__.split("\n\n")[1])
    verdict = json.loads(Path(argv[0]).read_text())
    laws = yaml.safe_load(Path(argv[1]).read_text())
    text = yaml.safe_dump(overlay(verdict, laws, chosen_on=argv[0]), sort_keys=False)
    sys.stdout.write(f"# Generated by scripts/final_readings_overlay.py from {argv[0]} and {argv[1]}\n"
                     "# (docs/findings/2026-12-01-table-ii-final-readings-plan.md); protocol seed 0, run with the protocol rerun.\n" + text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
