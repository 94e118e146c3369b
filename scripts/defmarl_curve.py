"""Summarise a DEF-MARL learning-curve CSV (``<out>_history.csv`` of ``train-defmarl``): training
statistics per block of iterations and every validation row, with the plateau verdict of
``madpinn.marl.validation.plateau`` on the training-count safety.

    PYTHONPATH=$PWD python scripts/defmarl_curve.py training/defmarl_n8/defmarl_n8_history.csv --block 50 --window 4
"""

from __future__ import annotations

import argparse

import pandas as pd

from madpinn.marl.validation import plateau


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("csv")
    ap.add_argument("--block", type=int, default=50, help="iterations per block of training statistics")
    ap.add_argument("--window", type=int, default=4)
    ap.add_argument("--min-gain", type=float, default=1.0)
    args = ap.parse_args()
    h = pd.read_csv(args.csv)
    print(f"{len(h)} iterations, {int(h.iteration.min()) + 1} … {int(h.iteration.max()) + 1} (1-based, after the step)")
    for a in range(0, len(h), args.block):
        b = h.iloc[a : a + args.block]
        print(f"  {int(b.iteration.iloc[0]) + 1:>5}–{int(b.iteration.iloc[-1]) + 1:<5} violations {100 * b.violation_rate.mean():.2f} % "
              f"collided agents {100 * b.collision_rate.mean():.1f} % team cost {b.team_cost.mean():+.3f}")
    cols = [c for c in h.columns if c.startswith("val_safety_n")]
    if not cols:
        return
    v = h[h[cols[0]].notna()]
    for _, r in v.iterrows():
        rest = " ".join(f"{c[4:]} {r[c]:.4g}" for c in v.columns if c.startswith("val_") and c not in ("val_plateau",))
        print(f"  after {int(r.iteration) + 1}: {rest}")
    print(f"plateau ({cols[0]}, window {args.window}, min gain {args.min_gain}): "
          f"{plateau(v[cols[0]].tolist(), args.window, args.min_gain)}")


if __name__ == "__main__":
    main()
