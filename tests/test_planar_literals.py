"""The planar double integrator lives in ``madpinn/dynamics/`` (issue 63): code elsewhere reads
sizes and offsets from the agent model (:class:`madpinn.dynamics.AgentModel`), not from literals.

Counted in code (strings and comments removed), outside ``madpinn/dynamics/``:

- a slice of the planar layout after a comma: ``[..., 0:2]``, ``[:, 2:4]``, ``[..., 4:6]``,
  ``[..., :2]``, ``[..., 2:]`` (positions, velocities, goals of the 2-D state / observation);
- a literal 2, 4 or 6 as the last size given to ``reshape`` / ``view`` / ``expand`` / a tensor
  constructor (the control, state and neighbour-block sizes).

The goal is 0; until then :data:`BOUND` pins the count, which may only fall.
"""

from __future__ import annotations

import io
import re
import tokenize

from madpinn.provenance import PACKAGE

SLICE = re.compile(r",\s*(?:0?:2|2:4|4:6|2:)\s*\]")
SIZE = re.compile(r"\b(?:reshape|view|expand|new_zeros|zeros|ones|empty|full|rand|randn)\([^()]*,\s*[246]\s*\)")
BOUND = 0
"""today's count (the command in docs/reference/architecture.md prints it); lower it as it falls"""


def _code_lines(text: str) -> list[str]:
    """The file's lines with strings and comments blanked (line numbers kept)."""
    lines = text.splitlines()
    out = [list(line) for line in lines]
    for tok in tokenize.generate_tokens(io.StringIO(text).readline):
        if tok.type in (tokenize.STRING, tokenize.COMMENT) or tok.type == getattr(tokenize, "FSTRING_MIDDLE", -1):
            (r0, c0), (r1, c1) = tok.start, tok.end
            for r in range(r0, r1 + 1):
                row = out[r - 1]
                lo = c0 if r == r0 else 0
                hi = c1 if r == r1 else len(row)
                row[lo:hi] = " " * (hi - lo)
    return ["".join(r) for r in out]


def planar_literals() -> list[str]:
    """``path:line: code`` for every planar literal outside ``madpinn/dynamics/``."""
    hits = []
    for f in sorted(PACKAGE.rglob("*.py")):
        rel = f.relative_to(PACKAGE.parent)
        if rel.parts[1] == "dynamics":
            continue
        for i, line in enumerate(_code_lines(f.read_text()), 1):
            n = len(SLICE.findall(line)) + len(SIZE.findall(line))
            hits += [f"{rel}:{i}: {line.strip()}"] * n
    return hits


def test_the_patterns_see_planar_literals_and_nothing_else():
    seen = _code_lines('x = s[..., 0:2] + s[:, 2:4]  # [..., 4:6]\ny = u.reshape(S, N, 2)\nz = "[..., 0:2]"\nq = path[:2]\n')
    assert [len(SLICE.findall(line)) + len(SIZE.findall(line)) for line in seen] == [2, 1, 0, 0]


def test_planar_literals_outside_dynamics_only_fall():
    hits = planar_literals()
    assert len(hits) <= BOUND, "new planar literals outside madpinn/dynamics/ (read sizes from the agent model):\n" + "\n".join(hits)


if __name__ == "__main__":
    found = planar_literals()
    print("\n".join(found))
    print(len(found), "planar literals outside madpinn/dynamics/")
