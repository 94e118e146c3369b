"""The floor that the paper's z bisection puts under MAD-PINN's policy time on this CPU (issue 37).

    PYTHONPATH=$PWD python benchmarks/zsearch_floor.py --cells results/eval [--vhat models/vhat.pt] [--repeats 20]

Per agent-step, the deployed search (SPEC §6, :func:`madpinn.value_functions.z_search.cold_search`)
needs three kinds of V̂ network rows:

- one value row at ``z_max``, the feasibility test;
- ``steps = ⌈log2(1/z_tolerance)⌉`` halvings (10), each a value row. An infeasible agent's answer is
  ``z_max`` whatever its halvings return, so the search skips its halvings (since issue 48);
- one value-and-gradient row at ``z*``, for the control ``−u_max·sign(∂V̂/∂v_ego)``.

A search that returns the bisection's answer on every input cannot evaluate fewer rows. Its answer
is a function of V̂'s signs at the midpoints it visits, and where V̂ is not monotone in z no other
value determines them (the warm search, which evaluates others, returns another index on 7 % of
agent-steps with the shipped V̂, every time with a non-monotone V̂ in between; ``docs/reference/performance.md``).
A rigorous bound on the network's output, ``|N − b_out| ≤ ‖w_out‖₁`` (as ``|sin| ≤ 1``), could
certify a sign without a row only where the exact terminal term ``max(φ − z, g)`` outweighs
``(T − t)·σ·‖w_out‖₁`` = 4.3 (shipped V̂, z_max = 21.5). :func:`certifiable_rows` counts such rows
on the bisection's own path; ``bench_policy_cell.py`` prints the count on its episode's observations.

So the rows, times what one network row costs on this core, bound from below every implementation
that gives identical answers. The cost of a row is measured here: the SIREN forward (value) or
forward + analytic input gradient (gradient), at each cell's batch (agents × scenarios), one
thread, process CPU time, best of ``--repeats``. The exact boundary term and the input
normalisation are left out (the search computes their z-independent parts once per step since
issue 48); this makes the floor lower, so it stays a bound.

``--cells DIR`` reads the cells' summaries (:func:`protocol_time.cell_summaries`: ``n*_seed*.json``
under ``results/eval``, or ``*_summary.json`` in ``output_cache/``): agent-steps, share of
infeasible agent-steps, and the search
actually run (cells whose V̂ rows per agent-step are not the cold bisection's, i.e. warm starts, are
left out: :func:`ran_cold_bisection`). The floor is this CPU's: a cell whose summary names another
CPU (``cpu_model``, cells since issue 65's re-key) is left out of every sum and counted apart
(``--any-cpu`` keeps it); a cell that names none is kept and counted (``--named-only`` leaves it out:
``--cells output_cache`` in the middle of a rerun then reads the rerun's cells of this CPU alone). A cell's job time is its process CPU time where recorded
(:func:`protocol_time.cell_seconds`; the floor is process CPU time too), else its wall time.
For every MAD-PINN group it prints the cells, the measured job time (h), the floor (h)
and its share. The last lines are ``cold_bisection_cells_core_h`` (the measured time of those
MAD-PINN cells and its ratio to their floor), ``cold_bisection_floor_core_h: X`` (the floor summed
over the protocol's cells; studies named by ``--skip`` are left out), ``protocol_cells_core_h: Y``
(the measured time of the same protocol's cells, every method) and ``protocol_time_over_floor: Y/X``.

**The host's speed moves, so the floor is measured in rounds** (``--rounds K``, default 1): every
row cost the cells need is measured K times, round-robin over the batches, so the rounds spread
over the run. On this project's 2-vCPU cloud guest a row's best-of-20 moved from 3.3 to 5.6 µs
between consecutive two-second measurements (2026-12-06), the speed of minute-long host phases that
a cell's ``cpu_s``, summed over its whole run, averages over. Two floors are printed: the strict one
(each row cost the minimum over every round: the fastest moment seen; the lines above) and the
**typical-host** one (each row cost the median over rounds of their best-of-repeats: sub-second
noise removed, the host's typical speed kept), ``protocol_time_over_floor_typical_host``; their
gap is how much of the ratio is the host, not the code.

The extension rows with a CBVF filter after MAD-PINN's control (``madpinn-filtered``, not in the
paper) also evaluate V_s rows no identical-answer filter can skip: per agent-step a value row for
each of its ``candidates`` slots and a value-and-gradient row for each of its ``critical_neighbours``
(``methods.madpinn…safety_filter`` of ``--config``), at the V_s network's bare speed (``--vs``).
``network_floor_core_h`` adds them to the floor, and ``protocol_time_over_network_floor`` is the
protocol's time over that floor (MAD-PINN's own V_s neighbour scoring, whose row count varies with
the crowd, is in neither floor).
"""

