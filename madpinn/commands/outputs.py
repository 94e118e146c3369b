"""``table`` and ``figure``: paper tables and figures assembled from result files."""

from __future__ import annotations

from pathlib import Path

from madpinn.commands.args import add_config_arg, config_of
from madpinn.commands.finish import JobRecord, finish


def _table(args) -> int:
    from madpinn.evaluation.tables import write_table

    cfg = config_of(args)
    files = write_table(args.name, args.kind, args.inputs, cfg, args.out_dir)
    return finish(cfg, JobRecord(job_key=f"table/{args.name}", rule=args.name, artifacts=files,
                                 params={"kind": args.kind, "inputs": len(args.inputs)}), not args.no_track, echo=list(files))


def _figure(args) -> int:
    cfg = config_of(args)
    if args.name == "fig_cost_safety":
        from madpinn.figures.cost_safety import plot_cost_safety

        files = plot_cost_safety(args.inputs, cfg, Path(args.out_dir) / args.name)
    else:  # fig_trajectories (argparse restricts the choices)
        from madpinn.evaluation.tables import label_of
        from madpinn.figures.trajectories import plot_trajectories

        labels = [label_of(cfg, Path(p).parent.name) for p in args.inputs]
        files = plot_trajectories(args.inputs, labels, Path(args.out_dir) / args.name)
    return finish(cfg, JobRecord(job_key=f"figure/{args.name}", rule=args.name, artifacts=files,
                                 params={"inputs": len(args.inputs)}), not args.no_track, echo=list(files))


def register(sub) -> None:
    p = sub.add_parser("table", help="assemble a paper table from result files")
    add_config_arg(p)
    p.add_argument("--name", required=True)
    p.add_argument("--kind", required=True, choices=["safety_by_n", "summary"])
    p.add_argument("--inputs", nargs="+", required=True)
    p.add_argument("--out-dir", required=True)
    p.add_argument("--no-track", action="store_true")
    p.set_defaults(func=_table)

    p = sub.add_parser("figure", help="draw a paper figure from result files")
    add_config_arg(p)
    p.add_argument("--name", required=True, choices=["fig_cost_safety", "fig_trajectories"])
    p.add_argument("--inputs", nargs="+", required=True, help="result .parquet (cost-safety) or _traj.npz files")
    p.add_argument("--out-dir", required=True)
    p.add_argument("--no-track", action="store_true")
    p.set_defaults(func=_figure)
