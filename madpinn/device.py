"""Torch device/dtype resolution and determinism settings shared by every entry point. What the
workflow reads of the machine while it plans (the planned device, the pinned job environment) is
:mod:`madpinn.machine`, which imports no torch."""

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