from __future__ import annotations

import argparse
import math
import time
from collections import defaultdict
from statistics import median
from pathlib import Path

import torch

from madpinn.config import load_config, method_config
from madpinn.machine import cpu_model
from madpinn.value_functions import load_vhat, load_vs
from madpinn.value_functions.z_search import bisection_steps
from protocol_time import cell_seconds, cell_summaries   # benchmarks/protocol_time.py
from zsearch_reference import reference_cold_search   # benchmarks/zsearch_reference.py

DEFAULT_SKIP = ("large_arena_frontier",)   # validation-seed study, not part of the protocol's tables


def row_costs_us(vhat, batch: int, repeats: int = 20) -> tuple[float, float]:
    """``(value, gradient)`` process-CPU µs per network row of ``vhat`` at ``batch`` rows, one thread,
    best of ``repeats`` (each repeat averages enough calls to last ≈ 0.05 s). The minimum, because a
    shared machine's speed varies by up to 30 % from one second to the next: the floor must hold
    for the fastest moments of the runs it bounds."""
    g = torch.Generator().manual_seed(0)
    s = vhat.problem.sample_states(batch, g, torch.float32)
    x = vhat.problem.normalise(s, torch.zeros(batch))
    net = vhat.net

    def best(fn) -> float:
        fn()
        t0 = time.process_time()
        fn()
        calls = max(1, int(0.05 / max(1e-6, time.process_time() - t0)))
        out = math.inf
        for _ in range(repeats):
            t0 = time.process_time()
            for _ in range(calls):
                fn()
            out = min(out, (time.process_time() - t0) / calls)
        return 1e6 * out / batch

    with torch.no_grad():
        return best(lambda: net(x)), best(lambda: net.value_and_input_grad(x))


class _RecordedValues:
    """``vhat`` whose :meth:`value` calls are kept as ``(z, value)``, in call order."""

    def __init__(self, vhat):
        self.vhat, self.calls = vhat, []

    def value(self, obs, z, t=0.0):
        v = self.vhat.value(obs, z, t)
        self.calls.append((z, v))
        return v


def certifiable_rows(vhat, obs: torch.Tensor, grid) -> float:
    """Mean value rows per agent of the deployed cold bisection on ``obs [B, D]`` whose sign the
    output bound ``|N − b_out| ≤ ‖w_out‖₁`` certifies without evaluating the network: V̂(z_max),
    and the halvings of feasible agents, on the path the search takes (followed with
    :func:`reference_cold_search`, which evaluates every row at every halving, the same answers as
    :func:`cold_search`). Checks every certified sign against the network's value."""
    w, b = vhat.net.out.weight, vhat.net.out.bias
    scale = vhat.horizon * vhat.output_scale            # (T − t)·σ at t = 0
    low, high = scale * (b - w.abs().sum()), scale * (b + w.abs().sum())

    def certified(z, value):
        term = vhat.system.terminal_value(obs, z)
        above, below = term + low > 0, term + high <= 0
        assert bool(((value > 0) | ~above).all() and ((value <= 0) | ~below).all()), "the output bound is violated"
        return above | below

    recorded = _RecordedValues(vhat)
    feasible = reference_cold_search(recorded, obs, grid, with_grad=False).feasible
    (z_top, v_top), *halvings = recorded.calls
    assert len(halvings) == grid.steps, "reference_cold_search no longer evaluates V̂(z_max) and then every row per halving"
    count = certified(z_top, v_top).double()
    for z, v in halvings:
        count += (certified(z, v) & feasible).double()
    return float(count.mean())


def filter_rows(cfg: dict, run: str) -> tuple[int, int]:
    """``(value rows, value-and-gradient rows)`` of V_s per agent-step that run ``run``'s CBVF filter
    after MAD-PINN's control evaluates (its ``candidates`` and ``critical_neighbours``); (0, 0)
    without one."""
    method, settings = method_config(cfg, run)
    sf = settings.get("safety_filter") if method == "madpinn" else None
    return (int(sf["candidates"]), int(sf["critical_neighbours"])) if sf else (0, 0)


