"""The shared ending of the MARL training jobs (SafeMARL nominal, DEF-MARL): train, save the
checkpoint, write the learning curve CSV and JSON summary, all in one live MLflow run (curves as
they happen, then the files and the actor)."""

from __future__ import annotations

import time
from pathlib import Path
from typing import Callable, Mapping, Sequence

from madpinn.commands.args import add_config_arg, add_job_args
from madpinn.commands.finish import JobRecord, finish, job, write_json


def train_and_record(cfg: dict, build: Callable[[], object], tcfg: Mapping, out: str | Path, *, desc: str, meta: Callable,
                     first: Sequence[str], last: Sequence[str], curves: Sequence[str], record: JobRecord,
                     extra: dict | None = None, threads: int = 1, progress: bool = True, track: bool = True) -> dict:
    """Inside ``record``'s live MLflow run (curves logged every iteration as they happen): seed
    with ``tcfg.seed``, train the trainer ``build()`` returns, save it to ``out`` with
    ``meta(trainer, wall_s)``, write ``<out>_history.csv`` and ``<out>.json``, then log the files,
    the summary and the actor (``mlflow.pytorch``); return the summary."""
    import pandas as pd

    from madpinn.device import seed_everything
    from madpinn.marl.build import training_summary
    from madpinn.marl.checkpoint import save_checkpoint

    out = Path(out)
    with job(cfg, record, track) as run:
        seed_everything(int(tcfg["seed"]), threads)
        t0 = time.perf_counter()
        trainer = build()
        history = trainer.train(progress=progress, desc=desc, on_iteration=live_curves(run, curves))
        wall = time.perf_counter() - t0
        save_checkpoint(out, trainer, meta=meta(trainer, wall))
        summary = training_summary(history, wall, first, last, extra=extra)
        curve_path = out.with_name(out.stem + "_history.csv")
        pd.DataFrame(history).to_csv(curve_path, index=False)
        json_path = write_json(out.with_suffix(".json"), summary)
        record.artifacts = [out, curve_path, json_path]
        record.metrics = {k: v for k, v in summary.items() if k not in (extra or {})}
        record.step = len(history)
        record.models = {"actor": trainer.actor}
        finish(run, record, echo=summary)
    return summary


def live_curves(run, keys: Sequence[str]) -> Callable[[dict], None]:
    """``on_iteration`` callback of a PPO trainer: the iteration's ``keys`` as step metrics."""
    return lambda stats: run.log_metrics({k: stats[k] for k in keys if k in stats}, step=int(stats["iteration"]))


def add_training_parser(sub, name: str, help: str, func, variant: bool = False) -> None:
    """Sub-command ``name`` of a MARL training job: ``--config``, [``--variant``], ``--out``, job options."""
    p = sub.add_parser(name, help=help)
    add_config_arg(p)
    if variant:
        p.add_argument("--variant", required=True, help="variant of methods.defmarl (e.g. n3, n8)")
    p.add_argument("--out", required=True, help="checkpoint path (.pt)")
    add_job_args(p)
    p.set_defaults(func=func)
