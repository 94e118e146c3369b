"""``train-defmarl``: one DEF-MARL model (``methods.defmarl`` merged with a variant).

One live MLflow run: learning curves, constraint-violation rates and z statistics logged per
iteration as they happen, and every ``methods.defmarl.validation.every`` iterations the
validation safety and cost of the current policy (evaluation cells on a validation seed); files
first — checkpoint, learning-curve CSV, JSON summary — then the files and the actor
(``mlflow.pytorch``). ``--checkpoint`` / ``--time-limit`` train in resumable, time-boxed pieces
(exit 75 = paused); ``--init`` continues a trained model that has no training state.
"""

from __future__ import annotations

import copy
import sys
from dataclasses import asdict
from pathlib import Path

from madpinn.commands.args import config_of
from madpinn.commands.finish import JobRecord
from madpinn.commands.marl_training import add_training_parser, train_and_record
from madpinn.commands.reads import marl

EXIT_PAUSED = 75   # as train-value: the time limit stopped a piece, the checkpoint is kept


def resume_hash(cfg: dict, variant: str) -> str:
    """The training hash of ``defmarl_<variant>`` with ``ppo.iterations`` and the validation
    settings left out: a resumable checkpoint continues when only the iteration budget grew or
    the validation changed (validating restores the RNG states, so it never changes the training
    trajectory; it only chooses the deployed checkpoint)."""
    from madpinn.marl_hash import marl_training_hash

    c = copy.deepcopy(cfg)
    c["methods"]["defmarl"]["training"]["ppo"]["iterations"] = 0
    c["methods"]["defmarl"]["validation"] = None
    for v in c["methods"]["defmarl"]["variants"].values():   # overlays: a variant may set its own iterations
        if "ppo" in (v.get("training") or {}):
            v["training"]["ppo"].pop("iterations", None)
    return marl_training_hash(c, f"defmarl_{variant}")


def train_defmarl(cfg: dict, variant: str, out: str | Path, threads: int = 1, progress: bool = True, track: bool = True,
                  checkpoint: str | Path | None = None, time_limit: float | None = None,
                  init: str | Path | None = None) -> dict | None:
    """Train (or resume, or continue ``init``) model ``defmarl-<variant>``; the summary, or None
    when ``time_limit`` paused it (state kept in ``checkpoint``)."""
    from madpinn.config import ConfigError, method_config
    from madpinn.marl.defmarl.build import DEFMARL_CURVES, SUMMARY_KEYS, build_defmarl_trainer
    from madpinn.evaluation.marl_validation import CellValidation
    from madpinn.marl.training_run import TrainingRun

    if "defmarl" not in cfg["methods"]:
        raise ConfigError("methods.defmarl is not configured")
    if time_limit is not None and checkpoint is None:
        raise ConfigError("--time-limit needs --checkpoint (the state the next piece resumes from)")
    run = f"defmarl-{variant}"
    _, mcfg = method_config(cfg, run)
    tcfg = mcfg["training"]
    if init is not None and not (checkpoint is not None and Path(checkpoint).is_file()):   # read only to start
        _check_init(init, mcfg)
    validation = CellValidation(cfg, run, tcfg["agent_counts"], threads) if mcfg["validation"] is not None else None
    curves = DEFMARL_CURVES + (validation.curves() if validation is not None else ())
    training = TrainingRun(
        build=lambda: build_defmarl_trainer(cfg, run)[0], seed=int(tcfg["seed"]), out=Path(out), desc=f"DEF-MARL ({variant})",
        meta=lambda trainer: {"method": "defmarl", "variant": variant, "epigraph": asdict(trainer.epi),
                              "arena": tcfg["arena"], "agent_counts": list(tcfg["agent_counts"]),
                              **({"init_from": str(init)} if init is not None else {})},
        first=SUMMARY_KEYS, last=SUMMARY_KEYS, extra={"run": run}, threads=threads, progress=progress,
        checkpoint=None if checkpoint is None else Path(checkpoint), time_limit=time_limit,
        init=None if init is None else Path(init), resume_hash=resume_hash(cfg, variant), validation=validation)
    return train_and_record(
        cfg, training, curves,
        JobRecord(job_key=f"train/defmarl_{variant}", rule="train_defmarl", wildcards={"variant": variant},
                  params={"training": tcfg, "epigraph": mcfg["epigraph"], "agents": cfg["agents"],
                          "observation": cfg["observation"], "validation": mcfg["validation"]}),
        track=track)


def _check_init(init: str | Path, mcfg: dict) -> None:
    """An ``--init`` model must be a DEF-MARL model of the same epigraph settings (z range, h)."""
    from madpinn.marl.checkpoint import CheckpointError, load_checkpoint
    from madpinn.marl.defmarl.epigraph import EpigraphSettings

    meta = load_checkpoint(init)["meta"]
    if meta.get("method") != "defmarl":
        raise CheckpointError(f"--init {init} is not a DEF-MARL model (method {meta.get('method')!r})")
    want = asdict(EpigraphSettings.from_config(mcfg["epigraph"]))
    if meta.get("epigraph") != want:
        raise CheckpointError(f"--init {init} was trained with epigraph settings {meta.get('epigraph')}, the config has {want}")


def _train(args) -> int:
    if args.time_limit is not None and args.checkpoint is None:
        print("madpinn: train-defmarl --time-limit needs --checkpoint (the state the next piece resumes from)", file=sys.stderr)
        return 2
    summary = train_defmarl(config_of(args), args.variant, args.out, threads=args.threads, progress=not args.no_progress,
                            track=not args.no_track, checkpoint=args.checkpoint, time_limit=args.time_limit, init=args.init)
    return EXIT_PAUSED if summary is None else 0


def register(sub) -> None:
    from madpinn.commands.value_functions import _seconds

    p = add_training_parser(sub, "train-defmarl", "train one DEF-MARL model (epigraph-form MARL)", _train,
                            reads=lambda cfg, variant: marl(cfg, f"defmarl_{variant}"), variant=True)
    p.add_argument("--checkpoint", default=None,
                   help="resumable training state: saved at every validation and when stopping, resumed when it exists")
    p.add_argument("--time-limit", type=_seconds, default=None, metavar="SECONDS",
                   help=f"stop after the first iteration that ends past this many seconds, keep --checkpoint and exit "
                        f"{EXIT_PAUSED}: long trainings as time-boxed pieces (docs/reference/defmarl.md)")
    p.add_argument("--init", default=None, metavar="PATH",
                   help="continue this trained DEF-MARL model (weights, normalisers; fresh optimizers) up to ppo.iterations")
