"""Hints that name the command building a missing workflow output (checkpoints, results)."""

from __future__ import annotations

from pathlib import Path


def build_hint(path: str | Path) -> str:
    """``snakemake -j2 <path>``: a missing file the workflow writes is its own Snakemake target
    (the training rules write ``<paths.results>/models/<name>.pt``). Run it in the workflow's
    directory with the ``--configfile`` options of the run that needs the file, so that
    ``paths.results`` is the same."""
    return f"build it with: snakemake -j2 {path} (plus the --configfile options of this run)"
