"""Hints that name the command building a missing workflow output (checkpoints, results)."""

from __future__ import annotations

from pathlib import Path


def build_hint(path: str | Path) -> str:
    """``snakemake -j2 <path>``: a missing file the workflow writes is its own Snakemake target
    (the training rules write ``<paths.results>/models/<name>.pt``). Run it in the workflow's
    directory with the ``--configfile`` options of the run that needs the file, so that
    ``paths.results`` is the same."""
    return f"build it with: snakemake -j2 {path} (plus the --configfile options of this run)"


def unreadable_reason(exc: BaseException) -> str:
    """Why ``torch.load(path, weights_only=True)`` refused a file, in plain words and on one line:
    a blocked pickle (Python objects a safe load never runs), a truncated or corrupted torch file,
    or other data. Never repeats torch's advice to load the file with ``weights_only=False``."""
    import re

    text = " ".join(str(exc).split())
    blocked = re.search(r"GLOBAL ([\w.]+)", text)
    if blocked:
        return (f"it holds pickled Python objects ({blocked.group(1)}), which a safe load (weights_only=True) "
                "refuses without running them; madpinn did not write it")
    if "Weights only load failed" in text:   # not a zip archive: a plain pickle or other bytes
        return "it is not a torch checkpoint (corrupted, or another kind of file)"
    first = re.split(r"(?<=\.)\s", text, maxsplit=1)[0] if text else type(exc).__name__
    return f"it is corrupted or truncated (an incomplete torch file: {first.rstrip('.')})"
