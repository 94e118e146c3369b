"""CLI commands of the value functions (listed in ``madpinn.cli.COMMAND_MODULES``):

- ``train-value --kind vhat|vs``: train (resumable), write the model, loss CSV/figure, MLflow run;
- ``validate-vs``: rollout verification JSON + V_s slices figure;
- ``validate-vhat``: held-out HJB residual statistics JSON;
- ``fig-value-heatmap``: the paper's V̂ heatmap (.pdf, .png);
- ``solve-vs-grid``: the hj_reachability grid reference of V_s (.npz) with its convergence check;
- ``validate-vs-grid``: V_s against the grid reference (JSON + zero-level-set figure);
- ``verify-vhat``: scenario-based (ε, β) verification of V̂ (uniform and conflict states);
- ``ship-models`` / ``install-shipped``: ``models/`` + ``manifest.json``; sha256-checked install.
"""

from __future__ import annotations

import json
from pathlib import Path

from madpinn.config import config_hash, load_config
from madpinn.observation import DEPLOYMENT_ONLY_KEYS

KINDS = ("vhat", "vs")
LIVE_POINTS = 1000   # training curves: at most this many live MLflow points per run


def problem_from_config(cfg: dict, kind: str):
    from madpinn.dynamics.epigraph import EpigraphSystem
    from madpinn.dynamics.pair import PairSystem
    from madpinn.value_functions.problems import EpigraphProblem, PairProblem
    from madpinn.value_functions.sampling import ConflictSampling

    if kind == "vhat":
        return EpigraphProblem(EpigraphSystem.from_config(cfg),
                               ConflictSampling.from_config(cfg["value_functions"]["vhat"]))
    return PairProblem(PairSystem.from_config(cfg), ConflictSampling.from_config(cfg["value_functions"]["vs"]))


def training_hash(cfg: dict, kind: str) -> str:
    """Hash of everything the trained weights depend on (not validation settings)."""
    vcfg = {k: v for k, v in cfg["value_functions"][kind].items() if k != "validation"}
    if not vcfg.get("velocity_saturation", True):   # off = the dynamics every earlier model was trained with: same hash
        vcfg.pop("velocity_saturation")
    observation = {k: v for k, v in cfg["observation"].items() if k not in DEPLOYMENT_ONLY_KEYS}   # deployment-only keys do not retrain
    return config_hash({"kind": kind, "agents": cfg["agents"], "observation": observation, "vf": vcfg,
                        "seed": cfg["value_functions"]["seed"], "dtype": cfg["dtype"]})


def _setup(cfg: dict, threads: int | None):
    from madpinn.device import resolve_device, resolve_dtype, seed_everything

    seed_everything(int(cfg["value_functions"]["seed"]), threads or int(cfg["value_functions"]["threads"]))
    return resolve_device(cfg["device"]), resolve_dtype(cfg["dtype"])


def validation_figure(model, cfg: dict, kind: str, stem: Path) -> list[Path]:
    from madpinn.value_functions import figures, validation

    if kind == "vhat":
        axis, z_star, feasible, _ = validation.heatmap_values(model, cfg["arenas"]["small"]["half_width"])
        return figures.value_heatmap(axis, z_star, feasible, stem)
    vels = cfg["value_functions"]["vs"]["validation"]["slice_velocities"]
    axis, values = validation.vs_slices(model, vels)
    return figures.vs_slices_figure(axis, values, vels, model.collision_radius, stem)


def _train(args) -> int:
    from madpinn.tracking import job_run

    cfg = load_config(args.config)
    kind = args.kind
    vcfg = cfg["value_functions"][kind]
    with job_run(cfg, job_key=f"train/{kind}", rule=f"train_{kind}", wildcards={"kind": kind},
                 params={"settings": {**vcfg, "seed": cfg["value_functions"]["seed"]},
                         "config_hash": training_hash(cfg, kind)}, track=not args.no_track) as run:
        return _train_job(cfg, kind, args, run)


