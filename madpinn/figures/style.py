"""Shared matplotlib setup: headless backend, consistent colours per run, saving as PDF + PNG."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import seaborn as sns  # noqa: E402


def setup() -> None:
    sns.set_theme(style="whitegrid", context="paper", font_scale=1.1)


def palette(runs: list[str]) -> dict[str, tuple]:
    colours = sns.color_palette("tab10", n_colors=max(10, len(runs)))
    return {run: colours[i] for i, run in enumerate(runs)}


def save(fig, out_prefix: str | Path) -> list[Path]:
    """Write ``<prefix>.pdf`` and ``<prefix>.png``; returns both paths. Byte-identical for the same
    figure (no creation date in the PDF), so a rerun of the workflow leaves committed figures
    unchanged."""
    out_prefix = Path(out_prefix)
    out_prefix.parent.mkdir(parents=True, exist_ok=True)
    paths = [out_prefix.with_suffix(".pdf"), out_prefix.with_suffix(".png")]
    fig.savefig(paths[0], bbox_inches="tight", metadata={"CreationDate": None})
    fig.savefig(paths[1], bbox_inches="tight", dpi=160)
    plt.close(fig)
    return paths
