"""``table``, ``figure``, ``oracle``, ``reproduction`` and ``claims``: paper tables, figures, the cost
lower bound, the reproduction report (from result files) and the paper's claims tested on it."""

from __future__ import annotations

from pathlib import Path

from madpinn.commands.args import add_config_arg, config_of, parse_models
from madpinn.commands.finish import JobRecord, finish, job, write_commit_record
from madpinn.commands.reads import governors, keys, labels, study_sim_override, table_ii_readings
from madpinn.config import hashed_agents


def _table(args) -> int:
    from madpinn.evaluation.tables import write_table

    cfg = config_of(args)
    record = JobRecord(job_key=f"table/{args.name}", rule=args.name, params={"kind": args.kind, "inputs": len(args.inputs)})
    with job(cfg, record, not args.no_track) as run:
        record.artifacts = write_table(args.name, args.kind, args.inputs, cfg, args.out_dir, oracle_paths=args.oracle or ())
        return finish(run, record, echo=list(record.artifacts))


def _figure(args) -> int:
    cfg = config_of(args)
    record = JobRecord(job_key=f"figure/{args.name}", rule=args.name, params={"inputs": len(args.inputs)})
    with job(cfg, record, not args.no_track) as run:
        if args.name == "fig_cost_safety":
            from madpinn.figures.cost_safety import plot_cost_safety

            files = plot_cost_safety(args.inputs, cfg, Path(args.out_dir) / args.name, oracle_paths=args.oracle or ())
        elif args.name == "fig_large_arena_frontier":
            from madpinn.config import ConfigError
            from madpinn.figures.frontier import FrontierRun, plot_large_arena_frontier

            if not args.study or len(args.study) != 1 or args.study[0] not in cfg["studies"]:
                raise ConfigError(f"fig_large_arena_frontier needs one --study STUDY of this configuration, got {args.study!r}")
            runs = [FrontierRun.of_run(cfg, run) for run in cfg["studies"][args.study[0]]["runs"]]
            files = plot_large_arena_frontier(args.inputs, runs, Path(args.out_dir) / args.name)
        elif args.name == "fig_vhat_budget":
            files = _vhat_budget_figure(cfg, args)
        else:  # fig_trajectories (argparse restricts the choices)
            from madpinn.evaluation.tables import label_of
            from madpinn.figures.trajectories import plot_trajectories

            labels = [label_of(cfg, Path(p).parent.name) for p in args.inputs]
            files = plot_trajectories(args.inputs, labels, Path(args.out_dir) / args.name)
        record.artifacts = files
        return finish(run, record, echo=list(files))


def _vhat_budget_figure(cfg: dict, args) -> list[Path]:
    """fig_vhat_budget: a panel per ``--study``, each run with the samples of the V̂ it loads (``--vhat
    RUN=PATH``) and, with ``--verify RUN=JSON``, that V̂'s scenario verification. A V̂ variant that only
    reseeds the base recipe is a training-seed replicate; one at the base's samples and schedule that
    changes its recipe (e.g. ``nocs``) is a recipe variant: neither is a budget point."""
    import json

    from madpinn.config import ConfigError, method_config
    from madpinn.figures.budget import BudgetRun, budget_base, budget_panel, budget_roles, model_samples, model_schedule, plot_vhat_budget
    from madpinn.value_functions.model import read_checkpoint

    studies = args.study or []
    unknown = [st for st in studies if st not in cfg["studies"]]
    if not studies or unknown:
        raise ConfigError(f"fig_vhat_budget needs --study STUDY... of this configuration, got {studies!r}")
    models, reports = parse_models(args.vhat or [], "--vhat"), parse_models(args.verify or [], "--verify")
    runs = []
    names = list(dict.fromkeys(run for st in studies for run in cfg["studies"][st]["runs"]))
    missing = [run for run in names if run not in models]
    if missing:
        raise ConfigError(f"fig_vhat_budget: pass --vhat {missing[0]}=PATH (the V̂ model run '{missing[0]}' loads)")
    metas = {run: read_checkpoint(models[run], "vhat")["meta"] for run in names}
    budget_of = {run: (model_samples(m), model_schedule(m)) for run, m in metas.items()}
    variants = {run: method_config(cfg, run)[1].get("vhat") for run in names}
    table = cfg["value_functions"]["vhat_variants"]
    base = budget_base(variants, table)   # the reference recipe's run
    roles = budget_roles(base, variants, table, budget_of)
    for run in names:
        report = json.loads(Path(reports[run]).read_text()) if run in reports else None
        runs.append(BudgetRun(run=run, label=str(method_config(cfg, run)[1]["label"]), samples=budget_of[run][0],
                              schedule=budget_of[run][1], verification=report, **roles[run]))
    panels = [budget_panel(st, cfg["studies"][st]["arena"], cfg["studies"][st]["pattern"], cfg["studies"][st]["agent_counts"])
              for st in studies]
    return plot_vhat_budget(args.inputs, runs, panels, Path(args.out_dir) / args.name)


