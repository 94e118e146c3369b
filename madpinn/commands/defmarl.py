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
import random
import sys
from dataclasses import asdict, replace
from pathlib import Path
from typing import Sequence

from madpinn.commands.args import config_of
from madpinn.commands.finish import JobRecord
from madpinn.commands.marl_training import add_training_parser, train_and_record

EXIT_PAUSED = 75   # as train-value: the time limit stopped a piece, the checkpoint is kept


def resume_hash(cfg: dict, variant: str) -> str:
    """The training hash of ``defmarl_<variant>`` with ``ppo.iterations`` and the validation
    settings left out: a resumable checkpoint continues when only the iteration budget grew or
    the validation changed (validating restores the RNG states, so it never changes the training
    trajectory; it only chooses the deployed checkpoint)."""
    from madpinn.marl_hash import marl_training_hash

    c = copy.deepcopy(cfg)
    c["methods"]["defmarl"]["training"]["ppo"]["iterations"] = 0
    c["methods"]["defmarl"].pop("validation", None)
    for v in c["methods"]["defmarl"].get("variants", {}).values():
        v.get("training", {}).get("ppo", {}).pop("iterations", None)
        v.pop("validation", None)
    return marl_training_hash(c, f"defmarl_{variant}")


class CellValidation:
    """Validation curve of run ``defmarl-<variant>``: the evaluation cells (``run_cell``, the
    study's cell settings with ``scenarios`` replaced) at the training and extra agent counts on
    the validation seed; adds ``val_safety_n<N>`` (%), ``val_safe_scenarios_n<N>`` (%),
    ``val_cost_n<N>`` and ``val_plateau`` to the iteration's curve row. The global RNG states are
    restored afterwards, so validating does not change the trained weights."""

    def __init__(self, cfg: dict, run: str, training_counts: Sequence[int], threads: int):
        from madpinn.config import method_config
        from madpinn.evaluation.cell import CellSettings
        from madpinn.marl.validation import ValidationSettings

        _, mcfg = method_config(cfg, run)
        self.settings = ValidationSettings.from_config(mcfg["validation"])
        s = self.settings
        self.every = s.every
        self.cell = replace(CellSettings.from_config(cfg, s.study, run), scenarios=s.scenarios)
        self.train_n = int(training_counts[0])
        self.counts = s.counts(training_counts)
        self.threads = threads
        self.stop_at_plateau = s.stop and s.every > 0

    def __call__(self, model: Path) -> dict:
        import numpy as np
        import torch

        from madpinn.evaluation.cell import run_cell

        states = (torch.get_rng_state(), np.random.get_state(), random.getstate())
        try:
            out = {}
            for n in self.counts:
                s = run_cell(self.cell, n, self.settings.seed, models={"policy": model}, backend=self.settings.backend,
                             threads=self.threads, progress=False).summary
                out.update({f"val_safety_n{n}": 100.0 * s["safety_rate"], f"val_safe_scenarios_n{n}": 100.0 * s["safe_scenarios"],
                            f"val_cost_n{n}": s["cost"]})
        finally:
            torch.set_rng_state(states[0])
            np.random.set_state(states[1])
            random.setstate(states[2])
        print(" ".join(f"{k}={v:.4g}" for k, v in out.items()), flush=True)
        return out

    def plateau(self, history: Sequence[dict]) -> bool:
        """The plateau rule (:func:`madpinn.marl.validation.plateau`) on the safety curve at the
        first training agent count."""
        from madpinn.marl.validation import plateau

        key = f"val_safety_n{self.train_n}"
        curve = [h[key] for h in history if key in h]
        return plateau(curve, self.settings.window, self.settings.min_gain)

    def score(self, stats) -> tuple[float, float] | None:
        """The best model's criterion: validation safety (%) at the first training agent count,
        rounded to 1e-6 so that equal outcome counts tie exactly (raw floats differ by rounding),
        then, on a tie, the mean validation safety at the other agent counts (generalisation)."""
        s = stats.get(f"val_safety_n{self.train_n}")
        if s is None or s != s:
            return None
        others = [stats[k] for k in (f"val_safety_n{n}" for n in self.counts if n != self.train_n) if k in stats]
        return round(float(s), 6), (round(sum(map(float, others)) / len(others), 6) if others else 0.0)

    def curves(self) -> tuple[str, ...]:
        return tuple(f"val_{m}_n{n}" for n in self.counts for m in ("safety", "safe_scenarios", "cost")) + (
            "val_plateau", "val_best")


def train_defmarl(cfg: dict, variant: str, out: str | Path, threads: int = 1, progress: bool = True, track: bool = True,
                  checkpoint: str | Path | None = None, time_limit: float | None = None,
                  init: str | Path | None = None) -> dict | None:
    """Train (or resume, or continue ``init``) model ``defmarl-<variant>``; the summary, or None
    when ``time_limit`` paused it (state kept in ``checkpoint``)."""
    from madpinn.config import ConfigError, method_config
    from madpinn.marl.defmarl.build import DEFMARL_CURVES, SUMMARY_KEYS, build_defmarl_trainer

    if "defmarl" not in cfg["methods"]:
        raise ConfigError("methods.defmarl is not configured")
    if time_limit is not None and checkpoint is None:
        raise ConfigError("--time-limit needs --checkpoint (the state the next piece resumes from)")
    run = f"defmarl-{variant}"
    _, mcfg = method_config(cfg, run)
    tcfg = mcfg["training"]
    if init is not None and not (checkpoint is not None and Path(checkpoint).is_file()):   # read only to start
        _check_init(init, mcfg)
    validation = CellValidation(cfg, run, tcfg["agent_counts"], threads) if "validation" in mcfg else None
    curves = DEFMARL_CURVES + (validation.curves() if validation is not None else ())
    return train_and_record(
        cfg, lambda: build_defmarl_trainer(cfg, run)[0], tcfg, out, desc=f"DEF-MARL ({variant})",
        meta=lambda trainer, wall: {"method": "defmarl", "variant": variant, "epigraph": asdict(trainer.epi), "wall_s": wall,
                                    "arena": tcfg["arena"], "agent_counts": list(tcfg["agent_counts"]),
                                    **({"init_from": str(init)} if init is not None else {})},
        first=SUMMARY_KEYS, last=SUMMARY_KEYS, curves=curves, extra={"run": run},
        record=JobRecord(job_key=f"train/defmarl_{variant}", rule="train_defmarl", wildcards={"variant": variant},
                         params={"training": tcfg, "epigraph": mcfg["epigraph"], "agents": cfg["agents"],
                                 "observation": cfg["observation"], "validation": mcfg.get("validation")}),
        threads=threads, progress=progress, track=track, checkpoint=checkpoint, time_limit=time_limit, init=init,
        resume_hash=resume_hash(cfg, variant), validation=validation,
    )


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

    p = add_training_parser(sub, "train-defmarl", "train one DEF-MARL model (epigraph-form MARL)", _train, variant=True)
    p.add_argument("--checkpoint", default=None,
                   help="resumable training state: saved at every validation and when stopping, resumed when it exists")
    p.add_argument("--time-limit", type=_seconds, default=None, metavar="SECONDS",
                   help=f"stop after the first iteration that ends past this many seconds, keep --checkpoint and exit "
                        f"{EXIT_PAUSED}: long trainings as time-boxed pieces (docs/defmarl.md)")
    p.add_argument("--init", default=None, metavar="PATH",
                   help="continue this trained DEF-MARL model (weights, normalisers; fresh optimizers) up to ppo.iterations")
