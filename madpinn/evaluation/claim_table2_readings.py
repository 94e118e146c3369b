"""Table II's claim judged over the readings the paper leaves open (issue 60 item 5): the checks
come from the readings page's ``verdict.json`` (:func:`madpinn.evaluation.table_ii_readings.claim_verdict`,
rule ``table_ii_readings``), one per judged reading. The protocol's reading is the stated one; every
other reading is unstated (a start/goal law, deployment or horizon the paper does not give), so the
claims page's scale gives "holds only under readings the paper does not state" exactly when the
readings page's verdict does."""

from __future__ import annotations

from typing import Mapping

from madpinn.evaluation.claim_checks import STATED, Check
from madpinn.evaluation.table_ii_page import reading_name


def readings_checks(verdict: Mapping | None) -> list[Check]:
    """One check per judged reading: it reproduces Table II by the pre-registered scale."""
    if not verdict or not verdict.get("judged"):
        return []
    proto = reading_name(verdict["protocol"])
    out = []
    for r in verdict["judged"]:
        stated = reading_name(r) == proto
        out.append(Check("every check of the pre-registered scale at 64 / 128 / 256 agents (safety − 2 points, safe "
                         "scenarios − 15 points, cost ± 25 % in one cost reading)",
                         f"{r['checks_passed']} of {r['checks']} checks" + (f"; failed: {r['failed']}" if r.get("failed") else ""),
                         (f"table_ii_readings/{reading_name(r)}",),
                         bool(r["reproduces"]), "Table II", r["pattern"], essential=stated,
                         reading=STATED if stated else reading_name(r), stated=stated, row="madpinn" if stated else "",
                         margin=(r["checks_passed"] - r["checks"]) / r["checks"]))
    return out