def _oracle(args) -> int:
    import pandas as pd

    from madpinn.evaluation.oracle import OracleSettings, write_bounds
    from madpinn.scenarios import UNIFORM, Arena

    cfg = config_of(args)
    arena = Arena.from_config(cfg, args.arena)
    settings = OracleSettings.from_config(cfg, args.arena)
    wildcards = {"arena": args.arena, "n": args.n_agents, "seed": args.seed, "scenarios": args.scenarios}
    where = args.arena
    pattern = args.pattern or UNIFORM
    if pattern != UNIFORM:
        wildcards["pattern"] = pattern
        where = f"{args.arena}/{pattern}"
    record = JobRecord(job_key=f"oracle/{where}/n{args.n_agents}/seed{args.seed}/s{args.scenarios}",
                       rule="oracle" if pattern == UNIFORM else "oracle_pattern",   # the workflow rule that runs it
                       wildcards=wildcards, params={"scenarios": args.scenarios, "steps": cfg["oracle"]["steps"]})
    with job(cfg, record, not args.no_track) as run:
        out = write_bounds(args.out, arena, args.n_agents, args.seed, args.scenarios, cfg["sim"]["start_separation"],
                           settings, pattern=pattern)
        record.artifacts = [out]
        record.metrics = {"oracle_cost_mean": float(pd.read_parquet(out)["oracle_cost"].mean())}
        return finish(run, record, echo=[out])


def _study_of(pairs: list[str]) -> dict[str, str]:
    """``--tables NAME=STUDY`` pairs -> {table name: study}."""
    from madpinn.config import ConfigError

    study_of = {}
    for kv in pairs:
        name, sep, study = kv.partition("=")
        if not sep or not name or not study:
            raise ConfigError(f"--tables expects NAME=STUDY, got '{kv}'")
        study_of[name] = study
    return study_of


def _reproduction(args) -> int:
    import pandas as pd

    from madpinn.evaluation.reproduction import write_report

    cfg = config_of(args)
    study_of = _study_of(args.tables)
    by_study: dict[str, list[str]] = {}
    for p in args.inputs:
        for study in pd.read_parquet(p, columns=["study"])["study"].unique():
            by_study.setdefault(str(study), []).append(p)
    tables = {name: by_study[study] for name, study in study_of.items() if study in by_study}
    record = JobRecord(job_key="report/reproduction", rule="reproduction_report", params={"tables": sorted(tables)})
    with job(cfg, record, not args.no_track) as run:
        record.artifacts = write_report(args.out_dir, tables, cfg, oracle_paths=args.oracle or (),
                                        model_paths=args.models or ())
        write_commit_record(cfg, record.job_key, record.artifacts)
        return finish(run, record, echo=list(record.artifacts))


def _claims(args) -> int:
    from madpinn.evaluation.claims import write_claims

    cfg = config_of(args)
    record = JobRecord(job_key="report/claims", rule="claims_table", params={"report": str(args.report)})
    with job(cfg, record, not args.no_track) as run:
        record.artifacts = write_claims(args.report, args.out_dir, timing_path=args.timing, heatmap_path=args.heatmap,
                                        readings_path=args.table_ii_verdict, recipe_path=args.vhat_recipe)
        write_commit_record(cfg, record.job_key, record.artifacts)
        return finish(run, record, echo=list(record.artifacts))


def _collision_readings(args) -> int:
    from madpinn.evaluation.readings import write_readings

    cfg = config_of(args)
    table_of = {study: name for name, study in _study_of(args.tables).items()}
    record = JobRecord(job_key="table/table_collision_readings", rule="collision_readings",
                       params={"tables": sorted(table_of.values()), "inputs": len(args.inputs)})
    with job(cfg, record, not args.no_track) as run:
        record.artifacts = write_readings(args.inputs, cfg, table_of, args.out_dir)
        return finish(run, record, echo=list(record.artifacts))


