"""Checks and verdicts of the claims table (issues 47, 61): what one check is, the verdict scale,
and readers of the reproduction report's cells.

A :class:`Check` states what the paper's sentence leads one to *expect* and what we *observe*, names
the *part* of the claim it tests (cost, safety, …) and the *reading* it belongs to: the run or
convention it judges. A reading is *stated* when the paper states it (its own row, its cost metric
"accumulated along safe trajectories"); our labelled extensions and conventions are unstated.

Verdict scale (:func:`verdict`, :func:`claim_verdict`), one verdict per reading:

- ``holds``: every check passes;
- ``partly (k of n)``: k of the n checks pass, no essential one fails;
- ``does not hold``: an essential check fails, or none passes;
- the claim's verdict pools its stated readings; when that is not ``holds`` but each paper row it
  tests holds under its own or an unstated reading (e.g. the authors' layered SafeMARL filter in
  place of ours): ``holds only under readings the paper does not state``.

``margin`` (in widths of the observed interval, > 0 when the check passes) picks the headline
check (:func:`headline`): the failed essential check, else the clearest failure; when all pass,
the essential check, else the closest pass.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping

HOLDS, PARTLY, DOES_NOT, UNMEASURED = "holds", "partly", "does not hold", "not judged"
UNSTATED = "holds only under readings the paper does not state"
SCALE = (HOLDS, PARTLY, UNSTATED, DOES_NOT, UNMEASURED)
"""the verdict scale, in the order the page counts it"""
STATED = "the paper's"
"""reading name of checks on the paper's own run and convention"""


@dataclass(frozen=True)
class Check:
    """One predicate over report cells; ``passed`` None when a cell it needs is missing or unjudged."""

    expected: str
    observed: str
    cells: tuple[str, ...]
    passed: bool | None
    paper: str = ""
    part: str = ""
    essential: bool = False
    reading: str = STATED
    stated: bool = True
    margin: float | None = None
    row: str = ""


def verdict(checks: list[Check]) -> str:
    """The verdict of one reading's checks (module docstring); unjudged checks do not count."""
    known = [c for c in checks if c.passed is not None]
    if not known:
        return UNMEASURED
    k = sum(c.passed for c in known)
    if any(c.essential and not c.passed for c in known) or k == 0:
        return DOES_NOT
    return HOLDS if k == len(known) else f"{PARTLY} ({k} of {len(known)})"


def by_reading(checks: list[Check]) -> dict[str, list[Check]]:
    out: dict[str, list[Check]] = {}
    for c in checks:
        out.setdefault(c.reading, []).append(c)
    return out


def claim_verdict(checks: list[Check]) -> str:
    """The claim's verdict: its stated readings pooled; :data:`UNSTATED` when each paper row (``row``)
    the stated checks test holds under its own reading or an unstated one (``row`` "": the whole claim)."""
    stated = verdict([c for c in checks if c.stated])
    if stated == HOLDS:
        return HOLDS
    alts = {r: cs for r, cs in by_reading(checks).items() if not cs[0].stated}
    if any(verdict(cs) == HOLDS for cs in alts.values() if not cs[0].row):
        return UNSTATED
    rows = {c.row for c in checks if c.stated}
    if not rows:   # only readings of ours (e.g. a tolerance the paper does not state)
        return verdict([c for cs in alts.values() for c in cs])
    holds = lambda row, cs: verdict([c for c in cs if c.row == row]) == HOLDS   # noqa: E731
    if alts and all(holds(row, [c for c in checks if c.stated]) or any(holds(row, cs) for cs in alts.values())
                    for row in rows):
        return UNSTATED
    return stated


def scale_of(v: str) -> str:
    """The scale word of a verdict (``partly (3 of 4)`` -> ``partly``)."""
    return v.split(" (")[0]


