"""``agent-models`` (issue 63; see :mod:`madpinn.evaluation.agent_models`): the agent-model table
from the cells of the studies ``agent_models.studies`` lists (the ``evaluate`` rule computes them;
workflow target ``table_agent_models``), then one MLflow run."""

from __future__ import annotations

from madpinn.commands.args import add_config_arg, add_job_args, config_of
from madpinn.commands.finish import JobRecord, finish, job
from madpinn.commands.reads import agent_model_rows


def _agent_models(args) -> int:
    from madpinn.config import ConfigError
    from madpinn.evaluation.agent_models import write_agent_models

    cfg = config_of(args)
    if not cfg["agent_models"]:
        raise ConfigError("agent-models: this configuration has no agent_models section (workflow/configs/agent_models.yaml)")
    record = JobRecord(job_key="table/table_agent_models", rule="table_agent_models", params={"inputs": len(args.inputs)})
    with job(cfg, record, not args.no_track) as run:
        record.artifacts = write_agent_models(args.inputs, cfg, args.out_dir)
        return finish(run, record, echo=[str(p) for p in record.artifacts])


def register(sub) -> None:
    p = sub.add_parser("agent-models", help="the agent-model table: 3-D vs planar double integrator on the same scenarios (issue 63)")
    add_config_arg(p)
    p.add_argument("--inputs", nargs="+", required=True, help="result .parquet files of agent_models.studies (_traj.npz beside them)")
    p.add_argument("--out-dir", required=True, help="writes table_agent_models.{csv,md,html} here")
    add_job_args(p, progress=False)
    p.set_defaults(func=_agent_models, reads=agent_model_rows)
