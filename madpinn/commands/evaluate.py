"""``evaluate``: one (study, run, N, seed) cell -> Parquet/JSON/NPZ, then one MLflow run."""

from __future__ import annotations

from pathlib import Path
from typing import Mapping

from madpinn.commands.args import add_config_arg, add_job_args, add_model_arg, config_of, parse_models
from madpinn.commands.finish import finish, job
from madpinn.commands.reads import cell

ECHO = ("run", "n_agents", "seed", "safety_rate", "safe_scenarios", "cost", "cost_time_avg", "elapsed_s")


def evaluate(
    cfg: dict,
    study: str,
    run: str,
    n_agents: int,
    seed: int,
    out: str | Path,
    models: Mapping[str, str | Path] | None = None,
    backend: str | None = None,
    threads: int = 1,
    progress: bool = True,
    track: bool = True,
    echo: bool = False,
    collision_events: bool = False,
    protocol_seed_reason: str | None = None,
    by_hand: bool = False,
    device: str | None = None,
) -> dict:
    """Run one cell inside its live MLflow run (opened before the simulation), write its files,
    log them; return the summary. ``collision_events``: classify the collision onsets of a MAD-PINN
    cell into its summary also where the study does not ask for it (the study's
    ``collision_events`` does for its cells; an ad-hoc diagnosis of one cell). ``device``: ``cpu`` or
    ``cuda`` in place of the config's ``device`` (the workflow passes the device the cell is keyed
    under: :func:`madpinn.machine.planned_device`); CUDA on a machine without it is one line, before any file."""
    from dataclasses import replace

    from madpinn.commands.cell_runs import cell_metrics, cell_record
    from madpinn.commands.seed_guard import REASON_KEY, protocol_seed_reason as guard
    from madpinn.config import ConfigError, RunSettings, check_cell
    from madpinn.evaluation.cell import CellSettings, run_cell, write_cell

    check_cell(cfg, n_agents, seed, study=study, run=run, backend=backend)   # as the workflow checks its targets
    reason = guard(seed, protocol_seed_reason) if by_hand else protocol_seed_reason

    r = RunSettings.resolve(cfg, study, run)   # the run, merged once
    cs = CellSettings.from_run(cfg, r)   # the run's agents override included (run_limits)
    if device is not None:
        from madpinn.device import resolve_device

        resolve_device(device)   # CUDA asked for where there is none: one line, nothing written
        cs = replace(cs, device=device)
    if collision_events and not cs.collision_events:
        if r.method != "madpinn":
            raise ConfigError(f"--collision-events classifies MAD-PINN collisions; run '{run}' is not a MAD-PINN run")
        cs = replace(cs, collision_events=True)
    backend = backend or str(r.sim["backend"])
    # the same key, params and metrics as a cell restored from the output cache (madpinn/commands/cell_runs.py)
    record = cell_record(r, n_agents, seed, backend, restored=False)
    if reason:
        record.tags[REASON_KEY] = reason
    with job(cfg, record, track) as tracker:
        cell = run_cell(cs, n_agents, seed, models=models, backend=backend, threads=threads, progress=progress)
        if reason:
            cell.summary[REASON_KEY] = reason
        record.artifacts = write_cell(cell, out)
        s = cell.summary
        record.metrics = cell_metrics(record.artifacts[0])
        shown = {k: s[k] for k in ECHO}
        if cs.collision_events:   # the onsets' summary (madpinn/evaluation/collisions.py); every event is in the JSON
            from madpinn.evaluation.collisions import summarise

            shown["collisions"] = summarise(s["collision_events"])
            record.metrics["collision_onsets"] = shown["collisions"]["collision_onsets"]
        finish(tracker, record, echo=shown if echo else None)
    return s


def _evaluate(args) -> int:
    evaluate(config_of(args), args.study, args.run, args.n_agents, args.seed, args.out, models=parse_models(args.model),
             backend=args.backend, threads=args.threads, progress=not args.no_progress, track=not args.no_track, echo=True,
             collision_events=args.collision_events, protocol_seed_reason=args.protocol_seed_reason,
             by_hand=True, device=args.device)
    return 0


def register(sub) -> None:
    p = sub.add_parser("evaluate", help="evaluate one (study, run, N, seed) cell")
    add_config_arg(p)
    p.add_argument("--study", required=True)
    p.add_argument("--run", required=True, help="method or method-variant")
    p.add_argument("--n-agents", type=int, required=True)
    p.add_argument("--seed", type=int, required=True)
    p.add_argument("--backend", default=None, help="override the study's backend (its sim.backend, else sim.backend)")
    p.add_argument("--out", required=True, help="per-scenario Parquet path")
    p.add_argument("--device", choices=("cpu", "cuda"), default=None,
                   help="run the cell on this device instead of the config's `device` (the workflow passes the one the cell is keyed under)")
    p.add_argument("--collision-events", action="store_true",
                   help="classify every collision onset of a MAD-PINN cell into its JSON summary (madpinn/evaluation/collisions.py)")
    p.add_argument("--protocol-seed-reason", default=None, metavar="TEXT",
                   help="why a protocol seed (< 100) is evaluated by hand; required for one outside the workflow, "
                        "recorded in the cell's summary and MLflow run")
    add_model_arg(p, ("madpinn: vhat, vs", "safemarl: nominal, vs", "defmarl-<variant>: policy"))
    add_job_args(p)
    p.set_defaults(func=_evaluate, reads=cell)
