"""V_s neighbour scoring: bounded (new, :func:`pair_scores_bounded`) vs exhaustive in-domain scoring.

On global states recorded at neighbour updates of real MAD-PINN episodes (double integrator,
shipped models, validation seed ≥ 100; :mod:`benchmarks.record_states`, run here if ``--states``
does not exist): 256 agents in the large arena and 16 in the small arena. Both methods run side by
side in one process, interleaved, torch one thread, best of ``--repeats``:

- ``exhaustive``: today's deployment before issue 37 — V_s on every in-domain pair
  (:func:`pair_scores`), then the n = 2 lowest (``torch.topk``);
- ``bounded``: V_s only on pairs the bounds cannot exclude, the n lowest by (score, index).

Selections are compared agent by agent against the exhaustive scores selected by (score, index)
(the reference), and against today's ``topk`` selection. The margin calibration (once per model,
≈ 1 s) is timed separately, not in the per-update time.

    PYTHONPATH=$PWD python benchmarks/bench_neighbours.py --states /tmp/states.pt [--band]

``--band``: both methods score with V_s clamped into its exact band (``methods.madpinn.vs_band``, the
protocol since 2026-11-26); the calibrated margin then shrinks to its pad.

Last lines: ``neighbour_scoring_speedup_at_256: X`` and ``identical_selection_share: Y``.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import time
from pathlib import Path

import torch

from madpinn.policies.neighbours import calibrate_drift_margins, pair_scores, pair_scores_bounded, select_lowest
from madpinn.value_functions import load_vs

N_NEIGHBOURS = 2


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--vs", default="models/vs.pt")
    ap.add_argument("--vhat", default="models/vhat.pt", help="only to record states")
    ap.add_argument("--states", default="/tmp/madpinn_recorded_states.pt")
    ap.add_argument("--batch", type=int, default=4, help="recorded 256-agent states scored together (a scenario batch)")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--band", action="store_true", help="score with V_s clamped into its exact band (the protocol's vs_band)")
    args = ap.parse_args()
    torch.set_num_threads(1)
    if not Path(args.states).is_file():
        here = Path(__file__).resolve().parent
        subprocess.run([sys.executable, str(here / "record_states.py"), "--vhat", args.vhat, "--vs", args.vs,
                        "--out", args.states], check=True)
    data = torch.load(args.states, weights_only=True)
    vs = load_vs(args.vs, band=args.band)
    t = time.perf_counter()
    margins = calibrate_drift_margins(vs)
    calib = time.perf_counter() - t
    print(f"states {args.states} ({data['meta']}); margin calibration {calib:.2f} s; "
          f"margins (m) {[round(m, 3) for m in margins.margins]}", flush=True)
    share = {}
    speed = {}
    with torch.no_grad():
        for name in ("large", "small"):
            states = data[name]
            B = args.batch if name == "large" else 8 * args.batch
            batches = [states[a : a + B] for a in range(0, states.shape[0], B)]
            same_ref = same_topk = agents = 0
            counts: dict = {}
            for s in batches:
                ref_scores = pair_scores(s, vs)
                ref = select_lowest(ref_scores, N_NEIGHBOURS, exact_ties=True)
                today = select_lowest(ref_scores, N_NEIGHBOURS)
                new = select_lowest(pair_scores_bounded(s, vs, N_NEIGHBOURS, margins, counts=counts), N_NEIGHBOURS,
                                    exact_ties=True)
                same_ref += int((new == ref).all(-1).sum())
                same_topk += int((new == today).all(-1).sum())
                agents += s.shape[0] * s.shape[1]
            best = {"exhaustive": float("inf"), "bounded": float("inf")}
            for _ in range(args.repeats):
                for method in ("exhaustive", "bounded"):
                    t = time.process_time()
                    for s in batches:
                        if method == "exhaustive":
                            select_lowest(pair_scores(s, vs), N_NEIGHBOURS)
                        else:
                            select_lowest(pair_scores_bounded(s, vs, N_NEIGHBOURS, margins), N_NEIGHBOURS, exact_ties=True)
                    best[method] = min(best[method], time.process_time() - t)
            n_agents = states.shape[1]
            per = {m: 1e6 * v / agents for m, v in best.items()}
            speed[name] = best["exhaustive"] / best["bounded"]
            share[name] = same_ref / agents
            print(f"{name}: {states.shape[0]} states x {n_agents} agents, {len(batches)} updates of {B} scenarios; "
                  f"in-domain partners/agent {counts['in_domain'] / agents:.1f}, evaluated {counts['evaluated'] / agents:.1f} "
                  f"({counts['evaluated'] / counts['in_domain']:.3f}); us/agent-update exhaustive {per['exhaustive']:.1f} "
                  f"bounded {per['bounded']:.1f}, speedup {speed[name]:.2f}; identical selections {same_ref}/{agents} "
                  f"(vs today's topk order: {same_topk}/{agents})", flush=True)
    print(f"neighbour_scoring_speedup_at_256: {speed['large']:.2f}")
    print(f"identical_selection_share: {min(share.values()):.6f}")


if __name__ == "__main__":
    main()
