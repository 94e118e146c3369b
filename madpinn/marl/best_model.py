"""Which checkpoint of a validated MARL training run is deployed (``train-defmarl``).

:class:`BestOnValidation` gives a validation curve (:class:`madpinn.marl.training_run.Validation`)
its choice: the row whose ``score`` beats every earlier row's (:func:`mark_best`) is the deployed
model (:func:`deploy_best`). Only validated trainings import this module, so its edits rerun
those trainings alone (the SafeMARL nominal policy, never validated, deploys its last model).
"""

from __future__ import annotations

from pathlib import Path
from typing import Callable, Mapping, Sequence


class BestOnValidation:
    """Mixin of a validation curve with a ``score(row) -> key | None`` (compared with ``>``; None
    on rows without one; equal outcomes must give equal keys, no float noise)."""

    def score(self, stats: Mapping) -> tuple | None:
        raise NotImplementedError

    def best(self, history: Sequence[dict]) -> dict | None:
        """:func:`mark_best` of ``history`` under :meth:`score`."""
        return mark_best(history, self.score)

    def deploy(self, out: Path, best_path: Path, last_path: Path, *, best_iteration: int, last_iteration: int) -> None:
        """:func:`deploy_best`."""
        deploy_best(out, best_path, last_path, best_iteration=best_iteration, last_iteration=last_iteration)


def mark_best(history: Sequence[dict], score: Callable[[Mapping], tuple | None]) -> dict | None:
    """Set ``val_best`` on every validated row of ``history`` (1: its ``score`` beats every
    earlier row's) and return the last such row (the best; None without validated rows)."""
    best_key, best_row = None, None
    for row in history:
        key = score(row)
        if key is None:
            continue
        row["val_best"] = float(best_key is None or key > best_key)
        if row["val_best"]:
            best_key, best_row = key, row
    return best_row


def deploy_best(out: Path, best_path: Path, last_path: Path, *, best_iteration: int, last_iteration: int) -> None:
    """Make ``out`` (the last model, just written) the model of ``best_iteration``: keep the last
    one as ``last_path``, then copy ``best_path`` over ``out`` unless the best is the last model.
    ``best_path`` must hold that iteration (its ``meta.validation.iteration``)."""
    import shutil

    from madpinn.marl.checkpoint import CheckpointError, load_checkpoint

    shutil.copyfile(out, last_path)
    if best_iteration == last_iteration:
        return
    held = load_checkpoint(best_path)["meta"].get("validation", {}).get("iteration") if best_path.is_file() else None
    if held != best_iteration:
        raise CheckpointError(f"the validation curve's best model is iteration {best_iteration}, but {best_path} holds "
                              f"{'no model' if held is None else f'iteration {held}'}: retrain (the curve's rule changed "
                              "after that model was saved)")
    shutil.copyfile(best_path, out)