def _train_job(cfg: dict, kind: str, args, run) -> int:
    import numpy as np

    from madpinn.tracking.mlflow_store import git_commit
    from madpinn.value_functions import figures
    from madpinn.value_functions.model import model_from_payload, model_payload, save_atomic
    from madpinn.value_functions.train import TrainSettings, residual_stats, train

    device, dtype = _setup(cfg, args.threads)
    problem = problem_from_config(cfg, kind)
    vcfg = cfg["value_functions"][kind]
    settings = TrainSettings.from_config(vcfg, cfg["value_functions"]["seed"])
    if settings.init_from and not Path(settings.init_from).is_absolute():
        settings.init_from = str(Path(cfg["paths"]["results"]) / settings.init_from)
    out = Path(args.out)
    ckpt = Path(args.checkpoint) if args.checkpoint else out.parent / "checkpoints" / f"{kind}.ckpt.pt"
    chash = training_hash(cfg, kind)
    total = settings.iterations + int((vcfg.get("fine_tune") or {}).get("iterations", 0))
    every = max(1, -(-total // LIVE_POINTS))   # ceil: at most LIVE_POINTS points
    net, info = train(problem, settings, ckpt, chash, device=device, dtype=dtype, progress=not args.no_progress,
                      stop_after=args.stop_after, on_iteration=run.curve("loss", every))
    if not info["completed"]:
        run.log_params({"completed": False})
        print(f"{kind}: stopped after {info['iterations']} of {settings.iterations} iterations; checkpoint {ckpt}")
        return 0
    if vcfg.get("fine_tune"):
        net, info = _fine_tune(problem, settings, net, info, vcfg["fine_tune"], out, ckpt, chash, device, dtype, args,
                               on_iteration=run.curve("loss", every, offset=info["iterations"]))
        if not info["completed"]:
            run.log_params({"completed": False})
            return 0
    history = info["history"]
    meta = {"config_hash": chash, "git_commit": git_commit(), "iterations": info["iterations"], "wall_s": info["wall_s"],
            "init_from": settings.init_from, "batch_offset": info["batch_offset"],
            "final_loss": float(np.mean(history[-100:])), "settings": {**vcfg, "seed": settings.seed}}
    model = model_from_payload(model_payload(problem, net, settings.output_scale, meta), device=device, dtype=dtype)
    val = vcfg.get("validation", {})
    samples = int(val.get("samples", val.get("rollout_samples", 65536)))
    meta["residual"] = residual_stats(problem, model, samples, settings.seed)
    save_atomic(model_payload(problem, net, settings.output_scale, meta), out)
    stem = out.with_suffix("")
    loss_csv = stem.with_name(stem.name + "_loss.csv")
    np.savetxt(loss_csv, np.asarray(history), header="loss", comments="", fmt="%.8g")
    artifacts = [out, loss_csv, figures.loss_curve(history, f"{kind} training", stem.with_name(stem.name + "_loss.png"))]
    artifacts += validation_figure(model, cfg, kind, stem.with_name(stem.name + "_figure"))
    summary = {"kind": kind, "iterations": info["iterations"], "wall_s": info["wall_s"], "final_loss": meta["final_loss"],
               **meta["residual"]}
    Path(stem.with_name(stem.name + "_train.json")).write_text(json.dumps(summary, indent=2))
    run.finish(metrics={k: v for k, v in summary.items() if isinstance(v, (int, float))}, step=info["iterations"],
               artifacts=artifacts, models={f"{kind}_network": net})
    print(json.dumps(summary))
    return 0


def _fine_tune(problem, settings, net, info, ft: dict, out: Path, ckpt: Path, chash: str, device, dtype, args,
               on_iteration=None):
    """Second stage of ``value_functions.<kind>.fine_tune``: save the first stage's model next to
    ``out`` (``<kind>_stage1.pt``), then train from it with a fresh optimizer and schedule
    (:func:`madpinn.value_functions.train.load_initial_weights`; no curriculum, its batches
    continue the first stage's stream). Returns ``(network, info)`` over both stages."""
    from dataclasses import replace

    from madpinn.value_functions.model import model_payload, save_atomic
    from madpinn.value_functions.train import train

    stage1 = out.with_name(f"{out.stem}_stage1.pt")
    save_atomic(model_payload(problem, net, settings.output_scale,
                              {"config_hash": chash, "iterations": info["iterations"], "batch_offset": info["batch_offset"],
                               "wall_s": info["wall_s"]}), stage1)
    s2 = replace(settings, iterations=int(ft["iterations"]), lr=float(ft["lr"]), lr_final=float(ft["lr_final"]),
                 curriculum_fraction=0.0, init_from=str(stage1))
    net2, info2 = train(problem, s2, ckpt.with_name(ckpt.name.replace(".ckpt", ".fine_tune.ckpt")), chash + "/fine_tune",
                        device=device, dtype=dtype, progress=not args.no_progress, stop_after=args.stop_after,
                        on_iteration=on_iteration)
    if not info2["completed"]:
        print(f"{problem.kind}: fine-tuning stopped after {info2['iterations']} of {s2.iterations} iterations")
    return net2, {"history": info["history"] + info2["history"], "iterations": info["iterations"] + info2["iterations"],
                  "wall_s": info["wall_s"] + info2["wall_s"], "completed": info2["completed"],
                  "batch_offset": info["batch_offset"]}


def _validate_vs(args) -> int:
    from madpinn.tracking import job_run
    from madpinn.value_functions import load_vs
    from madpinn.value_functions.validation import vs_rollouts

    cfg = load_config(args.config)
    with job_run(cfg, job_key="validate/vs", rule="validate_vs", track=not args.no_track) as run:
        device, dtype = _setup(cfg, args.threads)
        vs = load_vs(args.model, device=device, dtype=dtype)
        val = cfg["value_functions"]["vs"]["validation"]
        stats = vs_rollouts(vs, int(val["rollout_samples"]), float(val["rollout_dt"]), seed=int(cfg["value_functions"]["seed"]))
        stats["target_false_safe_rate"] = 0.01
        stats["model_iterations"] = vs.meta.get("iterations")
        stats["residual"] = vs.meta.get("residual")
        out = Path(args.out)
        out.parent.mkdir(parents=True, exist_ok=True)
        out.write_text(json.dumps(stats, indent=2))
        figs = validation_figure(vs, cfg, "vs", Path(args.fig_stem))
        run.finish(metrics={k: v for k, v in stats.items() if isinstance(v, (int, float))}, artifacts=[out, *figs])
    print(json.dumps({k: stats[k] for k in ("false_safe_rate", "mean_abs_error", "predicted_safe_fraction")}))
    return 0


def _validate_vhat(args) -> int:
    from madpinn.tracking import job_run
    from madpinn.value_functions import load_vhat
    from madpinn.value_functions.train import residual_stats

    cfg = load_config(args.config)
    with job_run(cfg, job_key="validate/vhat", rule="validate_vhat", track=not args.no_track) as run:
        device, dtype = _setup(cfg, args.threads)
        vhat = load_vhat(args.model, device=device, dtype=dtype)
        samples = int(cfg["value_functions"]["vhat"]["validation"]["samples"])
        stats = residual_stats(vhat.problem, vhat, samples, seed=int(cfg["value_functions"]["seed"]) + 1)
        stats.update({"model_iterations": vhat.meta.get("iterations"), "z_max": vhat.z_max, "horizon": vhat.horizon})
        out = Path(args.out)
        out.parent.mkdir(parents=True, exist_ok=True)
        out.write_text(json.dumps(stats, indent=2))
        run.finish(metrics={k: v for k, v in stats.items() if isinstance(v, (int, float))}, artifacts=[out])
    print(json.dumps(stats))
    return 0


def _heatmap(args) -> int:
    from madpinn.tracking import job_run
    from madpinn.value_functions import load_vhat

    cfg = load_config(args.config)
    with job_run(cfg, job_key="figure/fig_value_heatmap", rule="fig_value_heatmap", track=not args.no_track) as run:
        device, dtype = _setup(cfg, args.threads)
        vhat = load_vhat(args.model, device=device, dtype=dtype)
        files = validation_figure(vhat, cfg, "vhat", Path(args.out_stem))
        run.finish(artifacts=files)
    print("\n".join(map(str, files)))
    return 0


def grid_settings(cfg: dict):
    from madpinn.value_functions.grid_reference import GridSettings

    return GridSettings.from_dict(cfg["value_functions"]["vs"]["validation"]["grid"])


def _solve_vs_grid(args) -> int:
    from madpinn.dynamics.pair import PairSystem
    from madpinn.tracking import log_job
    from madpinn.value_functions.grid_reference import save_solution, solve_reference

    cfg = load_config(args.config)
    system, settings = PairSystem.from_config(cfg), grid_settings(cfg)
    fine, coarse, conv = solve_reference(system, settings, progress=not args.no_progress)
    extra = {"convergence": conv, "coarse_nodes": coarse.meta["nodes"], "wall_s_coarse": coarse.wall_s}
    save_solution(args.out, fine, system, settings, extra)
    summary = {"nodes": settings.nodes, "wall_s": fine.wall_s, "wall_s_coarse": coarse.wall_s,
               **{f"coarse_mae_t{t}": m["mae"] for t, m in conv.items()}}
    if not args.no_track:
        log_job(cfg, job_key="validate/vs_grid_solution", rule="solve_vs_grid", wildcards={}, metrics=summary,
                artifacts=[])
    print(json.dumps(summary))
    return 0


def _validate_vs_grid(args) -> int:
    from madpinn.tracking import log_job
    from madpinn.value_functions import figures, load_vs
    from madpinn.value_functions.grid_reference import compare_vs, load_solution

    cfg = load_config(args.config)
    _setup(cfg, args.threads)
    import torch

    vs = load_vs(args.model, dtype=torch.float64)
    solution, header = load_solution(args.grid)
    report = compare_vs(vs, solution, header)
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(report, indent=2))
    figs = figures.vs_grid_figure(solution, vs, (-3.0, 0.0), Path(args.fig_stem))
    metrics = {f"{k}_t{t}": m[k] for t, m in report["vs_vs_grid"].items() for k in ("mae", "unsafe_called_safe")}
    if not args.no_track:
        log_job(cfg, job_key="validate/vs_grid", rule="validate_vs_grid", wildcards={}, metrics=metrics,
                artifacts=[out, *figs])
    print(json.dumps({"meets_target": report["meets_target"], **metrics}))
    return 0


def _verify_vhat(args) -> int:
    from madpinn.tracking import log_job
    from madpinn.value_functions import load_vhat
    from madpinn.value_functions.verification import ScenarioSettings, verify

    cfg = load_config(args.config)
    device, dtype = _setup(cfg, args.threads)
    settings = ScenarioSettings.from_dict(cfg["value_functions"]["vhat"]["validation"]["scenario"])
    vhat = load_vhat(args.model, device=device, dtype=dtype)
    report = {"model": str(args.model), "model_iterations": vhat.meta.get("iterations"),
              "model_config_hash": vhat.meta.get("config_hash"), "horizon": vhat.horizon,
              "uniform": verify(vhat, settings, conflict=False), "conflict": verify(vhat, settings, conflict=True)}
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(report, indent=2))
    metrics = {f"{d}_{k}_rate": report[d][k]["rate"] for d in ("uniform", "conflict") for k in ("safety", "any")}
    if not args.no_track:
        log_job(cfg, job_key="validate/vhat_scenario", rule="verify_vhat", wildcards={}, metrics=metrics, artifacts=[out])
    print(json.dumps(metrics))
    return 0