def headline(checks: list[Check]) -> Check | None:
    """The most informative check: of the stated readings (else all), the failed essential one, else
    the failure with the largest margin; when all pass, the essential one, else the closest pass."""
    pool = [c for c in checks if c.stated and c.passed is not None] or [c for c in checks if c.passed is not None]
    if not pool:
        return checks[0] if checks else None
    m = lambda c: 0.0 if c.margin is None else c.margin   # noqa: E731
    failed = [c for c in pool if not c.passed]
    if failed:
        return next((c for c in failed if c.essential), min(failed, key=m))
    return next((c for c in pool if c.essential), min(pool, key=m))


# --- reading the report -------------------------------------------------------------------------

def cell(rep: Mapping, table: str, run: str, n) -> dict | None:
    c = rep.get(table, {}).get(run, {}).get(str(n))
    return c if c and c.get("safety") is not None else None


def ns(rep: Mapping, table: str, run: str) -> list[int]:
    return sorted(int(n) for n, c in rep.get(table, {}).get(run, {}).items() if c.get("safety") is not None)


def name(table: str, run: str, n) -> str:
    return f"{table}/{run}/N={n}"


def label(rep: Mapping, table: str, run: str) -> str:
    cells = rep.get(table, {}).get(run, {})
    return next(iter(cells.values()), {}).get("label", run) if cells else run


def fig(c: dict | None, key: str) -> tuple[float, float, float] | None:
    """(mean, lo, hi) of a cell's figure; None without an interval."""
    ci = (c or {}).get(f"{key}_ci")
    return None if not c or c.get(key) is None or not ci else (c[key], ci[0], ci[1])


def diff(c: dict | None, key: str) -> tuple[float, float, float] | None:
    """(diff, lo, hi) of the cell's paired difference from the table's Ours."""
    v = ((c or {}).get("vs_ours") or {}).get(key)
    return None if not v or v["diff"] is None or v["lo"] is None else (v["diff"], v["lo"], v["hi"])


def width(x: tuple[float, float, float]) -> float:
    return max(x[2] - x[1], 1e-3)


def above(x, b: float) -> tuple[bool, float]:
    """Interval wholly above ``b``: (passed, margin)."""
    return x[1] > b, (x[1] - b) / width(x)


def below(x, b: float) -> tuple[bool, float]:
    """Interval wholly below ``b``: (passed, margin)."""
    return x[2] < b, (b - x[2]) / width(x)


def reaches(x, b: float) -> tuple[bool, float]:
    """Interval's upper end at or above ``b``: (passed, margin)."""
    return x[2] >= b, (x[2] - b) / width(x)


def direction(d, more: str, less: str, same: str = "no significant difference") -> str:
    """The word of a paired difference: ``more`` when its interval lies above 0, ``less`` below."""
    return more if d[1] > 0 else less if d[2] < 0 else same


# --- formatting ----------------------------------------------------------------------------------

def pp(x) -> str:
    return f"{100 * x[0]:.1f} % [{100 * x[1]:.1f}, {100 * x[2]:.1f}]"


def dpp(x) -> str:
    return f"{100 * x[0]:+.1f} pp [{100 * x[1]:+.1f}, {100 * x[2]:+.1f}]"


def dcost(x) -> str:
    return f"{x[0]:+.3f} [{x[1]:+.3f}, {x[2]:+.3f}]"


def cost(x) -> str:
    return f"{x[0]:.2f} [{x[1]:.2f}, {x[2]:.2f}]"


def pct(p: float | None) -> str:
    """A paper fraction as a percentage with the digits the paper prints (0.5 -> 50 %)."""
    return "–" if p is None else f"{100 * p:.6g} %"


def fall(x) -> str:
    return f"falls {100 * x[0]:.1f} pp [{100 * x[1]:.1f}, {100 * x[2]:.1f}]"


def drop(rep: Mapping, table: str, run: str, lo_n: int, hi_n: int, key: str = "safety"):
    """The fall of ``key`` from N = lo_n to hi_n: (mean, conservative lo, hi) from the two cells' intervals."""
    fa, fb = fig(cell(rep, table, run, lo_n), key), fig(cell(rep, table, run, hi_n), key)
    return None if not (fa and fb) else (fa[0] - fb[0], fa[1] - fb[2], fa[2] - fb[1])
