"""A shipped model's MLflow run (``install-shipped``, rule ``install_shipped_model``): the model
as a logged, registered network, its manifest entry as params and metrics, and the training curves
of the committed training log that produced it, step-indexed.

The committed logs live under ``training/<run>/`` (resumable long trainings): a MARL policy's
``<name>_history.csv`` (one row per PPO iteration: losses, rollout figures, the ``val_*``
validation columns at the iterations that validated) and a value function's ``<kind>_loss.csv``
(one loss per iteration). A log belongs to a shipped model when its directory holds a checkpoint
with the same bytes (sha256), or, for a value function re-saved since, the same training record
(iterations, wall time, final loss in the checkpoint's metadata). Models without one (the paper's
first V̂, V_s and SafeMARL nominal, trained before their logs were kept) say so in the tag
``madpinn.training_log``.
"""

from __future__ import annotations

from pathlib import Path

from madpinn.config import REPO_ROOT

TRAINING_DIR = REPO_ROOT / "training"
LOG_PATTERNS = ("*_history.csv", "*_loss.csv")
LOSS_POINTS = 1000          # a value function's per-iteration loss: logged as ≤ this many window means
SAME_TRAINING = ("iterations", "wall_s", "final_loss")   # a value function's meta fields naming its training run


def _meta(path: Path) -> dict:
    import torch

    try:
        data = torch.load(path, map_location="cpu", weights_only=True)
    except Exception:  # noqa: BLE001 - a checkpoint of another format: no match
        return {}
    return dict(data.get("meta") or {}) if isinstance(data, dict) else {}


def training_log(model: str | Path, sha256: str, root: str | Path = TRAINING_DIR) -> Path | None:
    """The committed training log of the shipped model file ``model`` (sha256 ``sha256``): the
    ``*_history.csv`` / ``*_loss.csv`` in the directory under ``root`` holding a checkpoint of the
    same bytes, else of the same training (value functions, :data:`SAME_TRAINING`); None if none."""
    from madpinn.checksum import sha256 as file_sha256

    root = Path(root)
    if not root.is_dir():
        return None
    dirs = sorted(d for d in root.iterdir() if d.is_dir() and any(next(d.glob(p), None) for p in LOG_PATTERNS))
    found = next((d for d in dirs for pt in sorted(d.glob("*.pt")) if file_sha256(pt) == sha256), None)
    if found is None:
        meta = _meta(Path(model))
        if meta and all(meta.get(k) is not None for k in SAME_TRAINING):
            found = next((d for d in dirs for pt in sorted(d.glob("*.pt"))
                          if all(_meta(pt).get(k) == meta[k] for k in SAME_TRAINING)), None)
    if found is None:
        return None
    return next(p for pat in LOG_PATTERNS for p in sorted(found.glob(pat)))


def log_training_curves(run, log: Path) -> int:
    """Log ``log``'s curves into ``run`` (a :class:`madpinn.tracking.JobRun`), step-indexed: a
    history's every numeric column at its ``iteration``; a loss file's ``loss`` as window means
    at the window's last iteration (≤ :data:`LOSS_POINTS` points). Returns the points logged."""
    import pandas as pd

    df = pd.read_csv(log)
    points = 0
    if "iteration" in df:
        cols = [c for c in df.columns if c != "iteration" and pd.api.types.is_numeric_dtype(df[c])]
        for row in df[["iteration", *cols]].itertuples(index=False):
            values = {c: v for c, v in zip(cols, row[1:]) if pd.notna(v)}
            run.log_metrics(values, step=int(row[0]))
            points += len(values)
        return points
    every = max(1, -(-len(df) // LOSS_POINTS))
    loss = df["loss"].astype(float)
    for start in range(0, len(loss), every):
        window = loss.iloc[start:start + every]
        run.log_metrics({"loss": float(window.mean())}, step=start + len(window) - 1)
        points += 1
    return points


def manifest_metrics(entry: dict) -> dict:
    """Numeric figures of a manifest entry: ``iterations``, ``wall_s``, ``final_loss``, ``samples``
    and every numeric validation figure (``validation.<report>.<key>``, nested keys joined by ``.``)."""
    out = {k: entry[k] for k in ("iterations", "wall_s", "final_loss", "samples", "bytes")
           if isinstance(entry.get(k), (int, float)) and not isinstance(entry.get(k), bool)}

    def walk(d: dict, prefix: str) -> None:
        for k, v in d.items():
            if isinstance(v, dict):
                walk(v, f"{prefix}{k}.")
            elif isinstance(v, (int, float)) and not isinstance(v, bool):
                out[f"{prefix}{k}"] = v

    walk(entry.get("validation") or {}, "validation.")
    return out


def network(path: str | Path, name: str):
    """The shipped model as a ``torch.nn.Module``: a value function's network (as its training job
    logs it), a MARL policy's actor."""
    from madpinn.value_functions.shipping import model_kind

    kind = model_kind(name)
    if kind in ("vhat", "vs"):
        from madpinn.value_functions.model import load_value_function

        return load_value_function(path, kind).net
    from madpinn.marl.checkpoint import load_actor

    return load_actor(path)[0]
