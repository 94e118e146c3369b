"""``gap-decomposition`` and ``diagnose-collisions`` (issue 14; see :mod:`madpinn.evaluation.gap`)."""

from __future__ import annotations

import json
from pathlib import Path

from madpinn.commands.args import add_config_arg, add_model_arg, config_of, parse_models

MODELS = ("vhat", "vs")


def _models(args) -> dict[str, Path]:
    """The MAD-PINN run's trained files (``--model vhat=PATH --model vs=PATH``), checked to exist."""
    from madpinn.config import ConfigError

    models = {k: p.resolve() for k, p in parse_models(args.model).items()}
    missing = [k for k in MODELS if k not in models]
    if missing or set(models) - set(MODELS):
        raise ConfigError(f"pass --model vhat=PATH --model vs=PATH (got {sorted(models)})")
    for key, p in models.items():
        if not p.is_file():
            raise FileNotFoundError(f"--model {key}: no file {p}")
    return models


def _command_line(args) -> str:
    """The gap-decomposition command that reproduces this run (from the parsed arguments)."""
    parts = ["python -m madpinn gap-decomposition --config", *args.config, "--run", args.run]
    if args.model:
        parts += ["--model", *args.model]
    parts += ["--agents", *map(str, args.agents), "--seeds", *map(str, args.seeds), "--scenarios", str(args.scenarios)]
    if args.carrot_margin is not None:
        parts += ["--carrot-margin", str(args.carrot_margin)]
    if args.margin_sweep:
        parts += ["--margin-sweep", *map(str, args.margin_sweep)]
    if args.look_ahead is not None:
        parts += ["--look-ahead", str(args.look_ahead)]
    return " ".join(parts + ["--out-dir", str(args.out_dir)])


def _gap(args) -> int:
    import torch

    from madpinn.config import config_hash
    from madpinn.evaluation import gap
    from madpinn.tracking.mlflow_store import git_commit

    torch.set_num_threads(args.threads)
    cfg = config_of(args)
    models = _models(args)
    margin = args.carrot_margin if args.carrot_margin is not None else float(cfg["observation"].get("carrot_margin", 0.0))
    ahead = args.look_ahead if args.look_ahead is not None else lookahead_of(cfg)
    variants = gap.default_variants(margin, tuple(args.margin_sweep), ahead)
    commit = git_commit()   # the code the rows run, read before the (long) decomposition
    table, diagnostics = gap.decompose(cfg, variants, args.agents, args.seeds, args.scenarios, args.run,
                                       progress=not args.no_progress, models=models)
    provenance = {
        "command": _command_line(args),
        "run": args.run, "vhat_model": str(models["vhat"]), "vs_model": str(models["vs"]),
        "config_hash": config_hash(cfg), "commit": commit,
    }
    for p in gap.write(table, diagnostics, args.out_dir, provenance):
        print(p)
    return 0


def _diagnose(args) -> int:
    import torch

    from madpinn.config import ConfigError
    from madpinn.evaluation import gap
    from madpinn.evaluation.collisions import summarise

    torch.set_num_threads(args.threads)
    cfg = config_of(args)
    models = _models(args)
    if args.seed < gap.FIRST_VALIDATION_SEED and not args.allow_protocol_seed:
        raise ConfigError(f"diagnose on validation seeds ≥ {gap.FIRST_VALIDATION_SEED} (or pass --allow-protocol-seed)")
    backend = args.backend or cfg["sim"]["backend"]
    summary, events = gap.run_cell(cfg, backend, args.run, args.study, args.n_agents, args.seed, args.scenarios,
                                   not args.no_progress, models=models)
    report = {"backend": backend, "n_agents": args.n_agents, "seed": args.seed, "scenarios": args.scenarios, **summary, **summarise(events)}
    print(json.dumps(report, indent=1, default=float))
    if args.out:
        Path(args.out).parent.mkdir(parents=True, exist_ok=True)
        Path(args.out).write_text(json.dumps({"summary": report, "events": events}, indent=1, default=float))
    return 0


def lookahead_of(cfg: dict) -> float:
    """τ (s) of the look-ahead extension: the ``madpinn-lookahead`` run's (the paper's deployment,
    ``madpinn``, has none)."""
    from madpinn.config import method_config

    return float(method_config(cfg, "madpinn-lookahead")[1]["look_ahead"])


def register(sub) -> None:
    def common(p):
        add_config_arg(p)
        p.add_argument("--run", default="madpinn", help="MAD-PINN run (madpinn or madpinn-<variant>)")
        add_model_arg(p, MODELS)
        p.add_argument("--threads", type=int, default=1)
        p.add_argument("--no-progress", action="store_true")

    p = sub.add_parser("gap-decomposition", help="MAD-PINN safety/cost: double integrator vs MuJoCo, each deployment fix alone and together")
    common(p)
    p.add_argument("--agents", type=int, nargs="+", default=[12, 16, 64])
    p.add_argument("--seeds", type=int, nargs="+", default=[100, 101], help="validation seeds (≥ 100)")
    p.add_argument("--scenarios", type=int, default=20, help="scenarios per seed")
    p.add_argument("--carrot-margin", type=float, default=None, help="margin of the carrot fix (m; default observation.carrot_margin)")
    p.add_argument("--margin-sweep", type=float, nargs="*", default=[], help="extra double-integrator rows with these carrot margins (m)")
    p.add_argument("--look-ahead", type=float, default=None, help="τ (s) of the lag-compensation fix (default: the madpinn-lookahead run's; 0: no such rows)")
    p.add_argument("--out-dir", required=True, help="writes decomposition.{csv,md,json} here")
    p.set_defaults(func=_gap)

    p = sub.add_parser("diagnose-collisions", help="classify MAD-PINN's collision onsets on either backend")
    common(p)
    p.add_argument("--study", default="main")
    p.add_argument("--n-agents", type=int, default=12)
    p.add_argument("--seed", type=int, default=100)
    p.add_argument("--allow-protocol-seed", action="store_true", help="allow a seed < 100 (protocol seeds: never tune on them)")
    p.add_argument("--scenarios", type=int, default=40)
    p.add_argument("--backend", choices=["double_integrator", "mujoco"], default=None, help="default: sim.backend")
    p.add_argument("--out", help="JSON with the summary and every event")
    p.set_defaults(func=_diagnose)
