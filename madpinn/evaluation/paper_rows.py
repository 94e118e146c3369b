"""The paper's own rows: its method's safety in each arena at given agent counts (Table I in the
small arena, Table II in the large one; uniform scenarios only), read from the paper-values file."""

from __future__ import annotations

from typing import Iterable

from madpinn.evaluation.reproduction import paper_values
from madpinn.scenarios import UNIFORM

PAPER_TABLE_OF_ARENA = {"large": "table_ours_scaling", "small": "table_safety_scaling"}
"""the paper's table of its own method in each arena (Table II, Table I of paper_values.yaml)"""
PAPER_RUN = "madpinn"


def paper_cells(arena: str, pattern: str | None, counts: Iterable[int]) -> dict[int, dict]:
    """The paper's cells of its own method in ``arena`` at ``counts``: N -> its paper-values entry
    (``safety``, ``safe_scenarios`` as fractions, ``cost``, …); uniform scenarios only (the paper
    tests no structured conflict)."""
    if (pattern or UNIFORM) != UNIFORM or arena not in PAPER_TABLE_OF_ARENA:
        return {}
    cells = paper_values()[PAPER_TABLE_OF_ARENA[arena]]["runs"][PAPER_RUN]["n"]
    return {int(n): cells[int(n)] for n in counts if int(n) in cells}


def paper_safety(arena: str, pattern: str | None, counts: Iterable[int]) -> dict[int, float]:
    """The paper's safety (%) of its own method in ``arena`` at ``counts`` (:func:`paper_cells`)."""
    return {n: 100 * c["safety"] for n, c in paper_cells(arena, pattern, counts).items()}
