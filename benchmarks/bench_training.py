"""Time one V̂ training iteration: our fused exact-derivative step vs a DeepReach-style reference.

The reference computes the input gradient with ``torch.autograd.grad(..., create_graph=True)`` and
back-propagates the loss through it (double backward), as DeepReach / piml-soc do. Both steps use
the same network (SIREN 3×256), the same batch, sampling, loss and Adam update, in this process.

    PYTHONPATH=$PWD python benchmarks/bench_training.py [--batches 8192 65000] [--repeats 5] [--threads 1]

Prints iterations/s, ms/iteration and peak memory (CPU: process max RSS growth; CUDA: allocator
peak) for each method and batch size, best of ``--repeats``; the last line is
``speedup_vs_autograd_reference: X`` (at the largest batch).
"""

from __future__ import annotations

import argparse
import gc
import resource
import subprocess
import sys
import time

import torch

from madpinn.config import REPO_ROOT, load_config
from madpinn.device import resolve_device
from madpinn.value_functions.epigraph import EpigraphSystem
from madpinn.observation import ObservationSettings
from madpinn.value_functions.model import build_network
from madpinn.value_functions.problems import EpigraphProblem, assemble
from madpinn.value_functions.train import TrainSettings, train_step, training_batch


def reference_step(problem, net, opt, settings, iteration, device, dtype) -> float:
    """DeepReach-style iteration: autograd input gradient with create_graph, then backward."""
    s, t = training_batch(problem, settings, iteration, device, dtype)
    b, gb = problem.boundary_and_grad(s)
    x = problem.normalise(s, t).requires_grad_(True)
    n = net(x)
    grad_n = torch.autograd.grad(n.sum(), x, create_graph=True)[0]
    value, dv_dt, dv_ds = assemble(problem, s, t, n, grad_n, b, gb, settings.output_scale)
    loss = problem.residual(s, t, value, dv_dt, dv_ds).abs().mean()
    opt.zero_grad(set_to_none=True)
    loss.backward()
    opt.step()
    return float(loss.detach())


def peak_rss_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def setup(batch, device, dtype):
    paper = load_config([REPO_ROOT / "config.yaml"])
    spec = ObservationSettings.from_config(paper).base_mapping()
    system = EpigraphSystem.from_config(paper)
    problem = EpigraphProblem(system)
    settings = TrainSettings(iterations=1000, batch_size=batch, lr=2e-5, lr_final=2e-5, curriculum_fraction=0.5,
                             checkpoint_every=10**9, loss="l1", output_scale=1.0,
                             network=dict(paper["value_functions"]["vhat"]["network"]), seed=0, init_from=None, obstacle_weight=0.0, stop_at=None)
    torch.manual_seed(0)
    net = build_network(problem, settings.network).to(device=device, dtype=dtype)
    opt = torch.optim.Adam(net.parameters(), lr=settings.lr)
    return problem, settings, net, opt


def sync(device):
    if device.type == "cuda":
        torch.cuda.synchronize()


def time_methods(methods, batch, repeats, device, dtype) -> dict:
    """Best-of-``repeats`` seconds per iteration for each method, runs interleaved (the machine
    is shared: interleaving exposes both methods to the same background load)."""
    states = {name: setup(batch, device, dtype) for name in methods}
    best = {name: float("inf") for name in methods}
    for k in range(repeats + 1):  # iteration 0 is a warm-up
        for name, step in methods.items():
            problem, settings, net, opt = states[name]
            sync(device)
            t0 = time.perf_counter()
            step(problem, net, opt, settings, k, device, dtype)
            sync(device)
            if k > 0:
                best[name] = min(best[name], time.perf_counter() - t0)
    return best


def peak_memory_mb(method: str, batch: int, device, dtype) -> float:
    """Peak memory of one iteration of ``method``: CUDA allocator peak, or on CPU the growth of the
    max RSS of a fresh subprocess over its level after setup (each method measured alone)."""
    if device.type == "cuda":
        problem, settings, net, opt = setup(batch, device, dtype)
        torch.cuda.reset_peak_memory_stats()
        METHODS[method](problem, net, opt, settings, 0, device, dtype)
        return torch.cuda.max_memory_allocated() / 2**20
    out = subprocess.run([sys.executable, __file__, "--memory-of", method, "--batches", str(batch)],
                         capture_output=True, text=True, check=True)
    return float(out.stdout.strip().splitlines()[-1])


def _memory_of(method: str, batch: int) -> None:
    problem, settings, net, opt = setup(batch, torch.device("cpu"), torch.float32)
    gc.collect()
    before = peak_rss_mb()
    METHODS[method](problem, net, opt, settings, 0, torch.device("cpu"), torch.float32)
    print(peak_rss_mb() - before)


METHODS = {"ours": train_step, "autograd_reference": reference_step}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--batches", type=int, nargs="+", default=[8192, 65000])
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--device", default="auto")
    ap.add_argument("--memory-of", default=None, help=argparse.SUPPRESS)
    args = ap.parse_args()
    torch.set_num_threads(args.threads)
    if args.memory_of:
        return _memory_of(args.memory_of, args.batches[0])
    device = resolve_device(args.device)
    dtype = torch.float32
    print(f"device={device} threads={torch.get_num_threads()} torch={torch.__version__} network=SIREN 3x256 float32")
    speedup = None
    methods = METHODS
    for batch in args.batches:
        mem = {name: peak_memory_mb(name, batch, device, dtype) for name in methods}
        best = time_methods(methods, batch, args.repeats, device, dtype)
        unit = "peak_cuda_alloc_mb" if device.type == "cuda" else "peak_rss_growth_mb"
        for name in methods:
            print(f"batch={batch} method={name} ms_per_iter={1e3 * best[name]:.1f} "
                  f"iters_per_s={1 / best[name]:.3f} {unit}={mem[name]:.0f}")
        speedup = best["autograd_reference"] / best["ours"]
        print(f"batch={batch} speedup={speedup:.2f}")
    print(f"speedup_vs_autograd_reference: {speedup:.2f}")


if __name__ == "__main__":
    main()
