"""What follows the machine and not the job, read while the workflow plans: the device a cell is
keyed under and the environment pinned for every job. Light: torch is imported only where a GPU's
device node exists (a snakemake start then pays no ``import torch``)."""

from __future__ import annotations

import os

GPU_DEVICE_NODES = ("/dev/nvidiactl", "/dev/nvidia0", "/dev/dxg", "/dev/kfd")
"""device nodes without one of which no torch build sees a GPU (NVIDIA's driver, WSL2's GPU
paravirtualisation, ROCm's kernel driver, whose HIP builds answer ``torch.cuda``)"""


def cuda_available() -> bool:
    """``torch.cuda.is_available()``, without importing torch on a machine that has none of
    :data:`GPU_DEVICE_NODES` (where it is False for every torch build)."""
    if not any(os.path.exists(p) for p in GPU_DEVICE_NODES):
        return False
    import torch

    return bool(torch.cuda.is_available())


def planned_device(name: str = "auto") -> str:
    """The device kind (``cpu`` | ``cuda``) an evaluation cell is keyed under and runs on, fixed
    when the workflow plans it: ``cuda`` for a ``cuda`` setting, or for ``auto`` on a machine with
    CUDA; else ``cpu``. A cell's floating-point results depend on the device (GPU kernels sum in
    another order), so the workflow passes it to the job as a param (``evaluate --device``): a
    GPU cell and a CPU cell of the same settings are two output-cache entries, never one restored
    for the other. On a cluster whose planning machine has no GPU, ``device: cuda`` plans GPU
    cells (the job stops with one line on a node without one)."""
    if name == "auto":
        return "cuda" if cuda_available() else "cpu"
    return "cuda" if name.startswith("cuda") else "cpu"


CPU_INFO = "/proc/cpuinfo"
"""where Linux lists the CPU's feature flags"""


def cpu_flags() -> set[str]:
    """The CPU's feature flags (Linux: :data:`CPU_INFO`), empty elsewhere."""
    try:
        with open(CPU_INFO) as f:
            return next((set(line.split(":", 1)[1].split()) for line in f if line.startswith("flags")), set())
    except OSError:
        return set()


def cpu_model() -> str:
    """The CPU's model name (Linux: :data:`CPU_INFO`'s ``model name``; else ``platform.processor()``),
    recorded in each cell's summary: a cell's time compares with a floor measured on the same CPU only."""
    try:
        with open(CPU_INFO) as f:
            name = next((line.split(":", 1)[1].strip() for line in f if line.startswith("model name")), "")
    except OSError:
        name = ""
    if not name:
        import platform

        name = platform.processor() or platform.machine()
    return name or "unknown"


def pinned_job_environment() -> dict[str, str]:
    """What follows the machine and not the job, pinned for every workflow job (issue 66 item 2; the
    workflow sets each only where the user has not). Thread pools: one thread in BLAS and OpenMP
    unless the job sets its own (:func:`seed_everything`'s ``threads``); they otherwise start one per
    core. SIMD level: on a machine with AVX-512 numpy's dispatched loops, OpenBLAS's kernels, torch's
    kernels and MKL take AVX-512 paths that round differently from their AVX2 (x86-64-v3) ones, and
    a cell's contacts amplify a last-bit difference; all four are held at AVX2 where the CPU has it.
    On an AVX2 machine none of this changes a bit (scripts/cell_recompute.py,
    docs/reference/reliability.md)."""
    env = {"OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}
    if {"avx2", "fma"} <= cpu_flags():
        env.update(NPY_DISABLE_CPU_FEATURES="X86_V4 AVX512_ICL AVX512_SPR", OPENBLAS_CORETYPE="Haswell",
                   ATEN_CPU_CAPABILITY="avx2", MKL_ENABLE_INSTRUCTIONS="AVX2")
    return env
