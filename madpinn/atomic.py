"""Atomic file writes: a reader (or a job killed mid-write) never sees a half-written file."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any, Callable


class UnwritableDirectoryError(OSError):
    """A directory a command must write into cannot be written (permissions, a read-only mount,
    a regular file in its path); raised before anything is written there."""


def atomic_write(path: str | Path, write: Callable[[Path], Any]) -> Path:
    """Call ``write(tmp)`` on a temporary file beside ``path`` (unique per process), then rename
    it onto ``path``; parents are created, the temporary file never outlives the call."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f"{path.name}.tmp{os.getpid()}")
    try:
        write(tmp)
        tmp.replace(path)
    finally:
        tmp.unlink(missing_ok=True)
    return path


def save_torch(payload: Any, path: str | Path) -> Path:
    """``torch.save(payload)`` to ``path`` atomically (load back with ``weights_only=True``). The
    bytes are those of a save to memory, so they depend on the payload alone: saved to a file,
    torch names the archive's records after that file (here a per-process temporary name), and
    two identical payloads written to two paths would differ."""
    import io

    import torch

    buffer = io.BytesIO()
    torch.save(payload, buffer)
    return atomic_write(path, lambda tmp: tmp.write_bytes(buffer.getvalue()))
