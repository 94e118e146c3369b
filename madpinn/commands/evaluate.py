"""``evaluate``: one (study, run, N, seed) cell -> Parquet/JSON/NPZ, then one MLflow run."""

from __future__ import annotations

from pathlib import Path
from typing import Mapping

from madpinn.commands.args import add_config_arg, add_job_args, add_model_arg, config_of, parse_models
from madpinn.commands.finish import JobRecord, finish, job

ECHO = ("run", "n_agents", "seed", "safety_rate", "safe_scenarios", "cost", "cost_time_avg", "elapsed_s")
LOGGED = ("safety_rate", "safe_scenarios", "cost", "cost_time_avg", "cost_all", "cost_all_time_avg",
          "safety_rate_2r", "safe_scenarios_2r", "elapsed_s", "policy_us_per_agent_step")


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
) -> dict:
    """Run one cell inside its live MLflow run (opened before the simulation), write its files,
    log them; return the summary."""
    from madpinn.config import method_config, study_sim
    from madpinn.evaluation.cell import CellSettings, run_cell, write_cell

    cs = CellSettings.from_config(cfg, study, run)
    method, mcfg = method_config(cfg, run)
    backend = backend or cfg["sim"]["backend"]
    record = JobRecord(
        job_key=f"evaluate/{backend}/{study}/{run}/n{n_agents}/seed{seed}", rule="evaluate",
        wildcards={"backend": backend, "study": study, "run": run, "n": n_agents, "seed": seed},
        params={"method": method, "method_config": mcfg, "arena": cfg["arenas"][cfg["studies"][study]["arena"]],
                "scenarios": cs.scenarios, "sim": study_sim(cfg, study), "observation": cfg["observation"]},
    )
    with job(cfg, record, track) as tracker:
        cell = run_cell(cs, n_agents, seed, models=models, backend=backend, threads=threads, progress=progress)
        record.artifacts = write_cell(cell, out)
        s = cell.summary
        record.metrics = {**{k: s[k] for k in LOGGED}, **{f"policy_{k}": v for k, v in s.get("policy_stats", {}).items()}}
        finish(tracker, record, echo={k: s[k] for k in ECHO} if echo else None)
    return s


def _evaluate(args) -> int:
    evaluate(config_of(args), args.study, args.run, args.n_agents, args.seed, args.out, models=parse_models(args.model),
             backend=args.backend, threads=args.threads, progress=not args.no_progress, track=not args.no_track, echo=True)
    return 0


def register(sub) -> None:
    p = sub.add_parser("evaluate", help="evaluate one (study, run, N, seed) cell")
    add_config_arg(p)
    p.add_argument("--study", required=True)
    p.add_argument("--run", required=True, help="method or method-variant")
    p.add_argument("--n-agents", type=int, required=True)
    p.add_argument("--seed", type=int, required=True)
    p.add_argument("--backend", default=None, help="override sim.backend")
    p.add_argument("--out", required=True, help="per-scenario Parquet path")
    add_model_arg(p, ("madpinn: vhat, vs", "safemarl: nominal, vs", "defmarl-<variant>: policy"))
    add_job_args(p)
    p.set_defaults(func=_evaluate)
