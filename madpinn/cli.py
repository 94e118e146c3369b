"""Command line: ``python -m madpinn <command>`` (also ``madpinn <command>``).

Workflow rules call these commands; every command validates its config first.
Commands live next to the code they drive: each module in ``COMMAND_MODULES`` exposes
``register(subparsers)`` that adds its sub-command with ``func=handler(args) -> int``.
"""

from __future__ import annotations

import argparse
import importlib
import json
import sys
from pathlib import Path

from madpinn.config import ConfigError, load_config

COMMAND_MODULES = [
    "madpinn.cli",
    "madpinn.value_functions.cli",  # train-value, validate-* (issue 3)
    "madpinn.simulation.mujoco.commands",  # render-clip (issue 5)
    "madpinn.marl.cli",  # train-safemarl-nominal (issue 7)
    "madpinn.marl.defmarl.cli",  # train-defmarl (issue 8)
    "madpinn.evaluation.gap_cli",  # gap-decomposition, diagnose-collisions (issue 14)
]


def add_config_arg(p: argparse.ArgumentParser) -> None:
    p.add_argument("--config", nargs="+", required=True, help="config file(s), later ones override earlier ones")


def add_job_args(p: argparse.ArgumentParser) -> None:
    """Options shared by every workflow job command: thread count, progress bar, MLflow logging."""
    p.add_argument("--threads", type=int, default=1)
    p.add_argument("--no-progress", action="store_true")
    p.add_argument("--no-track", action="store_true")


def _validate(args) -> int:
    load_config(args.config)
    print("config OK")
    return 0


def _tracking_init(args) -> int:
    from madpinn.tracking import TrackingSettings, init_store

    settings = TrackingSettings.from_config(load_config(args.config))
    info = {"enabled": settings.enabled}
    if settings.enabled:
        info.update(init_store(settings))
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    Path(args.out).write_text(json.dumps(info, indent=2))
    print(json.dumps(info))
    return 0


def _evaluate(args) -> int:
    from madpinn.evaluation.job import evaluate

    cfg = load_config(args.config)
    summary = evaluate(
        cfg, args.study, args.run, args.n_agents, args.seed, args.out, backend=args.backend,
        threads=args.threads, progress=not args.no_progress, track=not args.no_track,
    )
    print(json.dumps({k: summary[k] for k in ("run", "n_agents", "seed", "safety_rate", "safe_scenarios", "cost", "cost_time_avg", "elapsed_s")}))
    return 0


def _table(args) -> int:
    from madpinn.evaluation.tables import write_table
    from madpinn.tracking import job_run

    cfg = load_config(args.config)
    with job_run(cfg, job_key=f"table/{args.name}", rule=args.name, params={"kind": args.kind, "inputs": len(args.inputs)},
                 track=not args.no_track) as run:
        files = write_table(args.name, args.kind, args.inputs, cfg, args.out_dir, oracle_paths=args.oracle or ())
        run.finish(artifacts=files)
    print("\n".join(map(str, files)))
    return 0


def _oracle(args) -> int:
    from madpinn.evaluation.oracle import OracleSettings, write_bounds
    from madpinn.scenarios import Arena

    cfg = load_config(args.config)
    arena = Arena.from_config(cfg, args.arena)
    settings = OracleSettings(horizon_s=arena.episode_s, u_max=cfg["agents"]["u_max"], v_max=cfg["agents"]["v_max"],
                              dt=arena.episode_s / cfg["oracle"]["steps"])
    print(write_bounds(args.out, arena, args.n_agents, args.seed, args.scenarios, cfg["agents"]["collision_radius"], settings))
    return 0


def _reproduction(args) -> int:
    import pandas as pd

    from madpinn.evaluation.reproduction import write_report
    from madpinn.tracking import log_job
    from madpinn.tracking.mlflow_store import git_commit

    cfg = load_config(args.config)
    study_of = dict(kv.split("=", 1) for kv in args.tables)   # table name -> study
    by_study: dict[str, list[str]] = {}
    for p in args.inputs:
        for study in pd.read_parquet(p, columns=["study"])["study"].unique():
            by_study.setdefault(str(study), []).append(p)
    tables = {name: by_study[study] for name, study in study_of.items() if study in by_study}
    files = write_report(args.out_dir, tables, cfg, oracle_paths=args.oracle or (), model_paths=args.models or (),
                         commit=git_commit())
    if not args.no_track:
        log_job(cfg, job_key="report/reproduction", rule="reproduction_report", wildcards={},
                params={"tables": sorted(tables)}, artifacts=files)
    print("\n".join(map(str, files)))
    return 0


