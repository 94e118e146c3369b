"""``gap-decomposition`` and ``diagnose-collisions`` commands (issue 14; see :mod:`madpinn.evaluation.gap`)."""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

from madpinn.config import config_hash, deep_merge, load_config


def _config_with_models(args) -> dict:
    """The config with ``--model vhat=PATH vs=PATH`` set as absolute MAD-PINN model paths."""
    cfg = load_config(args.config)
    models = {}
    for item in args.model or []:
        key, sep, path = item.partition("=")
        if not sep or key not in ("vhat", "vs"):
            raise ValueError(f"--model takes vhat=PATH or vs=PATH, got '{item}'")
        p = Path(path).resolve()
        if not p.is_file():
            raise FileNotFoundError(f"--model {key}: no file {p}")
        models[f"{key}_model"] = str(p)
    return deep_merge(cfg, {"methods": {"madpinn": models}}) if models else cfg


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
    return " ".join(parts + ["--out-dir", str(args.out_dir)])


def _gap(args) -> int:
    import torch

    from madpinn.evaluation import gap

    torch.set_num_threads(args.threads)
    cfg = _config_with_models(args)
    margin = args.carrot_margin if args.carrot_margin is not None else float(cfg["observation"].get("carrot_margin", 0.0))
    variants = gap.default_variants(margin, tuple(args.margin_sweep))
    table, diagnostics = gap.decompose(cfg, variants, args.agents, args.seeds, args.scenarios, args.run, progress=not args.no_progress)
    try:
        commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True, check=False).stdout.strip()
    except OSError:
        commit = ""
    provenance = {
        "command": _command_line(args),
        "run": args.run, "vhat_model": cfg["methods"]["madpinn"]["vhat_model"], "vs_model": cfg["methods"]["madpinn"]["vs_model"],
        "config_hash": config_hash(cfg), "commit": commit or "unknown",
    }
    for p in gap.write(table, diagnostics, args.out_dir, provenance):
        print(p)
    return 0


def _diagnose(args) -> int:
    import numpy as np
    import torch

    from madpinn.evaluation import gap
    from madpinn.evaluation.collisions import summarise

    torch.set_num_threads(args.threads)
    cfg = _config_with_models(args)
    if args.seed < gap.FIRST_VALIDATION_SEED and not args.allow_protocol_seed:
        raise ValueError(f"diagnose on validation seeds ≥ {gap.FIRST_VALIDATION_SEED} (or pass --allow-protocol-seed)")
    backend = args.backend or cfg["sim"]["backend"]
    summary, events = gap.run_cell(cfg, backend, args.run, args.study, args.n_agents, args.seed, args.scenarios, not args.no_progress)
    report = {"backend": backend, "n_agents": args.n_agents, "seed": args.seed, "scenarios": args.scenarios, **summary, **summarise(events)}
    print(json.dumps(report, indent=1, default=float))
    if args.out:
        Path(args.out).parent.mkdir(parents=True, exist_ok=True)
        Path(args.out).write_text(json.dumps({"summary": report, "events": events}, indent=1, default=float))
    return 0


def register(sub) -> None:
    from madpinn.cli import add_config_arg

    def common(p):
        add_config_arg(p)
        p.add_argument("--run", default="madpinn", help="MAD-PINN run (madpinn or madpinn-<variant>)")
        p.add_argument("--model", nargs="*", help="vhat=PATH vs=PATH (default: methods.madpinn.*_model under paths.results)")
        p.add_argument("--threads", type=int, default=1)
        p.add_argument("--no-progress", action="store_true")

    p = sub.add_parser("gap-decomposition", help="MAD-PINN safety/cost: double integrator vs MuJoCo, each deployment fix alone and together")
    common(p)
    p.add_argument("--agents", type=int, nargs="+", default=[12, 16, 64])
    p.add_argument("--seeds", type=int, nargs="+", default=[100, 101], help="validation seeds (≥ 100)")
    p.add_argument("--scenarios", type=int, default=20, help="scenarios per seed")
    p.add_argument("--carrot-margin", type=float, default=None, help="margin of the carrot fix (m; default observation.carrot_margin)")
    p.add_argument("--margin-sweep", type=float, nargs="*", default=[], help="extra double-integrator rows with these carrot margins (m)")
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
