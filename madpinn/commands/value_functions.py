"""Value-function jobs:

- ``train-value --kind vhat|vs``: train (resumable), write the model, loss CSV/figure, MLflow run;
- ``validate-vs``: rollout verification JSON + V_s slices figure;
- ``validate-vhat``: held-out HJB residual statistics JSON;
- ``fig-value-heatmap``: the paper's V̂ heatmap (.pdf, .png).
"""

from __future__ import annotations

import json
from pathlib import Path

from madpinn.commands.args import add_config_arg, add_job_args, add_model_arg, config_of, parse_models, single_model
from madpinn.commands.finish import JobRecord, finish, write_json

KINDS = ("vhat", "vs")
"""value functions: V̂ (epigraph PINN) and V_s (pairwise safety)"""


def _setup(cfg: dict, threads: int | None):
    from madpinn.device import resolve_device, resolve_dtype, seed_everything

    seed_everything(int(cfg["value_functions"]["seed"]), threads or int(cfg["value_functions"]["threads"]))
    return resolve_device(cfg["device"]), resolve_dtype(cfg["dtype"])


def decimate(history, points: int = 5000) -> list[float]:
    """Window means of the per-iteration loss (≤ ``points`` values) for MLflow step metrics."""
    import numpy as np

    h = np.asarray(history, dtype=float)
    w = max(1, int(np.ceil(h.size / points)))
    n = h.size // w
    out = h[: n * w].reshape(n, w).mean(1).tolist()
    if h.size > n * w:
        out.append(float(h[n * w:].mean()))
    return out


def figure_of(model, cfg: dict, kind: str, stem: Path) -> list[Path]:
    from madpinn.value_functions.figures import validation_figure

    return validation_figure(model, kind, cfg["arenas"]["small"]["half_width"],
                             cfg["value_functions"]["vs"]["validation"]["slice_velocities"], stem)


def _train(args) -> int:
    import numpy as np

    from madpinn.tracking.mlflow_store import git_commit
    from madpinn.value_functions import figures
    from madpinn.value_functions.build import problem_from_config, training_hash
    from madpinn.value_functions.model import model_from_payload, model_payload, save_atomic
    from madpinn.value_functions.train import TrainSettings, fine_tune, residual_stats, train

    cfg = config_of(args)
    kind = args.kind
    device, dtype = _setup(cfg, args.threads)
    problem = problem_from_config(cfg, kind)
    vcfg = cfg["value_functions"][kind]
    settings = TrainSettings.from_config(vcfg, cfg["value_functions"]["seed"])
    models = parse_models(args.model)
    if "init" in models:   # the workflow resolves value_functions.<kind>.init_from and passes it in
        settings.init_from = str(models["init"])
    out = Path(args.out)
    ckpt = Path(args.checkpoint) if args.checkpoint else out.parent / "checkpoints" / f"{kind}.ckpt.pt"
    chash = training_hash(cfg, kind)
    progress = not args.no_progress
    net, info = train(problem, settings, ckpt, chash, device=device, dtype=dtype, progress=progress,
                      stop_after=args.stop_after)
    if not info["completed"]:
        print(f"{kind}: stopped after {info['iterations']} of {settings.iterations} iterations; checkpoint {ckpt}")
        return 0
    if vcfg.get("fine_tune"):
        net, info = fine_tune(problem, settings, net, info, vcfg["fine_tune"], out.with_name(f"{out.stem}_stage1.pt"),
                              ckpt, chash, device, dtype, progress=progress, stop_after=args.stop_after)
        if not info["completed"]:
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
    artifacts += figure_of(model, cfg, kind, stem.with_name(stem.name + "_figure"))
    summary = {"kind": kind, "iterations": info["iterations"], "wall_s": info["wall_s"], "final_loss": meta["final_loss"],
               **meta["residual"]}
    write_json(stem.with_name(stem.name + "_train.json"), summary)
    return finish(cfg, JobRecord(
        job_key=f"train/{kind}", rule=f"train_{kind}", wildcards={"kind": kind}, artifacts=artifacts,
        params={"settings": meta["settings"], "config_hash": chash},
        metrics={k: v for k, v in summary.items() if isinstance(v, (int, float))},
        step_metrics={"loss": decimate(history)},
    ), not args.no_track, echo=summary)


