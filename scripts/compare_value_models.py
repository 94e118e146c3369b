"""Does a retraining reproduce a shipped value function? Two checkpoints of the same kind compared.

    python scripts/compare_value_models.py models/vhat.pt training/vhat_s0/vhat.pt [--samples 65536] [--seed 100]

Prints one Markdown table: whether the weights are bitwise equal, the largest and the RMS weight
difference (relative to the RMS weight), each model's recorded final training loss, and the value
difference V_B − V_A on ``samples`` states drawn uniformly from the problem's own domain at
uniformly drawn times (validation stream ``seed`` ≥ 100) and, for V̂, on as many near-collision
states (one pair reaching the disk of ``--conflict-radius`` within the horizon: verify-vhat's
conflict law; z as in the uniform law): mean |ΔV|, its 99th percentile and maximum, both models'
mean |V|, and the share of states on which the two disagree on the sign of V (which side of the
zero level — safe for V̂ under its budget — each model puts the state on).
Both files are read with ``weights_only=True``; they must hold the same problem and network.
"""

from __future__ import annotations

import argparse
import sys

import torch

from madpinn.value_functions.calibration import draw_states
from madpinn.value_functions.model import load_value_function, read_checkpoint


def compare(path_a: str, path_b: str, samples: int, seed: int, conflict_radius: float = 0.3) -> list[tuple[str, str]]:
    data_a, data_b = read_checkpoint(path_a), read_checkpoint(path_b)
    if data_a["kind"] != data_b["kind"] or data_a["problem"] != data_b["problem"]:
        raise SystemExit(f"{path_a} and {path_b} are different problems: not comparable")
    a, b = load_value_function(path_a, data_a["kind"]), load_value_function(path_b, data_b["kind"])
    wa, wb = data_a["state_dict"], data_b["state_dict"]
    if set(wa) != set(wb) or any(wa[k].shape != wb[k].shape for k in wa):
        raise SystemExit(f"{path_a} and {path_b} have different networks: not comparable")
    diffs = torch.cat([(wb[k].double() - wa[k].double()).flatten() for k in wa])
    scale = torch.cat([wa[k].double().flatten() for k in wa]).pow(2).mean().sqrt()
    bitwise = all(torch.equal(wa[k], wb[k]) for k in wa)
    loss = lambda data: data.get("meta", {}).get("final_loss")   # noqa: E731
    fmt = lambda x: "–" if x is None else f"{x:.4g}"   # noqa: E731
    rows = [("weights bitwise equal", "yes" if bitwise else "no"),
            ("max |Δw| / RMS w", f"{diffs.abs().max() / scale:.3g}"),
            ("RMS Δw / RMS w", f"{diffs.pow(2).mean().sqrt() / scale:.3g}"),
            ("final loss A / B", f"{fmt(loss(data_a))} / {fmt(loss(data_b))}")]
    gen = torch.Generator().manual_seed(seed)
    for name in ("uniform", "conflict") if conflict_radius and data_a["kind"] == "vhat" else ("uniform",):
        s = a.problem.sample_states(samples, gen, torch.float32)
        if name == "conflict":   # the observation of a near-collision course (verify-vhat's law), z as drawn
            s[:, :-1] = draw_states(a.problem.system, samples, True, conflict_radius, gen, torch.float32)
        t = torch.rand(samples, generator=gen) * a.horizon
        va, vb = a.state_value(s, t).double(), b.state_value(s, t).double()
        d = (vb - va).abs()
        rows += [(f"{name}: mean |ΔV| on {samples} states (seed {seed})", f"{d.mean():.4g}"),
                 (f"{name}: 99th percentile / max |ΔV|", f"{d.quantile(0.99):.4g} / {d.max():.4g}"),
                 (f"{name}: mean |V| A / B", f"{va.abs().mean():.4g} / {vb.abs().mean():.4g}"),
                 (f"{name}: sign of V differs", f"{100 * ((va <= 0) != (vb <= 0)).double().mean():.2f} % of states")]
    return rows


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("a")
    p.add_argument("b")
    p.add_argument("--samples", type=int, default=65536)
    p.add_argument("--seed", type=int, default=100)
    p.add_argument("--conflict-radius", type=float, default=0.3,
                   help="V̂: also compare on near-collision states reaching this disk (m; verify-vhat's law); 0: uniform only")
    args = p.parse_args(argv)
    if args.seed < 100:
        raise SystemExit("--seed: validation streams are 100 and up (0-4 are the protocol's)")
    rows = compare(args.a, args.b, args.samples, args.seed, args.conflict_radius)
    print(f"| {args.a} against {args.b} | |\n|---|---|")
    for k, v in rows:
        print(f"| {k} | {v} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
