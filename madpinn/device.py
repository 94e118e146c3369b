"""Torch device/dtype resolution and determinism settings shared by every entry point."""

from __future__ import annotations

import random

import numpy as np
import torch

_DTYPES = {"float32": torch.float32, "float64": torch.float64}


class DeviceUnavailableError(RuntimeError):
    """A job asked for CUDA on a machine without it."""


def resolve_device(name: str = "auto") -> torch.device:
    """``auto`` -> CUDA when available, else CPU. ``cuda`` without a GPU is a clear error
    (:class:`DeviceUnavailableError`)."""
    if name == "auto":
        return torch.device("cuda" if torch.cuda.is_available() else "cpu")
    if name.startswith("cuda") and not torch.cuda.is_available():
        raise DeviceUnavailableError(f"device '{name}' requested but CUDA is not available on this machine")
    return torch.device(name)


def planned_device(name: str = "auto") -> str:
    """The device kind (``cpu`` | ``cuda``) an evaluation cell is keyed under and runs on, fixed
    when the workflow plans it: ``cuda`` for a ``cuda`` setting, or for ``auto`` on a machine with
    CUDA; else ``cpu``. A cell's floating-point results depend on the device (GPU kernels sum in
    another order), so the workflow passes it to the job as a param (``evaluate --device``): a
    GPU cell and a CPU cell of the same settings are two output-cache entries, never one restored
    for the other. On a cluster whose planning machine has no GPU, ``device: cuda`` plans GPU
    cells (the job stops with one line on a node without one)."""
    if name == "auto":
        return "cuda" if torch.cuda.is_available() else "cpu"
    return "cuda" if name.startswith("cuda") else "cpu"


def resolve_dtype(name: str = "float32") -> torch.dtype:
    try:
        return _DTYPES[name]
    except KeyError as exc:
        raise ValueError(f"dtype must be one of {sorted(_DTYPES)}, got '{name}'") from exc


def seed_everything(seed: int, threads: int | None = None) -> None:
    """Seed python/numpy/torch RNGs; fix the intra-op thread count (float reduction order)."""
    random.seed(seed)
    np.random.seed(seed % (2**32))
    torch.manual_seed(seed)
    if threads is not None:
        torch.set_num_threads(max(1, int(threads)))


CPU_INFO = "/proc/cpuinfo"
"""where Linux lists the CPU's feature flags"""


def cpu_flags() -> set[str]:
    """The CPU's feature flags (Linux: :data:`CPU_INFO`), empty elsewhere."""
    try:
        with open(CPU_INFO) as f:
            return next((set(line.split(":", 1)[1].split()) for line in f if line.startswith("flags")), set())
    except OSError:
        return set()


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