def _validate_vs(args) -> int:
    from madpinn.value_functions import load_vs
    from madpinn.value_functions.validation import vs_rollouts

    cfg = config_of(args)
    device, dtype = _setup(cfg, args.threads)
    vs = load_vs(single_model(args.model, "vs"), device=device, dtype=dtype)
    val = cfg["value_functions"]["vs"]["validation"]
    stats = vs_rollouts(vs, int(val["rollout_samples"]), float(val["rollout_dt"]), seed=int(cfg["value_functions"]["seed"]))
    stats["target_false_safe_rate"] = 0.01
    stats["model_iterations"] = vs.meta.get("iterations")
    stats["residual"] = vs.meta.get("residual")
    out = write_json(args.out, stats)
    figs = figure_of(vs, cfg, "vs", Path(args.fig_stem))
    return finish(cfg, JobRecord(
        job_key="validate/vs", rule="validate_vs", artifacts=[out, *figs],
        metrics={k: v for k, v in stats.items() if isinstance(v, (int, float))},
    ), not args.no_track, echo={k: stats[k] for k in ("false_safe_rate", "mean_abs_error", "predicted_safe_fraction")})


def _validate_vhat(args) -> int:
    from madpinn.value_functions import load_vhat
    from madpinn.value_functions.train import residual_stats

    cfg = config_of(args)
    device, dtype = _setup(cfg, args.threads)
    vhat = load_vhat(single_model(args.model, "vhat"), device=device, dtype=dtype)
    samples = int(cfg["value_functions"]["vhat"]["validation"]["samples"])
    stats = residual_stats(vhat.problem, vhat, samples, seed=int(cfg["value_functions"]["seed"]) + 1)
    stats.update({"model_iterations": vhat.meta.get("iterations"), "z_max": vhat.z_max, "horizon": vhat.horizon})
    out = write_json(args.out, stats)
    return finish(cfg, JobRecord(
        job_key="validate/vhat", rule="validate_vhat", artifacts=[out],
        metrics={k: v for k, v in stats.items() if isinstance(v, (int, float))},
    ), not args.no_track, echo=stats)


def _heatmap(args) -> int:
    from madpinn.value_functions import load_vhat

    cfg = config_of(args)
    device, dtype = _setup(cfg, args.threads)
    vhat = load_vhat(single_model(args.model, "vhat"), device=device, dtype=dtype)
    files = figure_of(vhat, cfg, "vhat", Path(args.out_stem))
    return finish(cfg, JobRecord(job_key="figure/fig_value_heatmap", rule="fig_value_heatmap", artifacts=files),
                  not args.no_track, echo=list(files))


def register(sub) -> None:
    def common(p, model: str | None):
        add_config_arg(p)
        add_model_arg(p, (model,) if model else ("init",))
        add_job_args(p, threads_default=None, progress=False)

    p = sub.add_parser("train-value", help="train V̂ or V_s (resumes from its checkpoint)")
    common(p, None)
    p.add_argument("--kind", required=True, choices=KINDS)
    p.add_argument("--out", required=True, help="final model file (.pt)")
    p.add_argument("--checkpoint", default=None, help="resume checkpoint (default <out dir>/checkpoints/<kind>.ckpt.pt)")
    p.add_argument("--stop-after", type=int, default=None, help="stop after this many iterations (testing resume)")
    p.add_argument("--no-progress", action="store_true")
    p.set_defaults(func=_train)

    p = sub.add_parser("validate-vs", help="V_s rollout verification (false-safe rate) and slices figure")
    common(p, "vs")
    p.add_argument("--out", required=True, help="JSON report")
    p.add_argument("--fig-stem", required=True, help="figure path without extension (.pdf and .png written)")
    p.set_defaults(func=_validate_vs)

    p = sub.add_parser("validate-vhat", help="V̂ held-out HJB residual statistics")
    common(p, "vhat")
    p.add_argument("--out", required=True, help="JSON report")
    p.set_defaults(func=_validate_vhat)

    p = sub.add_parser("fig-value-heatmap", help="paper figure: learned value over the ego position")
    common(p, "vhat")
    p.add_argument("--out-stem", required=True, help="figure path without extension (.pdf and .png written)")
    p.set_defaults(func=_heatmap)
