"""Expected errors -> one line naming the problem and the fix (issue 18 item 7).

Every expected failure of a job (bad config, infeasible scenario, missing or mismatched
checkpoint, shipped model, diverged training or physics, tracking store, unknown study or run) is
printed as

    madpinn: <problem> — fix: <what to do>

with a non-zero exit code; ``--debug`` or ``MADPINN_DEBUG=1`` re-raises it with its traceback.
Anything else is a bug and keeps its traceback. The workflow's checks before any job (Snakefile,
``workflow/rules/*.smk``) stop through :func:`stop_workflow`: the same table, the same line.
"""

from __future__ import annotations

import os
import sys
from typing import Callable


def _expected() -> list[tuple[type[BaseException], str, int]]:
    """(exception type, fix, exit code), most specific first. Imported lazily: the CLI's
    start-up stays light."""
    from madpinn.atomic import UnwritableDirectoryError
    from madpinn.commands.seed_guard import ProtocolSeedError
    from madpinn.config import ConfigError, ConfigFileError, TargetError, WorkingDirectoryError
    from madpinn.marl.checkpoint import CheckpointError as MarlCheckpointError
    from madpinn.output_cache import CacheEntryError
    from madpinn.scenarios import ScenarioInfeasibleError
    from madpinn.simulation.mujoco.backend import PhysicsDivergedError
    from madpinn.tracking import TrackingError
    from madpinn.value_functions.model import CheckpointError as ValueCheckpointError
    from madpinn.value_functions.shipping import ShippedModelError
    from madpinn.value_functions.train import TrainingDiverged

    from madpinn.device import DeviceUnavailableError

    retrain = "run the workflow (snakemake -j2 all) to (re)train it, or pass the right --model NAME=PATH"
    return [
        (ProtocolSeedError, "use a validation seed (≥ 100), or say why with --protocol-seed-reason TEXT (recorded in "
                            "the cell's summary and MLflow run)", 2),
        (TargetError, "ask for a configured study, run, backend, arena and agent count (snakemake -n all lists the "
                      "workflow's cells)", 2),
        (WorkingDirectoryError, "run snakemake from the repository root (cd there), or pass --directory DIR to work in "
                                "another directory on purpose", 2),
        (ConfigFileError, "name an existing config file (config.yaml of the repository, or an overlay under "
                          "workflow/configs/), or restore it from git (git checkout -- config.yaml)", 2),
        (ConfigError, "correct the named key(s) (schema: workflow/schemas/config.schema.yaml)", 2),
        (ScenarioInfeasibleError, "use fewer agents or a larger arena (arenas.<name>.half_width) for this study", 3),
        (ShippedModelError, "ship a checkpoint of that model written by madpinn (python -m madpinn ship-models --model "
                            "NAME=PATH) or restore models/ from git (git checkout -- models), or drop the name from "
                            "shipped_models.names to train it", 4),
        (ValueCheckpointError, retrain, 4),
        (MarlCheckpointError, retrain, 4),
        (PhysicsDivergedError, "lower sim.dt or sim.mujoco.timestep, or check the controller gains (sim.mujoco)", 5),
        (TrainingDiverged, "training diverged: lower value_functions.<kind>.lr (or output_scale) and rerun", 5),
        (FloatingPointError, "training diverged: lower the learning rate of the named training block and rerun", 5),
        (CacheEntryError, "restore the named entry from git (git checkout -- <its files>), or delete all its files: "
                          "its job then runs again", 7),
        (UnwritableDirectoryError, "make the directory writable (permissions, a read-write mount) or name another "
                                   "one (the command's --out-dir / --out)", 2),
        (TrackingError, "start the tracking server named by tracking.uri, or set tracking.enabled: false", 6),
        (DeviceUnavailableError, "set device: auto or cpu in the config (or pass --device cpu), or run on a machine with "
                                 "a CUDA GPU", 2),
    ]


def debug_requested(argv: list[str]) -> bool:
    return "--debug" in argv or os.environ.get("MADPINN_DEBUG", "").strip() not in ("", "0", "false", "no")


def one_line(exc: BaseException) -> str:
    """The message of ``exc`` on one line (multi-line config reports joined by '; ')."""
    parts = [p.strip().removeprefix("- ").strip() for p in str(exc).splitlines() if p.strip()]   # a bullet, not "-3"
    if len(parts) > 1 and parts[0].endswith(":"):
        return parts[0] + " " + "; ".join(parts[1:])
    return "; ".join(parts) or type(exc).__name__


def expected_line(exc: BaseException) -> str | None:
    """``madpinn: <problem> — fix: <what to do>`` for an expected error, None for any other (a bug)."""
    for kind, fix, _ in _expected():
        if isinstance(exc, kind):
            return f"madpinn: {one_line(exc)} — fix: {getattr(exc, 'fix', None) or fix}"   # an error may name its own
    return None


def stop_workflow(exc: BaseException) -> None:
    """The workflow's checks before any job (Snakefile, ``workflow/rules/*.smk``): an expected
    error stops the run with its one line (as a command prints it) and exit code 1; anything else
    re-raises with its traceback."""
    line = expected_line(exc)
    if line is None or debug_requested([]):   # MADPINN_DEBUG=1 (snakemake has its own --debug)
        raise exc
    sys.stderr.write(f"\n{line}\n\n")
    raise SystemExit(1)


def run_reporting(func: Callable[[], int], debug: bool) -> int:
    """Run ``func``; turn an expected error into one line on stderr and its exit code, and an
    interrupt (Ctrl-C; SIGTERM inside a job: :class:`madpinn.tracking.JobKilled`) into one line and
    128 + the signal number (the job's MLflow run is closed KILLED and a training keeps its
    checkpoint before the interrupt gets here)."""
    try:
        return int(func() or 0)
    except KeyboardInterrupt as exc:
        from madpinn.tracking import JobKilled

        if debug:
            raise
        killed = isinstance(exc, JobKilled)
        print(f"madpinn: {'stopped by SIGTERM' if killed else 'interrupted (Ctrl-C)'} — fix: run the same command again "
              "(a training resumes from its last checkpoint)", file=sys.stderr)
        return 143 if killed else 130
    except Exception as exc:  # noqa: BLE001 - filtered below; unexpected errors re-raise
        for kind, _, code in _expected():
            if isinstance(exc, kind):
                if debug:
                    raise
                print(expected_line(exc), file=sys.stderr)
                return code
        raise
