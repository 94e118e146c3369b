"""The shared ending of the MARL training jobs (SafeMARL nominal, DEF-MARL): train, save the
checkpoint, write the learning curve CSV and JSON summary, all in one live MLflow run (curves as
they happen, then the files and the actor)."""

from __future__ import annotations

import tempfile
import time
from pathlib import Path
from typing import Callable, Mapping, Protocol, Sequence

from madpinn.commands.args import add_config_arg, add_job_args
from madpinn.commands.finish import JobRecord, finish, job, write_json


class Validation(Protocol):
    """A validation learning curve (``train-defmarl``): every ``every`` iterations the command
    evaluates the model file it is given and may end training at a plateau."""

    every: int
    stop_at_plateau: bool

    def __call__(self, model: Path) -> dict: ...

    def plateau(self, history: Sequence[dict]) -> bool: ...

    def score(self, stats: Mapping) -> tuple | None:
        """The key the best model is selected on, compared with ``>`` (None on rows without one);
        equal outcomes must give equal keys (no float noise)."""


def train_and_record(cfg: dict, build: Callable[[], object], tcfg: Mapping, out: str | Path, *, desc: str, meta: Callable,
                     first: Sequence[str], last: Sequence[str], curves: Sequence[str], record: JobRecord,
                     extra: dict | None = None, threads: int = 1, progress: bool = True, track: bool = True,
                     checkpoint: str | Path | None = None, time_limit: float | None = None, init: str | Path | None = None,
                     resume_hash: str | None = None, validation: Validation | None = None) -> dict | None:
    """Inside ``record``'s live MLflow run (curves logged every iteration as they happen): seed
    with ``tcfg.seed``, train the trainer ``build()`` returns, save it to ``out`` with
    ``meta(trainer, wall_s)``, write ``<out>_history.csv`` and ``<out>.json``, then log the files,
    the summary and the actor (``mlflow.pytorch``); return the summary.

    Resumable training (``checkpoint``): the full trainer state is saved there (at every
    validation and when stopping) and a later call resumes from it when its ``resume_hash``
    matches (a different configuration is refused); ``time_limit`` (s) stops after the first
    iteration that ends past it, keeps the checkpoint and the curve CSV and returns None — run
    the same call again to go on. ``init``: start from a trained model without training state
    (fresh optimizers, :meth:`PPOTrainer.skip_to` its iterations). ``validation``: every
    ``validation.every`` iterations, its metrics and ``val_plateau`` join the iteration's curve
    row; with ``validation.stop_at_plateau`` training ends (completed) at the plateau. The model
    with the best ``validation.score`` so far is kept as ``<out>_best.pt`` (``val_best`` = 1 on
    its curve row), and that model is the one written to ``out`` (the deployed model; the last
    one is kept as ``<out>_last.pt``): selection on the validation seed, never on protocol seeds.
    The best row is found again from the whole curve at the end, so a finished state re-run under
    a changed ``score`` deploys what that rule picks (the last model, or ``<out>_best.pt`` when it
    holds that row's weights; anything else is an error, never a silent wrong model)."""
    import pandas as pd

    from madpinn.device import seed_everything
    from madpinn.marl.build import training_summary
    from madpinn.marl.checkpoint import save_checkpoint

    out = Path(out)
    checkpoint = Path(checkpoint) if checkpoint is not None else None
    curve_path = out.with_name(out.stem + "_history.csv")
    with job(cfg, record, track) as run, tempfile.TemporaryDirectory() as tmp:
        seed_everything(int(tcfg["seed"]), threads)
        t0 = time.perf_counter()
        trainer = build()
        wall_before = _start_state(trainer, checkpoint, init, resume_hash)
        log = live_curves(run, curves)
        for past in trainer.history:   # earlier pieces' curves: this run replaces theirs
            log(past)

        def wall() -> float:
            return wall_before + time.perf_counter() - t0

        def save_state() -> Path:
            return save_checkpoint(checkpoint, trainer, meta=meta(trainer, wall()),
                                   train_state={"config_hash": resume_hash, "wall_s": wall()})

        best_path = out.with_name(out.stem + "_best.pt")

        def on_iteration(stats: dict) -> bool:
            stop = False
            if validation is not None and validation.every > 0 and trainer.iteration % validation.every == 0:
                model = save_state() if checkpoint is not None else save_checkpoint(Path(tmp) / "model.pt", trainer, meta(trainer, wall()))
                stats.update(validation(model))
                stats["val_plateau"] = float(validation.plateau(trainer.history))
                stats["val_best"] = float(mark_best(trainer.history, validation.score) is stats)   # stats: the last row
                if stats["val_best"]:
                    save_checkpoint(best_path, trainer, meta={**meta(trainer, wall()), "validation": dict(
                        {k: v for k, v in stats.items() if k.startswith("val_")}, iteration=trainer.iteration)})
                stop = validation.stop_at_plateau and stats["val_plateau"] > 0
            log(stats)
            return stop

        deadline = None if time_limit is None else time.monotonic() + time_limit
        history = trainer.train(progress=progress, desc=desc, on_iteration=on_iteration, deadline=deadline)
        stopped_early = validation is not None and validation.stop_at_plateau and validation.plateau(history)
        if trainer.iteration < trainer.ppo.iterations and not stopped_early:   # paused by the time limit
            if checkpoint is None:
                raise RuntimeError("a time-limited training needs a checkpoint to resume from")
            save_state()
            pd.DataFrame(history).to_csv(curve_path, index=False)
            run.log_params({"completed": False})
            print(f"{desc}: paused after iteration {trainer.iteration} of {trainer.ppo.iterations}; "
                  f"state in {checkpoint}; run the same command again to resume")
            return None
        if checkpoint is not None:
            save_state()   # kept: a larger ppo.iterations continues from here
        w = wall()
        save_checkpoint(out, trainer, meta=meta(trainer, w))
        summary = training_summary(history, w, first, last, extra=extra)
        if stopped_early:
            summary["stopped_at_plateau"] = trainer.iteration
        best = mark_best(history, validation.score) if validation is not None else None
        last_path = out.with_name(out.stem + "_last.pt")
        summary["deployed_iteration"] = trainer.iteration if best is None else int(best["iteration"]) + 1
        if best is not None:
            summary["best_validation"] = {k: v for k, v in best.items() if k.startswith("val_") or k == "iteration"}
            deploy_best(out, best_path, last_path, best_iteration=summary["deployed_iteration"], last_iteration=trainer.iteration)
        pd.DataFrame(history).to_csv(curve_path, index=False)
        json_path = write_json(out.with_suffix(".json"), summary)
        record.artifacts = [out, curve_path, json_path, *[p for p in (best_path, last_path) if p.is_file()]]
        record.metrics = {k: v for k, v in summary.items() if k not in (extra or {})}
        record.step = len(history)
        record.models = {"actor": trainer.actor}
        finish(run, record, echo=summary)
    return summary


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


def _start_state(trainer, checkpoint: Path | None, init: str | Path | None, resume_hash: str | None) -> float:
    """Resume ``trainer`` from ``checkpoint`` (if the file exists) or initialise it from ``init``;
    return the wall seconds of the earlier pieces."""
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
        return float(ck["meta"].get("wall_s", 0.0))
    return 0.0


def live_curves(run, keys: Sequence[str]) -> Callable[[dict], None]:
    """``on_iteration`` callback of a PPO trainer: the iteration's ``keys`` as step metrics."""
    return lambda stats: run.log_metrics({k: stats[k] for k in keys if k in stats}, step=int(stats["iteration"]))


def add_training_parser(sub, name: str, help: str, func, variant: bool = False):
    """Sub-command ``name`` of a MARL training job: ``--config``, [``--variant``], ``--out``, job options."""
    p = sub.add_parser(name, help=help)
    add_config_arg(p)
    if variant:
        p.add_argument("--variant", required=True, help="variant of methods.defmarl (e.g. n3, n8)")
    p.add_argument("--out", required=True, help="checkpoint path (.pt)")
    add_job_args(p)
    p.set_defaults(func=func)
    return p
