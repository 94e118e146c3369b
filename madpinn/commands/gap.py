"""``gap-decomposition`` (issue 14; see :mod:`madpinn.evaluation.gap`): the decomposition table
from the gap studies' evaluation cells (the ``evaluate`` rule computes them; workflow target
``gap_decomposition``), then one MLflow run."""

from __future__ import annotations

from madpinn.commands.args import add_config_arg, add_job_args, config_of
from madpinn.commands.finish import JobRecord, finish, job
from madpinn.commands.reads import gap_rows


def _gap(args) -> int:
    from madpinn.config import config_hash
    from madpinn.evaluation import gap

    cfg = config_of(args)
    record = JobRecord(job_key="gap/decomposition", rule="gap_decomposition", params={"inputs": len(args.inputs)})
    with job(cfg, record, not args.no_track) as run:
        table, diagnostics = gap.decompose(cfg, gap.load_summaries(args.inputs))
        ref = cfg["gap_decomposition"]["reference"]
        provenance = {"studies": " ".join(cfg["gap_decomposition"]["studies"]), "cells": len(args.inputs),
                      "reference": f"{ref['run']} on {ref['backend']}", "config_hash": config_hash(cfg)}
        record.artifacts = gap.write(table, diagnostics, ref, args.out_dir, provenance)
        record.metrics = {"rows": len(table)}
        return finish(run, record, echo=[str(p) for p in record.artifacts])


def register(sub) -> None:
    p = sub.add_parser("gap-decomposition", help="MAD-PINN gap decomposition table from the gap studies' evaluation cells")
    add_config_arg(p)
    p.add_argument("--inputs", nargs="+", required=True, help="the gap studies' cell files (.json, or their .parquet)")
    p.add_argument("--out-dir", required=True, help="writes decomposition.{csv,md,json} here")
    add_job_args(p, progress=False)
    p.set_defaults(func=_gap, reads=gap_rows)
