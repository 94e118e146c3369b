"""Shared matplotlib setup: headless backend, consistent colours per run, saving as PDF + PNG."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import seaborn as sns  # noqa: E402


def setup() -> None:
    sns.set_theme(style="whitegrid", context="paper", font_scale=1.1)


# after tab10's ten: dark colours none of tab10's resembles (tab10 itself cycles: run 11 would be run 1's blue)
EXTRA_COLOURS = ("#000000", "#8c6d1f", "#1a1a7a", "#7a1a4a", "#2f5f2f", "#5a5a5a")


def palette(runs: list[str]) -> dict[str, tuple]:
    """One colour per run, all distinct for up to 16 runs (tab10, then :data:`EXTRA_COLOURS`)."""
    colours = [*sns.color_palette("tab10", 10), *sns.color_palette(EXTRA_COLOURS)]
    if len(runs) > len(colours):
        raise ValueError(f"{len(runs)} runs in one figure: at most {len(colours)} distinct colours")
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