def floor_us_per_agent_step(value_us: float, grad_us: float, steps: int, infeasible: float) -> float:
    """µs per agent-step of the rows no identical-answer search can skip (module docstring)."""
    return value_us * (1.0 + steps * (1.0 - infeasible)) + grad_us


def cell_floor_s(cell: dict, value_us: float, grad_us: float, steps: int) -> float:
    """Seconds of V̂ rows no identical-answer search can skip in cell summary ``cell`` (its agents ×
    scenarios × steps, its ``policy_stats`` infeasible share), at these row costs."""
    agent_steps = int(cell["n_agents"]) * int(cell["n_scenarios"]) * int(cell["n_steps"])
    infeasible = float(cell["policy_stats"]["infeasible_fraction"])
    return 1e-6 * agent_steps * floor_us_per_agent_step(value_us, grad_us, steps, infeasible)


def ran_cold_bisection(stats: dict, steps: int) -> bool:
    """Whether a cell's ``policy_stats`` are the cold bisection's: no warm-start hit and V̂ rows per
    agent-step between the floor's count ``2 + steps·(1 − infeasible share)`` (the search skips
    infeasible agents' halvings since issue 48, plus a few padded rows) and ``2 + steps`` (before)."""
    rows, infeasible = stats["vhat_evals_per_agent_step"], float(stats["infeasible_fraction"])
    return stats.get("warm_hit_rate", 0.0) == 0.0 and 2 + steps * (1.0 - infeasible) - 1e-9 <= rows <= 2 + steps + 1e-9


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cells", type=Path, required=True, help="results/eval or output_cache")
    ap.add_argument("--vhat", default="models/vhat.pt")
    ap.add_argument("--vs", default="models/vs.pt", help="V_s for the CBVF filter's rows")
    ap.add_argument("--config", nargs="+", default=["config.yaml"], help="the cells' configuration (the filter's row counts)")
    ap.add_argument("--repeats", type=int, default=20)
    ap.add_argument("--rounds", type=int, default=1,
                    help="measure every row cost this many times, round-robin over the batches (module docstring)")
    ap.add_argument("--z-tolerance", type=float, default=1e-3, help="methods.madpinn.z_tolerance (config.yaml: 1e-3)")
    ap.add_argument("--skip", nargs="*", default=list(DEFAULT_SKIP), help="studies left out of the protocol's sums")
    ap.add_argument("--any-cpu", action="store_true", help="keep cells computed on another CPU model (their ratio mixes machines)")
    ap.add_argument("--named-only", action="store_true",
                    help="leave out cells naming no CPU (computed before issue 65's re-key), e.g. --cells output_cache mid-rerun")
    args = ap.parse_args()
    torch.set_num_threads(1)
    steps = bisection_steps(args.z_tolerance)
    vhat, vs = load_vhat(args.vhat), load_vs(args.vs)
    cfg = load_config(args.config)
    cells = [c for c in cell_summaries(args.cells) if c["study"] not in args.skip]
    here = cpu_model()
    elsewhere = [c for c in cells if c.get("cpu_model", here) != here]
    unnamed = sum("cpu_model" not in c for c in cells)
    print(f"this CPU: {here}; cells on another CPU: {len(elsewhere)}"
          f"{' (kept: --any-cpu)' if args.any_cpu else ' (left out)'}; cells naming no CPU (before issue 65's re-key): {unnamed}"
          f"{' (left out: --named-only)' if args.named_only else ' (kept)'}")
    if not args.any_cpu:
        cells = [c for c in cells if c.get("cpu_model", here) == here]
    if args.named_only:
        cells = [c for c in cells if "cpu_model" in c]
    if not cells:
        raise SystemExit(f"no evaluation cell summaries under {args.cells} (on this CPU)")

    # which row costs the cells need: (network, batch) -> measured (value, gradient) per round
    needed: dict[tuple[str, int], list[tuple[float, float]]] = {}
    kept = []
    left_out = 0
    for c in cells:
        stats = c.get("policy_stats") or {}
        if stats.get("vhat_evals_per_agent_step") is None:
            kept.append((c, None))
            continue
        if not ran_cold_bisection(stats, steps):
            left_out += 1
            kept.append((c, None))
            continue
        batch = int(c["n_agents"]) * int(c["n_scenarios"])
        needed.setdefault(("vhat", batch), [])
        values, grads = filter_rows(cfg, c["run"])
        for count in (values, grads):
            if count:
                needed.setdefault(("vs", batch * count), [])
        kept.append((c, (batch, values, grads)))
    nets = {"vhat": vhat, "vs": vs}
    for r in range(max(1, args.rounds)):
        for (net, batch), got in sorted(needed.items()):
            got.append(row_costs_us(nets[net], batch, args.repeats))
            if r == 0 or r == args.rounds - 1:
                print(f"round {r + 1}: batch {batch:5d}: {'V̂' if net == 'vhat' else 'V_s'} value row {got[-1][0]:.3f} us, "
                      f"value-and-gradient row {got[-1][1]:.3f} us (process CPU, 1 thread)", flush=True)
    if args.rounds > 1:
        print(f"\n{'row costs over the rounds (us)':34s} {'value min / median / max':>26s} {'gradient min / median / max':>30s}")
        for (net, batch), got in sorted(needed.items()):
            v, g = sorted(x for x, _ in got), sorted(y for _, y in got)
            print(f"{net:4s} batch {batch:5d} ({len(got)} rounds){'':12s} {v[0]:7.3f} / {median(v):7.3f} / {v[-1]:7.3f} "
                  f"{g[0]:8.3f} / {median(g):7.3f} / {g[-1]:7.3f}")

    def floors(pick) -> tuple[dict, float, float, float]:
        """Per group [cells, job h, floor h, floor + filter rows h], the total, the floor, the network floor."""
        cost = {key: (pick([v for v, _ in got]), pick([g for _, g in got])) for key, got in needed.items()}
        groups: dict[str, list[float]] = defaultdict(lambda: [0, 0.0, 0.0, 0.0])
        total_h = floor_h = net_floor_h = 0.0
        for c, row in kept:
            total_h += cell_seconds(c) / 3600.0
            if row is None:
                continue
            batch, values, grads = row
            f = cell_floor_s(c, *cost[("vhat", batch)], steps) / 3600.0
            agent_steps = int(c["n_agents"]) * int(c["n_scenarios"]) * int(c["n_steps"])
            fv = 1e-6 * agent_steps * sum(count * cost[("vs", batch * count)][kind]
                                          for kind, count in enumerate((values, grads)) if count) / 3600.0
            key = f"{c['study']}/{c['run']}"
            groups[key][0] += 1
            groups[key][1] += cell_seconds(c) / 3600.0
            groups[key][2] += f
            groups[key][3] += f + fv
            floor_h += f
            net_floor_h += f + fv
        return groups, total_h, floor_h, net_floor_h

    groups, total_h, floor_h, net_floor_h = floors(min)
    print(f"\n{'cells (cold bisection)':42s} {'n':>4s} {'job h':>7s} {'floor h':>8s} {'floor share':>11s} {'+ filter rows':>13s}")
    for key, (n, h, f, nf) in sorted(groups.items(), key=lambda kv: -kv[1][1]):
        print(f"{key:42s} {n:4d} {h:7.3f} {f:8.3f} {f / h:11.2f} {nf / h:13.2f}")
    if left_out:
        print(f"({left_out} MAD-PINN cells with another search left out)")
    cold_h = sum(h for _, h, _, _ in groups.values())
    print(f"cold_bisection_cells_core_h: {cold_h:.3f} ({cold_h / max(floor_h, 1e-12):.2f} x their floor)")
    print(f"cold_bisection_floor_core_h: {floor_h:.3f}")
    print(f"protocol_cells_core_h: {total_h:.3f}")
    print(f"protocol_time_over_floor: {total_h / max(floor_h, 1e-12):.2f}")
    print(f"network_floor_core_h: {net_floor_h:.3f} (the floor + the CBVF filter's V_s rows)")
    print(f"protocol_time_over_network_floor: {total_h / max(net_floor_h, 1e-12):.2f}")
    if args.rounds > 1:
        _, _, typ_h, typ_net_h = floors(median)
        print(f"cold_bisection_floor_core_h_typical_host: {typ_h:.3f} (median over {args.rounds} rounds; the MAD-PINN cells "
              f"{cold_h / max(typ_h, 1e-12):.2f} x it)")
        print(f"protocol_time_over_floor_typical_host: {total_h / max(typ_h, 1e-12):.2f}")
        print(f"protocol_time_over_network_floor_typical_host: {total_h / max(typ_net_h, 1e-12):.2f}")


if __name__ == "__main__":
    main()
