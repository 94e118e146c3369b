"""The files of one evaluation cell: where they lie beside its Parquet file and how its JSON summary
is read (a leaf: the cell's writer, the tables and the MLflow glue read cells through it)."""

from __future__ import annotations

import json
from pathlib import Path


def cell_paths(out: str | Path) -> tuple[Path, Path, Path]:
    """``(parquet, json, trajectory npz)`` of a cell whose Parquet file is ``out``."""
    out = Path(out)
    return out, out.with_suffix(".json"), out.with_name(out.stem + "_traj.npz")


def cell_summary(parquet: str | Path) -> dict:
    """The JSON summary written beside a cell's Parquet file (``{}`` when there is none)."""
    summary = cell_paths(parquet)[1]
    return json.loads(summary.read_text()) if summary.is_file() else {}