def _figure(args) -> int:
    from madpinn.tracking import job_run

    cfg = load_config(args.config)
    with job_run(cfg, job_key=f"figure/{args.name}", rule=args.name, params={"inputs": len(args.inputs)},
                 track=not args.no_track) as run:
        if args.name == "fig_cost_safety":
            from madpinn.figures.cost_safety import plot_cost_safety

            files = plot_cost_safety(args.inputs, cfg, Path(args.out_dir) / args.name, oracle_paths=args.oracle or ())
        elif args.name == "fig_trajectories":
            from madpinn.evaluation.tables import label_of
            from madpinn.figures.trajectories import plot_trajectories

            labels = [label_of(cfg, Path(p).parent.name) for p in args.inputs]
            files = plot_trajectories(args.inputs, labels, Path(args.out_dir) / args.name)
        else:
            raise ValueError(f"unknown figure '{args.name}'")
        run.finish(artifacts=files)
    print("\n".join(map(str, files)))
    return 0


def register(sub) -> None:
    p = sub.add_parser("validate-config", help="validate config file(s) against the schema")
    add_config_arg(p)
    p.set_defaults(func=_validate)

    p = sub.add_parser("tracking-init", help="create the MLflow store and experiment once")
    add_config_arg(p)
    p.add_argument("--out", required=True, help="marker JSON written on success")
    p.set_defaults(func=_tracking_init)

    p = sub.add_parser("evaluate", help="evaluate one (study, run, N, seed) cell")
    add_config_arg(p)
    p.add_argument("--study", required=True)
    p.add_argument("--run", required=True, help="method or method-variant")
    p.add_argument("--n-agents", type=int, required=True)
    p.add_argument("--seed", type=int, required=True)
    p.add_argument("--backend", default=None, help="override sim.backend")
    p.add_argument("--out", required=True, help="per-scenario Parquet path")
    add_job_args(p)
    p.set_defaults(func=_evaluate)

    p = sub.add_parser("table", help="assemble a paper table from result files")
    add_config_arg(p)
    p.add_argument("--name", required=True)
    p.add_argument("--kind", required=True, choices=["safety_by_n", "summary"])
    p.add_argument("--inputs", nargs="+", required=True)
    p.add_argument("--oracle", nargs="*", default=None, help="oracle cache files: adds the lower-bound rows")
    p.add_argument("--out-dir", required=True)
    p.add_argument("--no-track", action="store_true")
    p.set_defaults(func=_table)

    p = sub.add_parser("reproduction", help="reproduction report: every table beside the paper's values")
    add_config_arg(p)
    p.add_argument("--tables", nargs="+", required=True, help="NAME=STUDY pairs")
    p.add_argument("--inputs", nargs="+", required=True, help="result .parquet files of those studies")
    p.add_argument("--oracle", nargs="*", default=None, help="oracle cache files (oracle rows)")
    p.add_argument("--models", nargs="*", default=None, help="model files whose sha256 the provenance lists")
    p.add_argument("--out-dir", required=True)
    p.add_argument("--no-track", action="store_true")
    p.set_defaults(func=_reproduction)

    p = sub.add_parser("oracle", help="cost lower bound of scenarios 0..S-1 of (arena, N, seed) -> Parquet")
    add_config_arg(p)
    p.add_argument("--arena", required=True)
    p.add_argument("--n-agents", type=int, required=True)
    p.add_argument("--seed", type=int, required=True)
    p.add_argument("--scenarios", type=int, required=True)
    p.add_argument("--out", required=True)
    p.set_defaults(func=_oracle)

    p = sub.add_parser("figure", help="draw a paper figure from result files")
    add_config_arg(p)
    p.add_argument("--name", required=True, choices=["fig_cost_safety", "fig_trajectories"])
    p.add_argument("--inputs", nargs="+", required=True, help="result .parquet (cost-safety) or _traj.npz files")
    p.add_argument("--oracle", nargs="*", default=None, help="oracle cache files (fig_cost_safety: lower-bound line)")
    p.add_argument("--out-dir", required=True)
    p.add_argument("--no-track", action="store_true")
    p.set_defaults(func=_figure)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="madpinn", description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command", required=True)
    for name in COMMAND_MODULES:
        module = sys.modules[__name__] if name == __name__ or name == "madpinn.cli" else importlib.import_module(name)
        module.register(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return int(args.func(args) or 0)
    except ConfigError as exc:
        print(f"madpinn: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    raise SystemExit(main())