def _controller_readings(args) -> int:
    from madpinn.evaluation.controller_readings import write_controller_readings

    cfg = config_of(args)
    record = JobRecord(job_key="table/table_controller_readings", rule="controller_readings",
                       params={"inputs": len(args.inputs)})
    with job(cfg, record, not args.no_track) as run:
        record.artifacts = write_controller_readings(args.inputs, cfg, args.out_dir)
        return finish(run, record, echo=list(record.artifacts))


def _table_ii_readings(args) -> int:
    import json

    from madpinn.config.paths import in_repository
    from madpinn.evaluation.reproduction import paper_values
    from madpinn.evaluation.table_ii_page import load_frames, write_table_ii_readings
    from madpinn.evaluation.table_ii_readings import PaperRow, reading_rows
    from madpinn.evaluation.table_ii_settings import ReadingsSettings
    from madpinn.figures.scenario_laws import plot_scenario_laws
    from madpinn.figures.table_ii_readings import plot_table_ii_readings

    cfg = config_of(args)
    settings, paper = ReadingsSettings.from_config(cfg), PaperRow.from_paper_values(paper_values())
    record = JobRecord(job_key="table/table_ii_readings", rule="table_ii_readings", params={"inputs": len(args.inputs)})
    with job(cfg, record, not args.no_track) as run:
        anchor, large, baselines = load_frames(args.inputs, settings)
        rows = reading_rows(large)   # once: the page's tables and the figure
        chosen = cfg["table_ii_readings"]["chosen_on"]   # the page these readings were chosen on (an input of the rule)
        chosen_on = json.loads(in_repository(chosen).read_text()) if chosen else None
        files = write_table_ii_readings(anchor, large, rows, baselines, settings, paper, args.out_dir, chosen_on=chosen_on)
        files += plot_table_ii_readings(rows, paper, settings.labels, Path(args.out_dir) / "fig_table_ii_readings")
        files += plot_scenario_laws(anchor, large, settings, Path(args.out_dir) / "fig_scenario_laws")
        record.artifacts = files
        return finish(run, record, echo=list(record.artifacts))


