"""The paper's timing claim (Results 4, tex 467; complexity, tex 346) against our measurement
(:mod:`madpinn.evaluation.neighbour_timing`, the workflow's ``neighbour_timing`` job, this machine's
hardware named): per agent and update, the selection time against the paper's figure, and the fitted
exponent of the per-agent time in N against the paper's linear growth (T_i = (N − 1) T_s).

Readings: the paper's account scores all N − 1 partners of every agent (stated); the protocol's
deployment scores only the partners within the sensing radius, which the paper does not state (a
reading of ours). Both run on this machine; the paper does not name its hardware.
"""

from __future__ import annotations

from typing import Mapping

from madpinn.evaluation.claim_checks import STATED, Check

STATED_SELECTOR = "all pairs"
"""the selector of the paper's account (T_i = (N − 1) T_s)"""


def timing_checks(timing: Mapping | None) -> list[Check]:
    """Per agent count: ms per agent ≤ the paper's; and the exponent's interval reaching ≤ 1."""
    from madpinn.evaluation.paper_consistency import raw

    if not timing:
        return []
    paper_ms = raw()["protocol"]["neighbour_selection_ms"]
    hw = timing.get("hardware", "")
    out = []
    for sel in timing.get("fit", {}):
        reading = {"reading": STATED, "stated": True} if sel == STATED_SELECTOR else \
            {"reading": f"{sel}: partners within the sensing radius only", "stated": False}
        for r in timing["rows"]:
            ms = r[sel]
            out.append(Check(f"N = {r['n']}: selection takes at most the paper's {paper_ms:g} ms per agent",
                             f"{ms:.3f} ms per agent per update ({r['arena']} arena; {hw})", (), ms <= paper_ms,
                             f"{paper_ms:g} ms (hardware not named)", "time", margin=(paper_ms - ms) / paper_ms, **reading))
        fit = timing["fit"][sel]
        if fit.get("exponent") is not None:
            out.append(Check("time per agent grows at most linearly in N (fitted exponent's 95 % interval reaches ≤ 1)",
                             f"exponent {fit['exponent']:.2f} [{fit['lo']:.2f}, {fit['hi']:.2f}] over N = "
                             f"{timing['rows'][0]['n']} … {timing['rows'][-1]['n']}", (), fit["lo"] <= 1.0,
                             "T_i = (N − 1) T_s: linear", "scaling", essential=True,
                             margin=(1.0 - fit["lo"]) / max(fit["hi"] - fit["lo"], 1e-3), **reading))
    return out
