"""The repository's root and the directories a configuration writes: checked before any job
(dry runs included) without writing anything."""

from __future__ import annotations

from pathlib import Path
from typing import Any, Mapping

from madpinn.config.hashing import lookup_key


REPO_ROOT = Path(__file__).resolve().parents[2]
"""the repository (the package's parent directory)"""


def in_repository(path: str | Path) -> Path:
    """``path`` as a file of the repository: relative paths are read from :data:`REPO_ROOT` (a committed,
    published page such as ``paper_figures/…``), whatever the workflow's working directory."""
    path = Path(path)
    return path if path.is_absolute() else REPO_ROOT / path


def write_if_changed(path: str | Path, text: str) -> Path:
    """Write ``text`` only if the file content differs (keeps mtimes stable for Snakemake)."""
    from madpinn.atomic import atomic_write

    path = Path(path)
    if path.is_file() and path.read_text() == text:
        return path
    return atomic_write(path, lambda tmp: tmp.write_text(text))

OUTPUT_PATH_KEYS = ("paths.results", "paths.figures")
"""the directories the workflow writes (checked before any job, dry runs included)"""


def unwritable_reason(path: str | Path) -> str | None:
    """Why directory ``path`` could not be created or written, or None when it can, found without
    writing anything (a dry run's check): the path or its nearest existing ancestor must be a
    directory this process may write (``os.access``: permissions, read-only mounts, immutable
    directories) on a file system with storage (``/proc``, ``/sys`` have none)."""
    import os

    path = Path(path).absolute()
    node = path
    while not node.exists() and node != node.parent:
        node = node.parent
    if not node.is_dir():
        return f"{node} is not a directory"
    if not os.access(node, os.W_OK | os.X_OK):
        return f"{node} is not writable" + (" (read-only file system)" if os.statvfs(node).f_flag & os.ST_RDONLY else "")
    if os.statvfs(node).f_blocks == 0:
        return f"{node} is on a file system without storage (e.g. /proc, /sys)"
    return None


def _unwritable_output_paths(cfg: Mapping[str, Any]) -> list[str]:
    """A line naming each key of :data:`OUTPUT_PATH_KEYS` whose directory cannot be written
    (:func:`unwritable_reason`); relative paths are taken from the working directory."""
    lines = []
    for key in OUTPUT_PATH_KEYS:
        value = lookup_key(cfg, key)
        reason = unwritable_reason(value) if value is not None else None
        if reason:
            lines.append(f"  - '{key}': {value!r} cannot be written: {reason}")
    return lines
