"""Rewrite README.md's generated blocks from the committed report (paper_figures/).

    python scripts/update_readme.py [--check]

Every block ``<!-- NAME:start -->`` … ``<!-- NAME:end -->`` is replaced by its rendering
(madpinn/evaluation/readme_blocks.py). ``--check`` writes nothing and exits 1 when README is stale.
Run it after a protocol run has regenerated ``paper_figures/``; the workflow never edits README.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from madpinn.evaluation.readme_blocks import render_readme

REPO = Path(__file__).resolve().parents[1]


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--readme", type=Path, default=REPO / "README.md")
    ap.add_argument("--figures", type=Path, default=REPO / "paper_figures")
    ap.add_argument("--check", action="store_true", help="exit 1 if README is stale; write nothing")
    args = ap.parse_args()
    text = args.readme.read_text()
    try:
        new = render_readme(text, args.figures)
    except (ValueError, OSError) as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    if new == text:
        print(f"{args.readme}: up to date")
        return 0
    if args.check:
        print(f"{args.readme}: stale generated blocks; run python scripts/update_readme.py", file=sys.stderr)
        return 1
    args.readme.write_text(new)
    print(f"{args.readme}: blocks rewritten")
    return 0


if __name__ == "__main__":
    sys.exit(main())
