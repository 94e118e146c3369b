"""Argument helpers shared by every sub-command (the only place that knows argparse options)."""

from __future__ import annotations

import argparse
from pathlib import Path

from madpinn.config import ConfigError, load_config


def add_config_arg(p: argparse.ArgumentParser) -> None:
    p.add_argument("--config", nargs="+", required=True, help="config file(s), later ones override earlier ones")


def add_job_args(p: argparse.ArgumentParser, threads_default: int | None = 1, progress: bool = True) -> None:
    """Options of every workflow job: thread count, progress bar, MLflow logging."""
    p.add_argument("--threads", type=int, default=threads_default,
                   help="torch threads" + (" (default value_functions.threads)" if threads_default is None else ""))
    if progress:
        p.add_argument("--no-progress", action="store_true")
    p.add_argument("--no-track", action="store_true", help="do not log to MLflow")


def add_model_arg(p: argparse.ArgumentParser, names: tuple[str, ...]) -> None:
    """``--model NAME=PATH`` (repeatable): the trained files a job reads, passed in by its rule."""
    p.add_argument("--model", action="extend", nargs="+", default=[], metavar="NAME=PATH",
                   help=f"trained model file(s) read by the job (names: {', '.join(names)}); repeatable")


def parse_models(items: list[str], flag: str = "--model") -> dict[str, Path]:
    """``["vhat=a.pt", "vs=b.pt"]`` -> ``{"vhat": Path("a.pt"), "vs": Path("b.pt")}``; errors name
    ``flag``, the option the items came from."""
    models: dict[str, Path] = {}
    for item in items:
        name, sep, path = item.partition("=")
        if not sep or not name or not path:
            raise ConfigError(f"{flag} expects NAME=PATH, got '{item}'")
        if name in models:
            raise ConfigError(f"{flag} {name}= given twice")
        models[name] = Path(path)
    return models


def single_model(items: list[str], name: str) -> Path:
    """The one model a command reads: ``--model PATH`` or ``--model NAME=PATH``."""
    if len(items) == 1 and "=" not in items[0]:
        return Path(items[0])
    models = parse_models(items)
    if name not in models:
        raise ConfigError(f"missing --model {name}=PATH")
    return models[name]


def config_of(args) -> dict:
    """The validated config of ``--config``."""
    return load_config(args.config)
