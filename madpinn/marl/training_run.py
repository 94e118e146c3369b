"""One MARL training run (SafeMARL nominal, DEF-MARL) from start to deployed checkpoint.

:class:`TrainingRun` seeds, builds the trainer, resumes it from its checkpoint or continues a
trained model, trains (optionally in time-boxed pieces), evaluates its validation curve, keeps
the best model and deploys it (the validation's choice: :mod:`madpinn.marl.best_model`, which
only validated trainings import), then writes the checkpoint, the learning curve CSV and the
JSON summary. The command layer (``madpinn/commands/marl_training.py``) only wraps it in the
job's live MLflow run: every line that decides which weights are written is in the training
jobs' source hash.

A written model holds only what its weights are a function of (settings, iterations, seed); the
run's wall time is in the summary JSON beside it, so identical weights give an identical file.
"""

from __future__ import annotations

import json
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Mapping, Protocol, Sequence


class Validation(Protocol):
    """A validation learning curve (``train-defmarl``): every ``every`` iterations it evaluates the
    model file it is given and may end training at a plateau."""

    every: int
    stop_at_plateau: bool

    def __call__(self, model: Path) -> dict: ...

    def plateau(self, history: Sequence[dict]) -> bool: ...

    def best(self, history: Sequence[dict]) -> dict | None:
        """Mark the best rows of ``history`` (``val_best``) and return the best one, None without
        validated rows (:class:`madpinn.marl.best_model.BestOnValidation`)."""

    def deploy(self, out: Path, best_path: Path, last_path: Path, *, best_iteration: int, last_iteration: int) -> None:
        """Make ``out`` the model of ``best_iteration`` (:func:`madpinn.marl.best_model.deploy_best`)."""


@dataclass(frozen=True)
class TrainingResult:
    """A finished run: its summary (also written as ``<out>.json``), the files written and the
    trained trainer (its ``actor`` is logged; ``len(history)`` is the last step)."""

    summary: dict
    files: list[Path]
    trainer: object


@dataclass(frozen=True)
class TrainingRun:
    """A MARL training job's settings: see :meth:`run`."""

    build: Callable[[], object]
    """returns the trainer (a :class:`madpinn.marl.trainer.PPOTrainer`)"""
    seed: int
    """seed of every RNG before the trainer is built"""
    out: Path
    """the deployed checkpoint (.pt); ``<out>_history.csv``, ``<out>.json`` beside it"""
    desc: str
    """progress-bar and message label"""
    meta: Callable[[object], dict]
    """``meta(trainer)``: the checkpoint's metadata besides the trainer's own"""
    first: Sequence[str]
    """curve keys whose first value the summary reports"""
    last: Sequence[str]
    """curve keys whose mean over the last 10 iterations the summary reports"""
    extra: dict | None = None
    """summary entries given as is"""
    threads: int = 1
    progress: bool = True
    checkpoint: Path | None = None
    """resumable training state (saved at every validation and when stopping)"""
    time_limit: float | None = None
    """seconds: stop after the first iteration that ends past it (needs ``checkpoint``)"""
    init: Path | None = None
    """a trained model without training state to continue"""
    resume_hash: str | None = None
    """the configuration a ``checkpoint`` must have been written with"""
    validation: Validation | None = None

    def run(self, log: Callable[[dict], None]) -> TrainingResult | None:
        """Seed, build and train, calling ``log(row)`` with every curve row (earlier pieces' rows
        first); save the trainer to ``out`` and write ``<out>_history.csv`` and ``<out>.json``.

        Resumable training (``checkpoint``): the full trainer state is saved there (at every
        validation and when stopping) and a later run resumes from it when its ``resume_hash``
        matches (a different configuration is refused); ``time_limit`` (s) stops after the first
        iteration that ends past it, keeps the checkpoint and the curve CSV and returns None — run
        again to go on. ``init``: start from a trained model without training state (fresh
        optimizers, :meth:`PPOTrainer.skip_to` its iterations). ``validation``: every
        ``validation.every`` iterations, its metrics and ``val_plateau`` join the iteration's
        curve row; with ``validation.stop_at_plateau`` training ends (completed) at the plateau.
        The model with the best ``validation.best`` row so far is kept as ``<out>_best.pt``
        (``val_best`` = 1 on its curve row), and that model is the one written to ``out`` (the
        deployed model; the last one is kept as ``<out>_last.pt``): selection on the validation
        seed, never on protocol seeds. The best row is found again from the whole curve at the
        end, so a finished state re-run under a changed rule deploys what that rule picks
        (the last model, or ``<out>_best.pt`` when it holds that row's weights; anything else is
        an error, never a silent wrong model)."""
        import pandas as pd

        from madpinn.device import seed_everything
        from madpinn.marl.build import training_summary
        from madpinn.marl.checkpoint import save_checkpoint

        out, checkpoint, validation = Path(self.out), self.checkpoint and Path(self.checkpoint), self.validation
        curve_path = out.with_name(out.stem + "_history.csv")
        best_path = out.with_name(out.stem + "_best.pt")
        with tempfile.TemporaryDirectory() as tmp:
            seed_everything(int(self.seed), self.threads)
            t0 = time.perf_counter()
            trainer = self.build()
            wall_before = start_state(trainer, checkpoint, self.init, self.resume_hash)
            for past in trainer.history:   # earlier pieces' curves
                log(past)

            def wall() -> float:
                return wall_before + time.perf_counter() - t0

            def save_state() -> Path:
                return save_checkpoint(checkpoint, trainer, meta=self.meta(trainer),
                                       train_state={"config_hash": self.resume_hash, "wall_s": wall()})

            def on_iteration(stats: dict) -> bool:
                stop = False
                if validation is not None and validation.every > 0 and trainer.iteration % validation.every == 0:
                    model = save_state() if checkpoint is not None else save_checkpoint(Path(tmp) / "model.pt", trainer,
                                                                                         self.meta(trainer))
                    stats.update(validation(model))
                    stats["val_plateau"] = float(validation.plateau(trainer.history))
                    stats["val_best"] = float(validation.best(trainer.history) is stats)   # stats: the last row
                    if stats["val_best"]:
                        save_checkpoint(best_path, trainer, meta={**self.meta(trainer), "validation": dict(
                            {k: v for k, v in stats.items() if k.startswith("val_")}, iteration=trainer.iteration)})
                    stop = validation.stop_at_plateau and stats["val_plateau"] > 0
                log(stats)
                return stop

            deadline = None if self.time_limit is None else time.monotonic() + self.time_limit
            history = trainer.train(progress=self.progress, desc=self.desc, on_iteration=on_iteration, deadline=deadline)
        stopped_early = validation is not None and validation.stop_at_plateau and validation.plateau(history)
        if trainer.iteration < trainer.ppo.iterations and not stopped_early:   # paused by the time limit
            if checkpoint is None:
                raise RuntimeError("a time-limited training needs a checkpoint to resume from")
            save_state()
            pd.DataFrame(history).to_csv(curve_path, index=False)
            print(f"{self.desc}: paused after iteration {trainer.iteration} of {trainer.ppo.iterations}; "
                  f"state in {checkpoint}; run the same command again to resume")
            return None
        if checkpoint is not None:
            save_state()   # kept: a larger ppo.iterations continues from here
        w = wall()
        save_checkpoint(out, trainer, meta=self.meta(trainer))
        summary = training_summary(history, w, self.first, self.last, extra=self.extra)
        if stopped_early:
            summary["stopped_at_plateau"] = trainer.iteration
        best = validation.best(history) if validation is not None else None
        last_path = out.with_name(out.stem + "_last.pt")
        summary["deployed_iteration"] = trainer.iteration if best is None else int(best["iteration"]) + 1
        if best is not None:
            summary["best_validation"] = {k: v for k, v in best.items() if k.startswith("val_") or k == "iteration"}
            validation.deploy(out, best_path, last_path, best_iteration=summary["deployed_iteration"], last_iteration=trainer.iteration)
        pd.DataFrame(history).to_csv(curve_path, index=False)
        json_path = out.with_suffix(".json")
        json_path.write_text(json.dumps(summary, indent=2))
        files = [out, curve_path, json_path, *[p for p in (best_path, last_path) if p.is_file()]]
        return TrainingResult(summary, files, trainer)


