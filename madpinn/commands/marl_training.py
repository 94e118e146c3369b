"""The shared ending of the MARL training jobs (SafeMARL nominal, DEF-MARL): the library's
training run (:class:`madpinn.marl.training_run.TrainingRun`: training, checkpoint choice, files)
inside one live MLflow run (curves as they happen, then the files and the actor)."""

from __future__ import annotations

from typing import TYPE_CHECKING, Callable, Sequence

from madpinn.commands.args import add_config_arg, add_job_args
from madpinn.commands.finish import JobRecord, finish, job

if TYPE_CHECKING:
    from madpinn.marl.training_run import TrainingRun


def train_and_record(cfg: dict, training: "TrainingRun", curves: Sequence[str], record: JobRecord,
                     track: bool = True) -> dict | None:
    """Run ``training`` inside ``record``'s live MLflow run (the ``curves`` keys of every curve row
    logged as they happen), then log its files, summary and actor; return the summary, or None
    when its time limit paused it (the run is marked not completed)."""
    with job(cfg, record, track) as run:
        result = training.run(live_curves(run, curves))
        if result is None:
            run.log_params({"completed": False})
            return None
        extra = training.extra or {}
        record.artifacts = result.files
        record.metrics = {k: v for k, v in result.summary.items() if k not in extra}
        record.step = result.summary["iterations"]   # the curve's length
        record.models = {"actor": result.trainer.actor}
        record.register = {"actor": record.job_key.rpartition("/")[2]}   # safemarl_nominal, defmarl_<variant>
        finish(run, record, echo=result.summary)
    return result.summary


def live_curves(run, keys: Sequence[str]) -> Callable[[dict], None]:
    """``on_iteration`` callback of a PPO trainer: the iteration's ``keys`` as step metrics."""
    return lambda stats: run.log_metrics({k: stats[k] for k in keys if k in stats}, step=int(stats["iteration"]))


def add_training_parser(sub, name: str, help: str, func, reads, variant: bool = False):
    """Sub-command ``name`` of a MARL training job: ``--config``, [``--variant``], ``--out``, job
    options; ``reads``: what its jobs read of the config (:mod:`madpinn.commands.reads`)."""
    p = sub.add_parser(name, help=help)
    add_config_arg(p)
    if variant:
        p.add_argument("--variant", required=True, help="variant of methods.defmarl (e.g. n3, n8)")
    p.add_argument("--out", required=True, help="checkpoint path (.pt)")
    add_job_args(p)
    p.set_defaults(func=func, reads=reads)
    return p
