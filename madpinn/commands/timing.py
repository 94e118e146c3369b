"""``neighbour-timing``: the deployment's neighbour-selection time per agent and update, N = 3 … 256
(madpinn/evaluation/neighbour_timing.py), for the claims page's timing claim."""

from __future__ import annotations

from madpinn.commands.args import add_config_arg, add_model_arg, config_of, single_model
from madpinn.commands.finish import JobRecord, finish, job, write_commit_record
from madpinn.commands.reads import keys


def _neighbour_timing(args) -> int:
    from madpinn.evaluation.neighbour_timing import write_timing

    cfg = config_of(args)
    record = JobRecord(job_key="report/neighbour_timing", rule="neighbour_timing",
                       params={"scenarios": args.scenarios, "repeats": args.repeats})
    with job(cfg, record, not args.no_track) as run:
        record.artifacts = write_timing(cfg, single_model(args.model, "vs"), args.out, args.scenarios, args.repeats)
        write_commit_record(cfg, record.job_key, record.artifacts)
        return finish(run, record, echo=list(record.artifacts))


def register(sub) -> None:
    p = sub.add_parser("neighbour-timing", help="neighbour-selection time per agent, N = 3 … 256 -> JSON")
    add_config_arg(p)
    add_model_arg(p, ("vs",))
    p.add_argument("--out", required=True, help="JSON path")
    p.add_argument("--scenarios", type=int, default=2, help="scenario starts timed per agent count")
    p.add_argument("--repeats", type=int, default=3, help="best of this many timings")
    p.add_argument("--no-track", action="store_true")
    p.set_defaults(func=_neighbour_timing,
                   reads=keys("experiment", "observation.n_neighbours", "observation.sensing_radius",
                              *(f"studies.{s}.{k}" for s in ("main", "scaling") for k in ("arena", "agent_counts")),
                              "arenas", "sim.start_separation", "methods.madpinn.vs_band"))
