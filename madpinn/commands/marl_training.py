"""The shared ending of the MARL training jobs (SafeMARL nominal, DEF-MARL): train, save the
checkpoint, write the learning curve CSV and JSON summary, then one MLflow run with the curves."""

from __future__ import annotations

import time
from pathlib import Path
from typing import Callable, Mapping, Sequence

from madpinn.commands.args import add_config_arg, add_job_args
from madpinn.commands.finish import JobRecord, finish, write_json


def train_and_record(cfg: dict, build: Callable[[], object], tcfg: Mapping, out: str | Path, *, desc: str, meta: Callable,
                     first: Sequence[str], last: Sequence[str], curves: Sequence[str], record: JobRecord,
                     extra: dict | None = None, threads: int = 1, progress: bool = True, track: bool = True) -> dict:
    """Seed with ``tcfg.seed``, train the trainer ``build()`` returns, save it to ``out`` with
    ``meta(trainer, wall_s)``, write ``<out>_history.csv`` and ``<out>.json``, then log ``record``
    (artifacts, metrics and curves filled in here); return the summary."""
    import pandas as pd

    from madpinn.device import seed_everything
    from madpinn.marl.build import training_summary
    from madpinn.marl.checkpoint import save_checkpoint

    out = Path(out)
    seed_everything(int(tcfg["seed"]), threads)
    t0 = time.perf_counter()
    trainer = build()
    history = trainer.train(progress=progress, desc=desc)
    wall = time.perf_counter() - t0
    save_checkpoint(out, trainer, meta=meta(trainer, wall))
    summary = training_summary(history, wall, first, last, extra=extra)
    curve_path = out.with_name(out.stem + "_history.csv")
    pd.DataFrame(history).to_csv(curve_path, index=False)
    json_path = write_json(out.with_suffix(".json"), summary)
    record.artifacts = [out, curve_path, json_path]
    record.metrics = {k: v for k, v in summary.items() if k not in (extra or {})}
    record.step_metrics = {k: [h[k] for h in history] for k in curves}
    finish(cfg, record, track, echo=summary)
    return summary


def add_training_parser(sub, name: str, help: str, func, variant: bool = False) -> None:
    """Sub-command ``name`` of a MARL training job: ``--config``, [``--variant``], ``--out``, job options."""
    p = sub.add_parser(name, help=help)
    add_config_arg(p)
    if variant:
        p.add_argument("--variant", required=True, help="variant of methods.defmarl (e.g. n3, n8)")
    p.add_argument("--out", required=True, help="checkpoint path (.pt)")
    add_job_args(p)
    p.set_defaults(func=func)