def start_state(trainer, checkpoint: Path | None, init: str | Path | None, resume_hash: str | None) -> float:
    """Resume ``trainer`` from ``checkpoint`` (if the file exists) or initialise it from ``init``;
    return the wall seconds of the earlier pieces (an ``init`` model's from its summary JSON, or
    from its own metadata in checkpoints written before the wall time left them)."""
    from madpinn.marl.checkpoint import CheckpointError, load_checkpoint, restore_modules

    if checkpoint is not None and checkpoint.is_file():
        ck = load_checkpoint(checkpoint, trainer.device)
        state = ck.get("train_state")
        if state is None:
            raise CheckpointError(f"{checkpoint} holds no training state (a finished model?); pass it as --init instead")
        if state.get("config_hash") != resume_hash:
            raise CheckpointError(f"{checkpoint} was trained with another configuration (hash {state.get('config_hash')}, "
                                  f"now {resume_hash}); use another --checkpoint or the configuration it was trained with")
        restore_modules(trainer, ck, checkpoint)
        trainer.load_training_state(state)
        print(f"resuming from {checkpoint} at iteration {trainer.iteration}")
        return float(state["wall_s"])
    if init is not None:
        ck = load_checkpoint(init, trainer.device)
        restore_modules(trainer, ck, init)
        done = int(ck["meta"].get("iterations", 0))
        if done >= trainer.ppo.iterations:
            raise CheckpointError(f"{init} was trained for {done} iterations, the configuration asks for "
                                  f"{trainer.ppo.iterations}: raise the iterations to continue it")
        trainer.skip_to(done)
        print(f"continuing {init} from iteration {done} (its optimizer state is not stored: fresh Adam moments)")
        return float(ck["meta"].get("wall_s", _summary_wall(Path(init))))
    return 0.0


def _summary_wall(model: Path) -> float:
    """The wall seconds in a trained model's summary JSON (``<model>.json``), 0 without one."""
    try:
        return float(json.loads(model.with_suffix(".json").read_text()).get("wall_s", 0.0))
    except (OSError, ValueError, TypeError, AttributeError):
        return 0.0