def _pairs(items, what: str) -> dict:
    out = {}
    for item in items or []:
        name, sep, path = item.partition("=")
        if not sep or not name or not path:
            raise SystemExit(f"{what} must be NAME=PATH, got {item!r}")
        out.setdefault(name, []).append(path)
    return out


def _ship_models(args) -> int:
    from madpinn.value_functions.shipping import ship

    models = {k: v[-1] for k, v in _pairs(args.model, "--model").items()}
    manifest = ship(models, args.out_dir, _pairs(args.validation, "--validation"), device=args.device)
    print(json.dumps({k: {f: e[f] for f in ("sha256", "bytes", "iterations", "samples")}
                      for k, e in manifest["models"].items()}, indent=2))
    return 0


def _install_shipped(args) -> int:
    from madpinn.value_functions.shipping import install

    print(install(args.dir, args.name, args.out))
    return 0


def register(sub) -> None:
    from madpinn.cli import add_config_arg

    def common(p, model=True):
        add_config_arg(p)
        if model:
            p.add_argument("--model", required=True, help="trained model file")
        p.add_argument("--threads", type=int, default=None, help="torch threads (default value_functions.threads)")
        p.add_argument("--no-track", action="store_true")

    p = sub.add_parser("train-value", help="train V̂ or V_s (resumes from its checkpoint)")
    common(p, model=False)
    p.add_argument("--kind", required=True, choices=KINDS)
    p.add_argument("--out", required=True, help="final model file (.pt)")
    p.add_argument("--checkpoint", default=None, help="resume checkpoint (default <out dir>/checkpoints/<kind>.ckpt.pt)")
    p.add_argument("--stop-after", type=int, default=None, help="stop after this many iterations (testing resume)")
    p.add_argument("--no-progress", action="store_true")
    p.set_defaults(func=_train)

    p = sub.add_parser("validate-vs", help="V_s rollout verification (false-safe rate) and slices figure")
    common(p)
    p.add_argument("--out", required=True, help="JSON report")
    p.add_argument("--fig-stem", required=True, help="figure path without extension (.pdf and .png written)")
    p.set_defaults(func=_validate_vs)

    p = sub.add_parser("validate-vhat", help="V̂ held-out HJB residual statistics")
    common(p)
    p.add_argument("--out", required=True, help="JSON report")
    p.set_defaults(func=_validate_vhat)

    p = sub.add_parser("fig-value-heatmap", help="paper figure: learned value over the ego position")
    common(p)
    p.add_argument("--out-stem", required=True, help="figure path without extension (.pdf and .png written)")
    p.set_defaults(func=_heatmap)

    p = sub.add_parser("solve-vs-grid", help="grid reference of V_s (hj_reachability) with its convergence check")
    common(p, model=False)
    p.add_argument("--out", required=True, help="solution file (.npz)")
    p.add_argument("--no-progress", action="store_true")
    p.set_defaults(func=_solve_vs_grid)

    p = sub.add_parser("validate-vs-grid", help="V_s against the grid reference: MAE, sign agreement, false safe")
    common(p)
    p.add_argument("--grid", required=True, help="solution file of solve-vs-grid (.npz)")
    p.add_argument("--out", required=True, help="JSON report")
    p.add_argument("--fig-stem", required=True, help="figure path without extension (.pdf and .png written)")
    p.set_defaults(func=_validate_vs_grid)

    p = sub.add_parser("verify-vhat", help="scenario-based (ε, β) verification of V̂ in the exact 3-agent dynamics")
    common(p)
    p.add_argument("--out", required=True, help="JSON report")
    p.set_defaults(func=_verify_vhat)

    p = sub.add_parser("ship-models", help="copy trained models into models/ and record them in models/manifest.json")
    p.add_argument("--model", action="append", required=True, help="NAME=PATH (repeatable), e.g. vs=results/models/vs.pt")
    p.add_argument("--validation", action="append", help="NAME=JSON report stored with the entry (repeatable)")
    p.add_argument("--out-dir", default="models", help="shipped-models directory (default models/)")
    p.add_argument("--device", default=None, help="device the models were trained on, when the checkpoint does not say")
    p.set_defaults(func=_ship_models)

    p = sub.add_parser("install-shipped", help="copy a shipped model to OUT after checking its sha256")
    p.add_argument("--dir", default="models", help="shipped-models directory with manifest.json")
    p.add_argument("--name", required=True, help="model name in the manifest (vs, vhat, safemarl_nominal, ...)")
    p.add_argument("--out", required=True, help="destination, e.g. results/models/vs.pt")
    p.set_defaults(func=_install_shipped)
