"""Value-function jobs:

- ``train-value --kind vhat|vs``: train (resumable), write the model, loss CSV/figure, MLflow run;
- ``validate-vs``: rollout verification JSON + V_s slices figure;
- ``validate-vhat``: held-out HJB residual statistics JSON;
- ``fig-value-heatmap``: the paper's V̂ heatmap (.pdf, .png) and its reading in numbers (.json);
- ``solve-vs-grid``: the hj_reachability grid reference of V_s (.npz) with its convergence check;
- ``validate-vs-grid``: V_s against the grid reference (JSON + zero-level-set figure);
- ``verify-vhat``: scenario-based (ε, β) verification of V̂ (uniform and conflict states);
- ``ship-models`` / ``install-shipped``: ``models/`` + ``manifest.json``; sha256-checked install.

Every job runs in one live MLflow run (:mod:`madpinn.commands.finish`), ``install-shipped`` when
given ``--config`` (as the workflow does); ``ship-models``, a maintainer's command, has none.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

from madpinn.commands.args import add_config_arg, add_job_args, add_model_arg, config_of, parse_models, single_model
from madpinn.commands.finish import JobRecord, finish, job, write_json
from madpinn.config import REPO_ROOT
from madpinn.value_functions.build import KINDS
from madpinn.commands.reads import VF_RUN, Z_TOL, keys, training

LIVE_POINTS = 1000
"""training curves: at most this many live MLflow points per run"""


def _seconds(text: str) -> float:
    """``--time-limit`` value: a number of seconds ≥ 0."""
    try:
        value = float(text)
    except ValueError:
        value = float("nan")
    if not value >= 0.0:
        raise argparse.ArgumentTypeError(f"expected a number of seconds >= 0, got '{text}'")
    return value


def _setup(cfg: dict, threads: int | None, seed: int):
    from madpinn.device import resolve_device, resolve_dtype, seed_everything

    seed_everything(seed, threads or int(cfg["value_functions"]["threads"]))
    return resolve_device(cfg["device"]), resolve_dtype(cfg["dtype"])


def deployed_z_tolerance(cfg: dict) -> float:
    """The z tolerance of the deployed MAD-PINN policy (its settings' ``z_tolerance``, a fraction
    of z_max): the grid ``verify-vhat`` and the heatmap search, so they certify and show its z*."""
    from madpinn.config import method_config
    from madpinn.policies import policy_settings

    return policy_settings(*method_config(cfg, "madpinn")).z_tolerance


def figure_of(model, cfg: dict, kind: str, stem: Path) -> list[Path]:
    """The validation figure of a trained model (the training's quick look and ``fig-value-heatmap``)."""
    from madpinn.value_functions.figures import validation_figure

    return validation_figure(model, kind, cfg["arenas"]["small"]["half_width"],
                             cfg["value_functions"]["vs"]["validation"]["slice_velocities"],
                             deployed_z_tolerance(cfg), stem)


def _train(args) -> int:
    from madpinn.value_functions.build import training_hash, training_seed

    from madpinn.config import vf_model_name, with_vf_variant

    kind, variant = args.kind, args.variant
    cfg = with_vf_variant(config_of(args), kind, variant)   # the variant's settings, before anything reads them
    name = vf_model_name(kind, variant)
    vcfg = _training_settings(cfg, kind)
    record = JobRecord(job_key=f"train/{name}", rule=f"train_{kind}_variant" if variant else f"train_{kind}",
                       wildcards={"kind": kind, **({"variant": variant} if variant else {})},
                       params={"settings": {**vcfg, "seed": training_seed(cfg, kind)},
                               "config_hash": training_hash(cfg, kind),
                               "schedule_hash": training_hash(cfg, kind, schedule_only=True)})
    with job(cfg, record, not args.no_track) as run:
        return _train_job(cfg, kind, args, run, record)


def _training_settings(cfg: dict, kind: str) -> dict:
    """``value_functions.<kind>`` without its ``validation`` section: what the training reads (the
    validation jobs read the rest; a validation setting never reruns a training)."""
    return {k: v for k, v in cfg["value_functions"][kind].items() if k != "validation"}


EXIT_PAUSED = 75   # EX_TEMPFAIL: --time-limit reached, checkpoint kept; run the same command again


def _paused(run, kind: str, where: str, ckpt: Path, args) -> int:
    """An unfinished training piece: say where it stopped; exit :data:`EXIT_PAUSED` when the time
    limit stopped it (a piece of a longer run), 0 for ``--stop-after``."""
    run.log_params({"completed": False})
    print(f"{kind}: stopped after {where}; checkpoints in {ckpt.parent}; run the same command again to resume")
    return EXIT_PAUSED if args.time_limit is not None else 0


def _train_job(cfg: dict, kind: str, args, run, record: JobRecord) -> int:
    """The training job inside its live run (the stages: :func:`madpinn.value_functions.train.train_stages`):
    the loss curve is logged as it trains (window means, ≤ :data:`LIVE_POINTS` points)."""
    from dataclasses import replace

    import numpy as np

    from madpinn.tracking.mlflow_store import git_commit
    from madpinn.value_functions import figures
    from madpinn.value_functions.build import problem_from_config, training_seed
    from madpinn.value_functions.train import save_trained_model, train_stages
    from madpinn.value_functions.train_settings import TrainSettings, stage_iterations

    seed = training_seed(cfg, kind)
    device, dtype = _setup(cfg, args.threads, seed)
    problem = problem_from_config(cfg, kind)
    vcfg = _training_settings(cfg, kind)
    settings = TrainSettings.from_config(vcfg, seed)
    models = parse_models(args.model)
    if "init" in models:   # the workflow resolves value_functions.<kind>.init_from and passes it in
        settings = replace(settings, init_from=str(models["init"]))
    out = Path(args.out)
    ckpt = Path(args.checkpoint) if args.checkpoint else out.parent / "checkpoints" / f"{out.stem}.ckpt.pt"
    chash = record.params["config_hash"]
    resume_hash = record.params["schedule_hash"]   # = chash unless stop_at ends the run inside its schedule
    total = stage_iterations(settings, vcfg["fine_tune"])
    every = max(1, -(-total // LIVE_POINTS))   # ceil: at most LIVE_POINTS points
    deadline = None if args.time_limit is None else time.monotonic() + args.time_limit
    net, info = train_stages(problem, settings, vcfg.get("fine_tune"), ckpt, out.with_name(f"{out.stem}_stage1.pt"), resume_hash,
                             device, dtype, progress=not args.no_progress, stop_after=args.stop_after,
                             on_iteration=run.curve("loss", every), deadline=deadline)
    if not info["completed"]:
        where = (f"{info['iterations']} of {settings.end_iteration} iterations" if info["stage"] == "train"
                 else f"fine-tuning, {info['iterations']} of {total} iterations in all")
        return _paused(run, kind, where, ckpt, args)
    model = save_trained_model(problem, net, settings, info, vcfg, chash, out, device, dtype)
    history = info["history"]
    stem = out.with_suffix("")
    loss_csv = stem.with_name(stem.name + "_loss.csv")
    np.savetxt(loss_csv, np.asarray(history), header="loss", comments="", fmt="%.8g")
    artifacts = [out, loss_csv, figures.loss_curve(history, f"{kind} training", stem.with_name(stem.name + "_loss.png"))]
    artifacts += figure_of(model, cfg, kind, stem.with_name(stem.name + "_figure"))
    # the run's own record (timing, commit) beside the model, never in it: identical weights, identical file
    summary = {"kind": kind, "iterations": info["iterations"], "wall_s": info["wall_s"], "git_commit": git_commit(),
               "final_loss": model.meta["final_loss"], **model.meta["residual"]}
    write_json(stem.with_name(stem.name + "_train.json"), summary)
    record.artifacts = artifacts
    record.metrics = {k: v for k, v in summary.items() if isinstance(v, (int, float))}
    record.step = info["iterations"]
    record.models = {f"{kind}_network": net}
    record.register = {f"{kind}_network": record.job_key.rpartition("/")[2]}   # vs, vhat, vhat_<variant>
    return finish(run, record, echo=summary)


def _validate_vs(args) -> int:
    from madpinn.value_functions import load_vs
    from madpinn.value_functions.validation import vs_rollouts

    cfg = config_of(args)
    record = JobRecord(job_key="validate/vs", rule="validate_vs")
    with job(cfg, record, not args.no_track) as run:
        device, dtype = _setup(cfg, args.threads, int(cfg["value_functions"]["seed"]))
        vs = load_vs(single_model(args.model, "vs"), device=device, dtype=dtype)
        val = cfg["value_functions"]["vs"]["validation"]
        stats = vs_rollouts(vs, int(val["rollout_samples"]), float(val["rollout_dt"]), seed=int(cfg["value_functions"]["seed"]))
        stats["target_false_safe_rate"] = 0.01
        stats["model_iterations"] = vs.meta.get("iterations")
        stats["residual"] = vs.meta.get("residual")
        out = write_json(args.out, stats)
        record.artifacts = [out, *figure_of(vs, cfg, "vs", Path(args.fig_stem))]
        record.metrics = {k: v for k, v in stats.items() if isinstance(v, (int, float))}
        return finish(run, record, echo={k: stats[k] for k in ("false_safe_rate", "mean_abs_error", "predicted_safe_fraction")})


def _validate_vhat(args) -> int:
    from madpinn.value_functions import load_vhat
    from madpinn.value_functions.train import residual_stats

    cfg = config_of(args)
    record = JobRecord(job_key="validate/vhat", rule="validate_vhat")
    with job(cfg, record, not args.no_track) as run:
        device, dtype = _setup(cfg, args.threads, int(cfg["value_functions"]["seed"]))
        vhat = load_vhat(single_model(args.model, "vhat"), device=device, dtype=dtype)
        samples = int(cfg["value_functions"]["vhat"]["validation"]["samples"])
        stats = residual_stats(vhat.problem, vhat, samples, seed=int(cfg["value_functions"]["seed"]) + 1)
        stats.update({"model_iterations": vhat.meta.get("iterations"), "z_max": vhat.z_max, "horizon": vhat.horizon})
        record.artifacts = [write_json(args.out, stats)]
        record.metrics = {k: v for k, v in stats.items() if isinstance(v, (int, float))}
        return finish(run, record, echo=stats)


def _heatmap(args) -> int:
    from madpinn.value_functions import load_vhat
    from madpinn.value_functions.figures import HEATMAP_POINTS, value_heatmap
    from madpinn.value_functions.heatmap_reading import write_reading
    from madpinn.value_functions.validation import heatmap_values

    cfg = config_of(args)
    record = JobRecord(job_key="figure/fig_value_heatmap", rule="fig_value_heatmap")
    with job(cfg, record, not args.no_track) as run:
        device, dtype = _setup(cfg, args.threads, int(cfg["value_functions"]["seed"]))
        vhat = load_vhat(single_model(args.model, "vhat"), device=device, dtype=dtype)
        axis, z_star, feasible, _ = heatmap_values(vhat, deployed_z_tolerance(cfg), cfg["arenas"]["small"]["half_width"],
                                                   HEATMAP_POINTS)
        stem = Path(args.out_stem)
        record.artifacts = [*value_heatmap(axis, z_star, feasible, stem),   # the figure, as figure_of draws it
                            *write_reading(axis, z_star, feasible, float(cfg["agents"]["collision_radius"]),
                                           stem.with_suffix(".json"))]
        return finish(run, record, echo=list(record.artifacts))


def _solve_vs_grid(args) -> int:
    from madpinn.dynamics.pair import PairSystem
    from madpinn.value_functions.grid_reference import GridSettings, save_solution, solve_reference

    cfg = config_of(args)
    record = JobRecord(job_key="validate/vs_grid_solution", rule="solve_vs_grid")
    with job(cfg, record, not args.no_track) as run:
        system = PairSystem.from_config(cfg)
        settings = GridSettings.from_config(cfg["value_functions"]["vs"]["validation"]["grid"])
        fine, coarse, conv = solve_reference(system, settings, progress=not args.no_progress)
        extra = {"convergence": conv, "coarse_nodes": coarse.meta["nodes"], "wall_s_coarse": coarse.wall_s}
        save_solution(args.out, fine, system, settings, extra)
        record.metrics = {"nodes": settings.nodes, "wall_s": fine.wall_s, "wall_s_coarse": coarse.wall_s,
                          **{f"coarse_mae_t{t}": m["mae"] for t, m in conv.items()}}
        return finish(run, record, echo=dict(record.metrics))


def _validate_vs_grid(args) -> int:
    import torch

    from madpinn.value_functions import figures, load_vs
    from madpinn.value_functions.grid_reference import compare_vs, load_solution

    cfg = config_of(args)
    record = JobRecord(job_key="validate/vs_grid", rule="validate_vs_grid")
    with job(cfg, record, not args.no_track) as run:
        _setup(cfg, args.threads, int(cfg["value_functions"]["seed"]))
        vs = load_vs(single_model(args.model, "vs"), dtype=torch.float64)
        solution, header = load_solution(args.grid)
        report = compare_vs(vs, solution, header)
        out = write_json(args.out, report)
        figs = figures.vs_grid_figure(solution, vs, figures.VS_GRID_VELOCITIES, Path(args.fig_stem))
        record.artifacts = [out, *figs]
        record.metrics = {f"{k}_t{t}": m[k] for t, m in report["vs_vs_grid"].items() for k in ("mae", "unsafe_called_safe")}
        return finish(run, record, echo={"meets_target": report["meets_target"], **record.metrics})


def _verify_vhat(args) -> int:
    from madpinn.value_functions import load_vhat
    from madpinn.value_functions.verification import ScenarioSettings, verify

    cfg = config_of(args)
    model = single_model(args.model, "vhat")
    record = JobRecord(job_key=f"validate/{Path(model).stem}_scenario", rule="verify_vhat")   # vhat_<variant>.pt: its own key
    with job(cfg, record, not args.no_track) as run:
        device, dtype = _setup(cfg, args.threads, int(cfg["value_functions"]["seed"]))
        settings = ScenarioSettings.from_config(cfg["value_functions"]["vhat"]["validation"]["scenario"])
        vhat = load_vhat(model, device=device, dtype=dtype)
        tol = deployed_z_tolerance(cfg)
        report = {"model": str(model), "model_iterations": vhat.meta.get("iterations"),
                  "model_config_hash": vhat.meta.get("config_hash"), "horizon": vhat.horizon,
                  "uniform": verify(vhat, settings, False, tol), "conflict": verify(vhat, settings, True, tol)}
        record.artifacts = [write_json(args.out, report)]
        record.metrics = {f"{d}_{k}_rate": report[d][k]["rate"] for d in ("uniform", "conflict") for k in ("safety", "any")}
        return finish(run, record, echo=dict(record.metrics))


def _pairs(items: list[str] | None, what: str) -> dict[str, list[str]]:
    """``["a=x", "a=y", "b=z"]`` -> ``{"a": ["x", "y"], "b": ["z"]}`` (repeatable NAME=PATH options)."""
    from madpinn.config import ConfigError

    out: dict[str, list[str]] = {}
    for item in items or []:
        name, sep, path = item.partition("=")
        if not sep or not name or not path:
            raise ConfigError(f"{what} expects NAME=PATH, got '{item}'")
        out.setdefault(name, []).append(path)
    return out


def _ship_models(args) -> int:
    """Every file and report is read and checked before ``models/`` is touched: a bad file stops
    the command with one line and leaves ``models/`` and its manifest byte-identical."""
    from madpinn.config import ConfigError
    from madpinn.value_functions.shipping import ship

    models = {k: str(p) for k, p in parse_models(args.model).items()}
    if not models:
        raise ConfigError("pass at least one --model NAME=PATH")
    manifest = ship(models, args.out_dir, _pairs(args.validation, "--validation"), device=args.device,
                    defaults=_provenance(args, models))
    print(json.dumps({k: {f: e.get(f) for f in ("sha256", "bytes", "iterations", "samples")}
                      for k, e in manifest["models"].items()}, indent=2))
    return 0


def _provenance(args, models: dict) -> dict:
    """What a checkpoint does not carry itself (the MARL policies store neither), read before
    anything is written: the training hash of ``--config`` (:func:`madpinn.marl_hash.marl_training_hash`,
    which the shipped overlay checks) and ``--git-commit`` (the training job's commit, e.g. from
    its MLflow run). Name -> entry fields used where the checkpoint's own are missing."""
    from madpinn.config import ConfigError, load_config
    from madpinn.marl_hash import is_marl_model, marl_training_hash
    from madpinn.value_functions.shipping import describe_checkpoint, read_model_file

    cfg = load_config(args.config) if args.config else None
    defaults = {}
    for name, path in models.items():
        fields = {"git_commit": args.git_commit} if args.git_commit else {}
        if is_marl_model(name) and describe_checkpoint(read_model_file(path, name))["training_config_hash"] is None:
            if cfg is None:
                raise ConfigError(f"{name}: the checkpoint records no training hash; pass --config (the training configuration)")
            fields["training_config_hash"] = marl_training_hash(cfg, name)
        defaults[name] = fields
    return defaults


def _install_shipped(args) -> int:
    from madpinn.value_functions.shipping import install, read_manifest

    if not args.config:                       # by hand, without a config: no MLflow run
        print(install(args.dir, args.name, args.out))
        return 0
    from madpinn.commands.shipped_runs import log_training_curves, manifest_metrics, network, training_log

    cfg = config_of(args)
    entry = read_manifest(args.dir)["models"].get(args.name, {})
    log = training_log(Path(args.dir) / f"{args.name}.pt", entry.get("sha256", ""))
    # the run of a shipped training: manifest entry, the committed training log's curves, the network
    record = JobRecord(job_key=f"install/{args.name}", rule="install_shipped_model", wildcards={"name": args.name},
                       params={"dir": args.dir, "sha256": entry.get("sha256"), "git_commit": entry.get("git_commit"),
                               "training_config_hash": entry.get("training_config_hash"), "device": entry.get("device"),
                               "init_from": entry.get("init_from")},
                       tags={"madpinn.training_log": str(log.relative_to(REPO_ROOT)) if log else
                             "none committed (trained before training logs were kept; summary: models/manifest.json)"})
    with job(cfg, record, not args.no_track) as run:
        out = install(args.dir, args.name, args.out)
        if log is not None:
            log_training_curves(run, log)
        record.artifacts = [out, *([log] if log else [])]
        record.metrics = manifest_metrics(entry)
        record.step = int(entry.get("iterations") or 0)
        record.models = {f"{args.name}_network": network(out, args.name)}
        record.register = {f"{args.name}_network": args.name}
        return finish(run, record, echo=[out])


def register(sub) -> None:
    def common(p, model: str | None):
        add_config_arg(p)
        add_model_arg(p, (model,) if model else ("init",))
        add_job_args(p, threads_default=None, progress=False)

    p = sub.add_parser("train-value", help="train V̂ or V_s (resumes from its checkpoint)")
    common(p, None)
    p.add_argument("--kind", required=True, choices=KINDS)
    p.add_argument("--variant", default=None, metavar="NAME",
                   help="train variant NAME of --kind: value_functions.<kind>_variants.NAME deep-merged over "
                        "value_functions.<kind>, its `agents` (an agent model) over agents (its settings and training hash; "
                        "issues 33, 63)")
    p.add_argument("--out", required=True, help="final model file (.pt)")
    p.add_argument("--checkpoint", default=None, help="resume checkpoint (default <out dir>/checkpoints/<out stem>.ckpt.pt)")
    p.add_argument("--stop-after", type=int, default=None, help="stop after this many iterations (testing resume)")
    p.add_argument("--time-limit", type=_seconds, default=None, metavar="SECONDS",
                   help=f"stop after the first iteration that ends past this many seconds, keeping a checkpoint, "
                        f"and exit {EXIT_PAUSED}: long trainings as time-boxed pieces (docs/reference/value_functions.md)")
    p.add_argument("--no-progress", action="store_true")
    p.set_defaults(func=_train, reads=lambda cfg, kind, variant=None: training(cfg, kind, variant))

    p = sub.add_parser("validate-vs", help="V_s rollout verification (false-safe rate) and slices figure")
    common(p, "vs")
    p.add_argument("--out", required=True, help="JSON report")
    p.add_argument("--fig-stem", required=True, help="figure path without extension (.pdf and .png written)")
    p.set_defaults(func=_validate_vs, reads=keys("value_functions.vs.validation", *VF_RUN))

    p = sub.add_parser("validate-vhat", help="V̂ held-out HJB residual statistics")
    common(p, "vhat")
    p.add_argument("--out", required=True, help="JSON report")
    p.set_defaults(func=_validate_vhat, reads=keys("value_functions.vhat.validation.samples", *VF_RUN))

    p = sub.add_parser("fig-value-heatmap", help="paper figure: learned value over the ego position")
    common(p, "vhat")
    p.add_argument("--out-stem", required=True, help="figure path without extension (.pdf, .png and the reading's .json)")
    p.set_defaults(func=_heatmap, reads=keys("arenas.small.half_width", "agents.collision_radius", Z_TOL, *VF_RUN))

    p = sub.add_parser("solve-vs-grid", help="grid reference of V_s (hj_reachability) with its convergence check")
    add_config_arg(p)
    add_job_args(p, threads_default=None)
    p.add_argument("--out", required=True, help="solution file (.npz)")
    p.set_defaults(func=_solve_vs_grid, reads=keys("agents", "value_functions.vs.horizon", "value_functions.vs.p_range",
                                                   "value_functions.vs.v_range", "value_functions.vs.validation.grid"))

    p = sub.add_parser("validate-vs-grid", help="V_s against the grid reference: MAE, sign agreement, false safe")
    common(p, "vs")
    p.add_argument("--grid", required=True, help="solution file of solve-vs-grid (.npz)")
    p.add_argument("--out", required=True, help="JSON report")
    p.add_argument("--fig-stem", required=True, help="figure path without extension (.pdf and .png written)")
    p.set_defaults(func=_validate_vs_grid, reads=keys(*VF_RUN))

    p = sub.add_parser("verify-vhat", help="scenario-based (ε, β) verification of V̂ in the exact 3-agent dynamics")
    common(p, "vhat")
    p.add_argument("--out", required=True, help="JSON report")
    p.set_defaults(func=_verify_vhat, reads=keys("value_functions.vhat.validation.scenario", Z_TOL, *VF_RUN))

    p = sub.add_parser("ship-models", help="copy trained models into models/ and record them in models/manifest.json")
    add_model_arg(p, ("vs", "vhat", "safemarl_nominal", "defmarl_<variant>", "..."))
    p.add_argument("--validation", action="append", help="NAME=JSON report stored with the entry (repeatable)")
    p.add_argument("--out-dir", default="models", help="shipped-models directory (default models/)")
    p.add_argument("--device", default=None, help="device the models were trained on, when the checkpoint does not say")
    p.add_argument("--config", nargs="+", default=None,
                   help="training configuration (+ overlays): records the training hash of MARL policies, whose checkpoints lack it")
    p.add_argument("--git-commit", default=None, help="commit that trained the models, when the checkpoint does not say")
    p.set_defaults(func=_ship_models)

    p = sub.add_parser("install-shipped", help="copy a shipped model to OUT after checking its sha256")
    p.add_argument("--dir", default="models", help="shipped-models directory with manifest.json")
    p.add_argument("--name", required=True, help="model name in the manifest (vs, vhat, safemarl_nominal, ...)")
    p.add_argument("--out", required=True, help="destination, e.g. results/models/vs.pt")
    p.add_argument("--config", nargs="+", default=None,
                   help="config file(s): the job is logged as an MLflow run (the workflow passes it)")
    p.add_argument("--no-track", action="store_true", help="do not log to MLflow")
    p.set_defaults(func=_install_shipped)

    from madpinn.commands.calibration import register as register_calibration   # calibrate-vhat (issue 62): its own module,

    register_calibration(sub)                        # so that no other job of this family changes its code hash
