"""Command layer: ``python -m madpinn <command>`` (also ``madpinn <command>``).

The only part of the package that knows the command line and the raw config dict's journey
to jobs. Each module in :data:`_MODULES` is one job family and exposes
``register(subparsers)``, adding sub-commands with ``func=handler(args) -> int``. Every job
validates its config first, calls the library with paths and settings, writes its result
files, and ends with :func:`madpinn.commands.finish.finish` (files first, then MLflow).
Expected errors print one line (see :mod:`madpinn.commands.errors`); ``--debug`` shows the
traceback.
"""

from __future__ import annotations

import argparse
import functools
import importlib
from typing import Mapping

from madpinn.commands.errors import debug_requested, run_reporting

_MODULES = {   # job family -> its module (a plugin registry: a job's hash follows its own handler only)
    "setup": "madpinn.commands.setup",  # validate-config, tracking-init
    "evaluate": "madpinn.commands.evaluate",  # evaluate
    "cell_runs": "madpinn.commands.cell_runs",  # track-cells
    "outputs": "madpinn.commands.outputs",  # table, figure, oracle, reproduction
    "value_functions": "madpinn.commands.value_functions",  # train-value, validate-vs, validate-vhat, fig-value-heatmap,
    #                       solve-vs-grid, validate-vs-grid, verify-vhat, ship-models, install-shipped
    "mujoco": "madpinn.commands.mujoco",  # render-clip
    "safemarl": "madpinn.commands.safemarl",  # train-safemarl-nominal
    "defmarl": "madpinn.commands.defmarl",  # train-defmarl
    "gap": "madpinn.commands.gap",  # gap-decomposition
    "agent_models": "madpinn.commands.agent_models",  # agent-models
    "timing": "madpinn.commands.timing",  # neighbour-timing
}
COMMAND_MODULES = tuple(_MODULES.values())
"""the command modules, each exposing ``register(subparsers)``"""


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="madpinn", description=__doc__.splitlines()[0])
    parser.add_argument("--debug", action="store_true", help="show the traceback of expected errors (also MADPINN_DEBUG=1)")
    sub = parser.add_subparsers(dest="command", required=True)
    for name in COMMAND_MODULES:
        importlib.import_module(name).register(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    import sys

    argv = list(sys.argv[1:] if argv is None else argv)
    debug = debug_requested(argv)
    args = build_parser().parse_args([a for a in argv if a != "--debug"])
    return run_reporting(lambda: args.func(args), debug)


def handler_entry(command: str) -> str:
    """``module:function`` of the handler that ``python -m madpinn <command>`` runs: the entry of
    the job's code for :func:`madpinn.provenance.source_hash` (the workflow's ``source`` params)."""
    handlers = _handlers()
    if command not in handlers:
        raise ValueError(f"unknown command '{command}' (have {sorted(handlers)})")
    return handlers[command]


def command_reads() -> dict:
    """command -> ``reads(cfg, **job)``: what its jobs read of the config, as each command declares
    it beside its parser (:mod:`madpinn.commands.reads`); commands that produce no result
    (``validate-config``, ``ship-models``, ...) declare none."""
    return {name: p.get_default("reads") for name, p in _subparsers().items() if p.get_default("reads") is not None}


def job_settings(cfg: Mapping, command: str, **job) -> object:
    """The part of the validated config that one job of ``python -m madpinn <command>`` reads
    (``job``: e.g. ``kind``, ``study`` and ``run``, ``arena``): the ``reads`` the command declares
    beside its parser (:func:`madpinn.commands.command_reads`)."""
    reads = command_reads()
    if command not in reads:
        raise ValueError(f"no config dependency declared for command '{command}' (its parser's `reads`, "
                         "madpinn/commands/reads.py)")
    return reads[command](cfg, **job)


def settings_hash(cfg: Mapping, command: str, **job) -> str:
    """Hash (12 hex) of :func:`job_settings`: the rules' ``settings`` param."""
    from madpinn.config import config_hash

    return config_hash(job_settings(cfg, command, **job))


@functools.lru_cache(maxsize=1)
def _subparsers() -> dict[str, argparse.ArgumentParser]:
    parser = build_parser()
    return dict(next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction)).choices)


@functools.lru_cache(maxsize=1)
def _handlers() -> dict[str, str]:
    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return {name: f"{p.get_default('func').__module__}:{p.get_default('func').__qualname__}"
            for name, p in sub.choices.items()}