def register(sub) -> None:
    p = sub.add_parser("table", help="assemble a paper table from result files")
    add_config_arg(p)
    p.add_argument("--name", required=True)
    p.add_argument("--kind", required=True, choices=["safety_by_n", "summary"])
    p.add_argument("--inputs", nargs="+", required=True)
    p.add_argument("--oracle", nargs="*", default=None, help="oracle cache files: adds the lower-bound rows")
    p.add_argument("--out-dir", required=True)
    p.add_argument("--no-track", action="store_true")
    p.set_defaults(func=_table, reads=lambda cfg, study: {"experiment": cfg["experiment"], "labels": labels(cfg, study)})

    p = sub.add_parser("reproduction", help="reproduction report: every table beside the paper's values")
    add_config_arg(p)
    p.add_argument("--tables", nargs="+", required=True, help="NAME=STUDY pairs")
    p.add_argument("--inputs", nargs="+", required=True, help="result .parquet files of those studies")
    p.add_argument("--oracle", nargs="*", default=None, help="oracle cache files (oracle rows)")
    p.add_argument("--models", nargs="*", default=None, help="model files whose sha256 the provenance lists")
    p.add_argument("--out-dir", required=True)
    p.add_argument("--no-track", action="store_true")
    p.set_defaults(func=_reproduction,
                   reads=lambda cfg, studies: {"experiment": cfg["experiment"], "labels": labels(cfg, *studies)})

    p = sub.add_parser("claims", help="the paper's claims tested on a reproduction report -> claims.{json,md,html}")
    add_config_arg(p)
    p.add_argument("--report", required=True, help="reproduction.json (python -m madpinn reproduction)")
    p.add_argument("--timing", default=None, help="neighbour_timing.json (python -m madpinn neighbour-timing)")
    p.add_argument("--heatmap", default=None, help="fig_value_heatmap.json (python -m madpinn fig-value-heatmap)")
    p.add_argument("--table-ii-verdict", default=None, help="verdict.json of the Table II readings (python -m madpinn table-ii-readings)")
    p.add_argument("--vhat-recipe", default=None, help="vhat_recipe.json: the V̂ recipe's choice (python -m madpinn vhat-recipe)")
    p.add_argument("--out-dir", required=True)
    p.add_argument("--no-track", action="store_true")
    p.set_defaults(func=_claims, reads=keys("experiment"))

    p = sub.add_parser("collision-readings", help="every paper cell under each collision reading (issue 38)")
    add_config_arg(p)
    p.add_argument("--tables", nargs="+", required=True, help="NAME=STUDY pairs: paper table of each base study")
    p.add_argument("--inputs", nargs="+", required=True, help="result .parquet files of the base and <base>_contacts studies")
    p.add_argument("--out-dir", required=True)
    p.add_argument("--no-track", action="store_true")
    p.set_defaults(func=_collision_readings,
                   reads=lambda cfg, studies: {"experiment": cfg["experiment"], "labels": labels(cfg, *studies)})

    p = sub.add_parser("controller-readings", help="every cell under each reading of the tracking controller (issue 46)")
    add_config_arg(p)
    p.add_argument("--inputs", nargs="+", required=True, help="result .parquet files of the ctl_* studies (JSON and _traj.npz beside them)")
    p.add_argument("--out-dir", required=True)
    p.add_argument("--no-track", action="store_true")
    p.set_defaults(func=_controller_readings,
                   reads=lambda cfg, studies: {"experiment": cfg["experiment"], "labels": labels(cfg, *studies),
                                               "readings": {s: study_sim_override(cfg, s) for s in studies}})

    p = sub.add_parser("table-ii-readings", help="Table II under the readings the paper leaves open, and the claim's verdict (issue 60)")
    add_config_arg(p)
    p.add_argument("--inputs", nargs="+", required=True, help="result .parquet files of table_ii_readings' studies and its anchor")
    p.add_argument("--out-dir", required=True)
    p.add_argument("--no-track", action="store_true")
    p.set_defaults(func=_table_ii_readings, reads=table_ii_readings)

    from madpinn.commands.recipe import register as register_recipe   # vhat-recipe: its own module (its page's hash only)

    register_recipe(sub)

    from madpinn.commands.conformal import register as register_conformal   # conformal-page: its own module (its page's hash only)

    register_conformal(sub)

    p = sub.add_parser("oracle", help="cost lower bound of scenarios 0..S-1 of (arena, N, seed) -> Parquet")
    add_config_arg(p)
    p.add_argument("--arena", required=True)
    p.add_argument("--n-agents", type=int, required=True)
    p.add_argument("--seed", type=int, required=True)
    p.add_argument("--scenarios", type=int, required=True)
    p.add_argument("--pattern", default=None, help="a structured conflict pattern (madpinn/conflicts.py); default: uniform (SPEC §2)")
    p.add_argument("--out", required=True)
    p.add_argument("--no-track", action="store_true")
    p.set_defaults(func=_oracle, reads=lambda cfg, arena: {
        "oracle": cfg["oracle"], "agents": hashed_agents(cfg["agents"]), "arena": cfg["arenas"][arena],
        "start_separation": cfg["sim"]["start_separation"]})

    p = sub.add_parser("figure", help="draw a paper figure from result files")
    add_config_arg(p)
    p.add_argument("--name", required=True, choices=["fig_cost_safety", "fig_trajectories", "fig_large_arena_frontier",
                                                      "fig_vhat_budget"])
    p.add_argument("--study", nargs="+", default=None,
                   help="fig_large_arena_frontier: the study whose runs it shows; fig_vhat_budget: one panel per study")
    p.add_argument("--vhat", nargs="*", default=None, metavar="RUN=PATH",
                   help="fig_vhat_budget: the V̂ model each run loads (its training samples)")
    p.add_argument("--verify", nargs="*", default=None, metavar="RUN=JSON",
                   help="fig_vhat_budget: the verify-vhat report of the V̂ each run loads (ε columns of the CSV)")
    p.add_argument("--inputs", nargs="+", required=True, help="result .parquet (cost-safety) or _traj.npz files")
    p.add_argument("--oracle", nargs="*", default=None, help="oracle cache files (fig_cost_safety: lower-bound line)")
    p.add_argument("--out-dir", required=True)
    p.add_argument("--no-track", action="store_true")
    p.set_defaults(func=_figure, reads=lambda cfg, name, study: {
        "experiment": cfg["experiment"], "labels": labels(cfg, *([study] if isinstance(study, str) else study)),
        **({"panels": {st: [cfg["studies"][st][k] for k in ("arena", "pattern", "agent_counts")] for st in study}}
           if name == "fig_vhat_budget" else {}),
        **({"trajectories": cfg["figures"]["trajectories"]} if name == "fig_trajectories" else {}),
        **({"governors": governors(cfg, study)} if name == "fig_large_arena_frontier" else {})})
