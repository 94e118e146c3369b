"""The calibration report (``calibrate-vhat``, :mod:`madpinn.value_functions.calibration`) as a
table: one row per (distribution, split, closing-speed bin, ε, β) with the calibrated δ, the
accepted fractions and the held-out coverage (issue 62, not in the paper). Written as CSV, Markdown and an HTML page
(the Snakemake report's item)."""

from __future__ import annotations

from pathlib import Path

import pandas as pd

COLUMNS = ("Distribution", "Split", "Closing speed", "ε", "β", "δ", "Calibration accepted",
           "Held-out accepted", "Held-out violations", "Held-out rate", "Held-out bound", "Coverage met")


def _pct(x: float) -> str:
    return f"{100 * x:.1f} %"


def calibration_frame(report: dict) -> pd.DataFrame:
    """The display table of a calibration report (``δ`` "none" where no level is certified)."""
    rows = []
    for dist, block in report["distributions"].items():
        for split in ("pooled", "binned"):
            for r in block[split]:
                c, t = r["calibration"], r["test"]
                rows.append([dist, split, r["bin_label"], f"{r['epsilon']:g}", f"{r['beta']:g}",
                             "none" if r["delta"] is None else f"{r['delta']:.3f}",
                             f"{_pct(c['accepted_fraction'])} ({c['accepted']}/{c['samples']})",
                             f"{_pct(t['accepted_fraction'])} ({t['accepted']}/{t['samples']})",
                             f"{t['violations']}/{t['accepted']}", _pct(t["rate"]) if t["accepted"] else "–",
                             _pct(t["upper_bound"]) if t["accepted"] else "–", "yes" if t["coverage_met"] else "NO"])
    return pd.DataFrame(rows, columns=list(COLUMNS))


def write_calibration_table(report: dict, csv: str | Path, md: str | Path, html: str | Path) -> list[Path]:
    """Write the table of ``report`` as CSV, Markdown and an HTML page; returns the paths."""
    from madpinn.atomic import atomic_write
    from madpinn.evaluation.html import markdown_page
    from madpinn.evaluation.tables import to_markdown

    frame = calibration_frame(report)
    title = "V̂ safety level δ: calibration and held-out coverage (not in the paper)"
    text = (f"# {title}\n\nSeed {report['seed']}, rollouts dt {report['dt']} s, z tolerance {report['z_tolerance']:g}; "
            f"candidate levels 0 … {report['levels'][-1]:g} ({len(report['levels'])}).\n\n" + to_markdown(frame))
    paths = [Path(csv), Path(md), Path(html)]
    for path, content in zip(paths, (frame.to_csv(index=False), text, markdown_page(text, title))):
        atomic_write(path, lambda tmp, c=content: tmp.write_text(c, encoding="utf-8"))
    return paths
