"""Issue 61: the paper's numbers live in madpinn/evaluation/paper_values.yaml only; no source file
of the package types one (a check string quoting "99.33 %" goes stale when the file is corrected)."""

from __future__ import annotations

import re

from conftest import REPO
from madpinn.evaluation.reproduction import paper_values

ALLOWED = {"0.975": "the 97.5 % quantile of every 95 % t-interval, not the paper's SafeMARL safety",
           "100": "a whole percentage, seed floors, sizes"}


def _significant(text: str) -> int:
    return len(text.replace(".", "").lstrip("0"))


def paper_numbers(values=None) -> set[str]:
    """The paper's table values as printed (percent) and as fractions, with ≥ 3 significant digits
    (shorter numbers such as 0.5 or 2 are everywhere in code)."""
    out = set()
    for table in (values or paper_values()).values():
        for row in table["runs"].values():
            for cell in row["n"].values():
                for key, v in cell.items():
                    if v is None or key.endswith("_std"):
                        continue
                    forms = [f"{v:g}"] if key == "cost" else [f"{round(100 * v, 6):g}", f"{v:g}"]
                    out |= {f for f in forms if _significant(f) >= 3}
    return out - set(ALLOWED)


def typed(text: str, numbers: set[str]) -> list[str]:
    pattern = re.compile(r"(?<![\d.])(" + "|".join(map(re.escape, sorted(numbers, key=len, reverse=True))) + r")(?!\d)")
    return [m.group(0) for m in pattern.finditer(text)]


def test_no_paper_number_typed_in_the_package():
    numbers = paper_numbers()
    hits = [f"{f.relative_to(REPO)}:{i}: {n}" for f in sorted((REPO / "madpinn").rglob("*.py"))
            for i, line in enumerate(f.read_text().splitlines(), 1) for n in typed(line, numbers)]
    assert not hits, "paper numbers typed outside paper_values.yaml:\n" + "\n".join(hits)


def test_the_scan_finds_a_typed_number():
    numbers = paper_numbers()
    assert "99.33" in numbers and "0.9933" in numbers and "2.73" in numbers
    assert typed('Check("k5", "99.99 vs 99.33 %")', numbers) == ["99.99", "99.33"]
    assert typed("v = 199.33; w = 99.331", numbers) == []
