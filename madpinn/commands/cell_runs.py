"""An evaluation cell's MLflow run, the same whether the cell was computed or restored, and
``track-cells``: every cell of the protocol a run of its experiment.

A computed cell's ``evaluate`` job logs its live run (:mod:`madpinn.commands.evaluate`); a cell
restored from the output cache (``--cache``, profile ``shipped``) runs no job, so
``track-cells`` (rule ``track_cells``, after every cell) logs it from its files — the same job key,
params (:func:`cell_record`), metrics (:func:`cell_metrics`) and artifacts — tagged
``madpinn.restored=true``. Every cell run carries ``madpinn.provenance_hash``, the Snakemake provenance
hash it is cached under (the name of the cache entry its output links to), once it is in the
output cache. Results stay files first: the runs are built from the cell's files.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Iterable

from madpinn.commands.args import add_config_arg, config_of
from madpinn.commands.finish import JobRecord, finish, job, write_json
from madpinn.config import RunSettings

RESTORED_TAG = "madpinn.restored"          # "true": restored from the output cache, "false": computed here
PROVENANCE_TAG = "madpinn.provenance_hash"      # Snakemake's provenance hash of the cell (its cache entry)
LOGGED = ("safety_rate", "safe_scenarios", "cost", "cost_time_avg", "cost_all", "cost_all_time_avg",
          "safety_rate_2r", "safe_scenarios_2r", "elapsed_s", "cpu_s", "policy_us_per_agent_step")
"""Figures of a cell's JSON summary logged as metrics (with ``min_separation`` from its scenarios
and ``infeasible_share`` where the policy reports it: :func:`cell_metrics`)."""


def cell_job_key(backend: str, study: str, run: str, n_agents: int, seed: int) -> str:
    return f"evaluate/{backend}/{study}/{run}/n{n_agents}/seed{seed}"


def cell_record(r: RunSettings, n_agents: int, seed: int, backend: str, restored: bool) -> JobRecord:
    """The cell's job record before its figures, from its resolved run ``r``
    (:class:`madpinn.config.RunSettings`): key, wildcards, params (what the cell depends on, and its
    coordinates for the runs table's columns) and the ``restored`` tag."""
    return JobRecord(
        job_key=cell_job_key(backend, r.study, r.run, n_agents, seed), rule="evaluate",
        wildcards={"backend": backend, "study": r.study, "run": r.run, "n": n_agents, "seed": seed},
        params={"study": r.study, "run": r.run, "n_agents": n_agents, "seed": seed, "method": r.method,
                "method_config": r.method_config, "arena": r.arena, "scenarios": r.study_config["scenarios"], "sim": r.sim,
                "observation": r.observation, "agents": r.agents},
        tags={RESTORED_TAG: str(restored).lower()},
    )


def cell_metrics(parquet: str | Path) -> dict:
    """A cell's metrics from its files: :data:`LOGGED` and ``policy_<stat>`` from the JSON summary
    beside ``parquet``, ``infeasible_share`` (MAD-PINN: agent-steps with no feasible budget,
    ``policy_stats.infeasible_fraction``), ``min_separation`` (m, smallest centre distance of any
    pair over the cell's scenarios) and ``min_separation_mean`` (its mean over scenarios)."""
    import pandas as pd

    from madpinn.evaluation.cell_files import cell_summary

    s = cell_summary(parquet)
    stats = s.get("policy_stats") or {}
    metrics = {k: s[k] for k in LOGGED if k in s}
    metrics.update({f"policy_{k}": v for k, v in stats.items() if isinstance(v, (int, float))})
    if "infeasible_fraction" in stats:
        metrics["infeasible_share"] = stats["infeasible_fraction"]
    sep = pd.read_parquet(parquet, columns=["min_separation"])["min_separation"]
    if len(sep):
        metrics.update(min_separation=float(sep.min()), min_separation_mean=float(sep.mean()))
    return metrics


def cell_files(parquet: str | Path) -> list[Path]:
    """The cell's three files: Parquet, JSON summary, first scenario's trajectory."""
    from madpinn.evaluation.cell_files import cell_paths

    return list(cell_paths(parquet))


def provenance_hash(parquet: str | Path) -> str | None:
    """The Snakemake provenance hash of a cell whose Parquet file links into the output cache
    (``<cache>/<hash>_parquet.parquet``), else None (not cached)."""
    path = Path(parquet)
    if not path.is_symlink():
        return None
    name = Path(os.readlink(path)).name
    head, sep, _ = name.partition("_")
    return head if sep and len(head) == 64 else None


def _cell_of(parquet: Path) -> dict:
    """(backend, study, run, n_agents, seed) of a cell from its summary."""
    from madpinn.evaluation.cell_files import cell_summary

    s = cell_summary(parquet)
    missing = [k for k in ("backend", "study", "run", "n_agents", "seed") if k not in s]
    if missing:
        from madpinn.config import ConfigError

        raise ConfigError(f"{parquet}: its JSON summary lacks {missing}; recompute the cell")
    return {"backend": str(s["backend"]), "study": str(s["study"]), "run": str(s["run"]),
            "n_agents": int(s["n_agents"]), "seed": int(s["seed"])}


def _cell_runs(settings) -> dict:
    """{job key: run} of this results path's workflow cell runs in the configuration's experiment."""
    from madpinn.tracking.mlflow_store import JOB_TAG, RESULTS_TAG, SOURCE_TAG, client, experiment_id

    c = client(settings)
    exp = experiment_id(c, settings)
    runs, token = {}, None
    while True:
        page = c.search_runs([exp], filter_string="tags.`madpinn.rule` = 'evaluate'", max_results=1000,
                             page_token=token)
        for r in page:
            if r.data.tags.get(SOURCE_TAG, "workflow") == settings.source and r.data.tags.get(RESULTS_TAG) == settings.results:
                runs[r.data.tags.get(JOB_TAG)] = r
        token = page.token
        if not token:
            return runs


def track_cells(cfg: dict, cells: Iterable[str | Path]) -> dict:
    """Make every cell of ``cells`` (Parquet paths) a run of the experiment: a cell without a run
    here, or whose restored run has another provenance hash, is logged from its files
    (``restored=true`` when it links into the output cache); a computed cell's run gets its
    provenance hash tag. Returns ``{cells, logged, tagged, enabled}``."""
    from madpinn.tracking import TrackingSettings
    from madpinn.tracking.mlflow_store import client

    settings = TrackingSettings.from_config(cfg)
    cells = [Path(p) for p in cells]
    counts = {"enabled": settings.enabled, "cells": len(cells), "logged": 0, "tagged": 0}
    if not settings.enabled:
        return counts
    existing = _cell_runs(settings)
    c = client(settings)
    for parquet in cells:
        where = _cell_of(parquet)
        key = cell_job_key(**where)
        prov = provenance_hash(parquet)
        run = existing.get(key)
        tags = run.data.tags if run is not None else {}
        if run is not None and (tags.get(RESTORED_TAG) != "true" or tags.get(PROVENANCE_TAG) in (None, prov)):
            missing = {k: v for k, v in ((PROVENANCE_TAG, prov), (RESTORED_TAG, "false")) if v and k not in tags}
            for k, v in missing.items():
                c.set_tag(run.info.run_id, k, v)
            counts["tagged"] += bool(missing)
            continue
        record = cell_record(RunSettings.resolve(cfg, where["study"], where["run"]), where["n_agents"], where["seed"],
                             where["backend"], restored=prov is not None)
        record.tags = {**record.tags, **({PROVENANCE_TAG: prov} if prov else {}),
                       **({"madpinn.logged_from_files": "true"} if prov is None else {})}
        with job(cfg, record, True) as tracker:
            record.artifacts = cell_files(parquet)
            record.metrics = cell_metrics(parquet)
            finish(tracker, record)
        counts["logged"] += 1
    return counts


def _track_cells(args) -> int:
    counts = track_cells(config_of(args), args.cells)
    write_json(args.out, counts)
    print(json.dumps(counts))
    return 0


def register(sub) -> None:
    p = sub.add_parser("track-cells", help="every evaluation cell (computed or restored from the output cache) an MLflow run")
    add_config_arg(p)
    p.add_argument("--cells", nargs="+", required=True, help="the cells' Parquet files")
    p.add_argument("--out", required=True, help="marker file: counts of cells, runs logged and tagged")
    p.set_defaults(func=_track_cells)
