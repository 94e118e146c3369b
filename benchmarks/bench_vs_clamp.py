"""Measure (not adopted): clamping the learned V_s into [free-drift bound, ψ] against the grid reference.

The exact pairwise value satisfies ``free-drift bound ≤ V_s ≤ ψ``: doing nothing is one admissible
relative control (so ``V_s(x, t) ≥ min_{τ∈[0, T−t]} ‖p + v·τ‖ − r``), and the min over the horizon
includes τ = t (``V_s ≤ ψ = ‖p‖ − r``). Clamping the network into that band can only move it
towards the exact value. This script solves the grid reference of ``validate_vs_grid``
(:mod:`madpinn.value_functions.grid_reference`, WENO5 + TVD-RK3, ``|p| ≤ 1``, ``|v| ≤ 6``) at
``--nodes`` per axis, evaluates the shipped V_s on its interior nodes (``|p| ≤ 0.6``, ``|v| ≤ 3``)
at t = 0, 0.25, 0.5, 0.75 s, and prints the metrics of ``compare_values`` for the raw and the
clamped network.

    PYTHONPATH=$PWD python benchmarks/bench_vs_clamp.py --nodes 17
"""

from __future__ import annotations

import argparse

import numpy as np
import torch

from madpinn.config import REPO_ROOT, load_config
from madpinn.policies.neighbours import free_drift_lower_bound
from madpinn.value_functions import load_vs
from madpinn.value_functions.grid_reference import GridSettings, compare_values, solve_pair_grid, vs_on_grid


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--vs", default="models/vs.pt")
    ap.add_argument("--nodes", type=int, default=17)
    args = ap.parse_args()
    torch.set_num_threads(1)
    vs = load_vs(args.vs)
    grid = load_config([REPO_ROOT / "config.yaml"])["value_functions"]["vs"]["validation"]["grid"]
    gs = GridSettings.from_config({**grid, "nodes": args.nodes})
    sol = solve_pair_grid(vs.system, args.nodes, gs.p_range, gs.v_range, gs.times, gs.accuracy)
    mask = sol.interior_mask(gs.interior_p, gs.interior_v)
    x = torch.as_tensor(sol.states()[mask], dtype=torch.float64)
    pred = vs_on_grid(vs, sol, mask)
    psi = (x[:, 0:2].norm(dim=-1) - vs.collision_radius).numpy()
    print(f"grid {args.nodes}^4 ({sol.wall_s:.0f} s), {int(mask.sum())} interior nodes, V_s {args.vs}")
    for i, t in enumerate(sol.times):
        lower = free_drift_lower_bound(x, vs.horizon - float(t), vs.collision_radius, vs.system.agent).numpy()
        clamped = np.clip(pred[i], lower, psi)
        ref = sol.values[i][mask]
        for name, p in (("raw", pred[i]), ("clamped", clamped)):
            m = compare_values(ref, p)
            print(f"t={t:g} {name:8s}: MAE {m['mae']:.4f} m, max {m['max_error']:.4f}, p99 {m['p99_error']:.4f}, "
                  f"unsafe called safe {m['unsafe_called_safe']:.4f}, safe called unsafe {m['safe_called_unsafe']:.4f}, "
                  f"sign agreement {m['sign_agreement']:.4f}", flush=True)
        print(f"      below the band {np.mean(pred[i] < lower):.3f} of nodes, above {np.mean(pred[i] > psi):.3f}; "
              f"grid reference outside the band (discretisation): below {np.mean(ref < lower - 1e-3):.4f}, "
              f"above {np.mean(ref > psi + 1e-3):.4f}", flush=True)


if __name__ == "__main__":
    main()
