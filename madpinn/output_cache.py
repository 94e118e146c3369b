"""Entries of Snakemake's between-workflow output cache (``--cache``; ``paths.output_cache``, the
committed ``output_cache/`` of profile ``shipped``), checked before a run may restore any of them.

Snakemake restores a cached job by symlinking its entry in place and checks nothing: a truncated
or damaged entry became a "finished" cell, and the table job built from it failed later (after
which Snakemake deleted the committed table, issue 50 item 1). :func:`check_entries` reads every
entry whole with the reader of its kind (Parquet: every column; JSON; NPZ: the CRC of every
member) and raises :class:`CacheEntryError` naming the first unreadable one; it writes nothing.
Cost: ≈ 1 s for the protocol's 1 083 entries (32 MB) on one core.
"""

from __future__ import annotations

import json
import os
import zipfile
from pathlib import Path


class CacheEntryError(RuntimeError):
    """An output-cache entry cannot be read (truncated, damaged or replaced)."""


def _parquet(path: Path) -> None:
    import pyarrow.parquet as pq

    pq.read_table(path)


def _json(path: Path) -> None:
    json.loads(path.read_bytes())


def _npz(path: Path) -> None:
    with zipfile.ZipFile(path) as z:
        bad = z.testzip()
    if bad is not None:
        raise ValueError(f"member {bad} fails its CRC check")


READERS = {".parquet": _parquet, ".json": _json, ".npz": _npz}
"""Entry suffix (the cached output's own) -> a reader that raises when the entry is unreadable."""


def check_entries(directory: str | Path) -> int:
    """Read every entry of the output cache ``directory`` (files of a kind in :data:`READERS`;
    others, e.g. its README, are skipped); return how many were checked. Raises
    :class:`CacheEntryError` for the first unreadable one."""
    checked = 0
    for path in sorted(Path(directory).iterdir()):
        reader = READERS.get(path.suffix)
        if reader is None or not path.is_file():
            continue
        try:
            reader(path)
        except Exception as exc:  # noqa: BLE001 - any failure to read means the entry is unusable
            shown = os.path.relpath(path) if path.resolve().is_relative_to(Path.cwd().resolve()) else path
            raise CacheEntryError(f"output cache entry {shown} is unreadable ({type(exc).__name__}: {exc}); a run "
                                  f"would restore it as a finished result") from exc
        checked += 1
    return checked
