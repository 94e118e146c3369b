"""Source hashes kept between snakemake starts.

Every snakemake start (each dry run, each run, each Slurm job step) computes the rules' ``source``
params (:func:`madpinn.provenance.source_hash`), ≈ 1.5 s CPU of reading the package's syntax trees.
A source hash is a function of the package's files alone (each module's and data file's path and
bytes), so the hashes are kept under the digest of those files (:func:`package_digest`): a start
whose package is byte for byte one seen before reads them back; any edit gives a new digest and
computes afresh. A cache that cannot be read or written is left alone (the hashes are computed).
"""

from __future__ import annotations

import hashlib
import json
import os
from pathlib import Path

from madpinn.atomic import atomic_write
from madpinn.provenance import DATA_SUFFIXES, PACKAGE


def cache_dir() -> Path:
    """``$XDG_CACHE_HOME/madpinn/source_hashes`` (default ``~/.cache``)."""
    return Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "madpinn" / "source_hashes"


def package_digest(root: Path = PACKAGE) -> str:
    """sha256 over the path (relative to ``root``) and bytes of every module and data file under
    ``root``: all that a source hash reads."""
    h = hashlib.sha256()
    files = sorted(p for p in root.rglob("*") if p.suffix in (".py", *DATA_SUFFIXES) and "__pycache__" not in p.parts)
    for f in files:
        if f.is_file():
            h.update(b"%s\0%d\0%s" % (f.relative_to(root).as_posix().encode(), f.stat().st_size, f.read_bytes()))
    return h.hexdigest()


def load(digest: str, directory: Path | None = None) -> dict[str, str]:
    """The source hashes kept for package ``digest`` (key -> hash; empty when none are)."""
    try:
        kept = json.loads(((directory or cache_dir()) / f"{digest}.json").read_text())
    except (OSError, ValueError):
        return {}
    return kept if isinstance(kept, dict) else {}


def save(digest: str, hashes: dict[str, str], directory: Path | None = None) -> None:
    """Keep ``hashes`` for package ``digest`` (atomically; a failure is ignored)."""
    try:
        atomic_write((directory or cache_dir()) / f"{digest}.json",
                     lambda tmp: tmp.write_text(json.dumps(hashes, sort_keys=True)))
    except OSError:
        pass
