"""One PINN trainer for both value functions (V̂ and V_s).

Each iteration draws a fresh uniform batch of states and curriculum times (DeepReach: times on
``[T − α·T, T]`` with α growing linearly from 0 to 1 over ``curriculum_fraction`` of the
iterations), evaluates the single HJB residual loss (paper eq. ``loss`` / ``HJI-VI``) with the
fused exact derivatives of :class:`~madpinn.value_functions.siren.Siren`, and takes an Adam step.

Fine-tuning: ``init_from`` starts from a trained model's weights with a fresh Adam state and a
fresh learning-rate/curriculum schedule; its batches continue the original run's stream (batch
index = the initial model's iterations + k), so no batch is replayed.

Robustness: the batch of iteration ``k`` is a pure function of ``(seed, k)``, so a run resumed
from a periodic checkpoint (network, Adam state, loss history) ends with the same weights as an
uninterrupted one; a non-finite loss or gradient stops training with :class:`TrainingDiverged`.
"""

from __future__ import annotations

import math
import time
from pathlib import Path
from typing import Callable

import torch
from tqdm.auto import tqdm

from madpinn.value_functions.model import (
    CheckpointError, build_network, model_payload, read_checkpoint, save_atomic,
)
from madpinn.value_functions.problems import PINNProblem, as_time, assemble
from madpinn.value_functions.train_settings import TrainSettings


class TrainingDiverged(RuntimeError):
    """The loss or a gradient became non-finite."""


def batch_generator(seed: int, iteration: int) -> torch.Generator:
    return torch.Generator().manual_seed(int(seed) * 1_000_003 + int(iteration))


def curriculum_alpha(iteration: int, s: TrainSettings) -> float:
    span = s.curriculum_fraction * s.iterations
    return 1.0 if span <= 0 else min(1.0, (iteration + 1) / span)


def learning_rate(iteration: int, s: TrainSettings) -> float:
    """Cosine decay from ``lr`` to ``lr_final`` (constant when equal)."""
    frac = iteration / max(1, s.iterations - 1)
    return s.lr_final + 0.5 * (s.lr - s.lr_final) * (1.0 + math.cos(math.pi * frac))


def make_head(problem: PINNProblem, s, t, boundary, grad_boundary, output_scale: float, loss_kind: str,
              obstacle_weight: float = 0.0):
    """Loss head ``(N, ∇N) -> (loss, ∂loss/∂N, ∂loss/∂∇N)``: autograd over the per-sample formula only."""

    def head(n, grad_n):
        with torch.enable_grad():
            n_ = n.detach().requires_grad_(True)
            g_ = grad_n.detach().requires_grad_(True)
            value, dv_dt, dv_ds = assemble(problem, s, t, n_, g_, boundary, grad_boundary, output_scale)
            r = problem.residual(s, t, value, dv_dt, dv_ds)
            norm = torch.abs if loss_kind == "l1" else torch.square
            loss = norm(r).mean()
            if obstacle_weight:
                loss = loss + obstacle_weight * norm(problem.obstacle_violation(s, value)).mean()
            n_bar, g_bar = torch.autograd.grad(loss, [n_, g_])
        return loss.detach(), n_bar, g_bar

    return head


def training_batch(problem: PINNProblem, settings: TrainSettings, iteration: int, device, dtype, batch_offset: int = 0):
    """States ``[B, S]`` and times ``[B]`` of one iteration: a pure function of the seed and the
    batch index ``batch_offset + iteration`` (the offset is non-zero when fine-tuning)."""
    gen = batch_generator(settings.seed, batch_offset + iteration)
    s = problem.sample_training_states(settings.batch_size, gen, dtype)
    t = problem.sample_times(settings.batch_size, curriculum_alpha(iteration, settings), gen, dtype)
    return s.to(device), t.to(device)


def train_step(problem, net, opt, settings, iteration, device, dtype, batch_offset: int = 0) -> float:
    s, t = training_batch(problem, settings, iteration, device, dtype, batch_offset)
    b, gb = problem.boundary_and_grad(s)
    head = make_head(problem, s, t, b, gb, settings.output_scale, settings.loss, settings.obstacle_weight)
    for group in opt.param_groups:
        group["lr"] = learning_rate(iteration, settings)
    opt.zero_grad(set_to_none=True)
    loss, _, _ = net.accumulate_loss_grad(problem.normalise(s, t), head)
    loss = float(loss)
    grad_ok = all(bool(torch.isfinite(p.grad).all()) for p in net.parameters())
    if not math.isfinite(loss) or not grad_ok:
        raise TrainingDiverged(
            f"{problem.kind}: training diverged at iteration {iteration}: loss={loss}, finite gradients={grad_ok}. "
            f"Lower value_functions.{problem.kind}.lr or output_scale and re-run (the last checkpoint is kept)."
        )
    opt.step()
    return loss


def residual_stats(problem: PINNProblem, model, samples: int, seed: int, chunk: int = 8192) -> dict:
    """Held-out HJB residual ``|min(...)|`` on uniform states and times ``t ∈ [0, T]``."""
    gen = torch.Generator().manual_seed(10_000_019 + int(seed))
    p = next(model.net.parameters())
    out = []
    for first in range(0, samples, chunk):
        n = min(chunk, samples - first)
        s = problem.sample_states(n, gen, p.dtype).to(p.device)
        t = problem.sample_times(n, 1.0, gen, p.dtype).to(p.device)
        v, dv_dt, dv_ds = model.state_value_and_grads(s, t)
        out.append(problem.residual(s, t, v, dv_dt, dv_ds).abs())
    r = torch.cat(out).double()
    q = torch.quantile(r[: min(r.numel(), 1_000_000)], torch.tensor([0.5, 0.9, 0.99], dtype=torch.float64, device=r.device))
    return {"residual_mean": float(r.mean()), "residual_median": float(q[0]), "residual_p90": float(q[1]),
            "residual_p99": float(q[2]), "residual_max": float(r.max()), "residual_samples": int(r.numel())}


def load_initial_weights(problem: PINNProblem, settings: TrainSettings, net: torch.nn.Module) -> int:
    """Load ``settings.init_from`` into ``net`` (same problem and network required); return the
    iterations it was trained for (the batch-stream offset of the fine-tuning run)."""
    data = read_checkpoint(settings.init_from, problem.kind)
    if data["problem"] != problem.describe():
        raise CheckpointError(f"init_from {settings.init_from} was trained on a different {problem.kind} problem "
                              f"({data['problem']} vs {problem.describe()})")
    if dict(data["network"]) != dict(settings.network) or float(data["output_scale"]) != settings.output_scale:
        raise CheckpointError(f"init_from {settings.init_from} has network {data['network']} (output_scale "
                              f"{data['output_scale']}), the config asks for {settings.network} ({settings.output_scale})")
    net.load_state_dict(data["state_dict"])
    return int(data["meta"].get("iterations", 0)) + int(data["meta"].get("batch_offset", 0))


def train(
    problem: PINNProblem, settings: TrainSettings, checkpoint: str | Path, config_hash: str,
    device=torch.device("cpu"), dtype=torch.float32, progress: bool = True, stop_after: int | None = None,
    on_iteration: Callable[[int, float], None] | None = None, deadline: float | None = None,
) -> tuple[torch.nn.Module, dict]:
    """Train (resuming from ``checkpoint`` when it matches ``config_hash``); return
    ``(network, info)`` with the per-iteration loss history. ``stop_after`` ends the run early
    after that many iterations in this call (used to test resume); ``deadline`` (a
    :func:`time.monotonic` instant) ends it after the first iteration that finishes past it, so a
    long training runs as time-boxed pieces (each resumes from the checkpoint the last one saved;
    the weights equal the uninterrupted run's, since the batch of iteration k is a function of
    ``(seed, k)``); ``on_iteration(i, loss)`` is called after iteration ``i`` (1-based) of this
    call, e.g. to log the curve live."""
    torch.manual_seed(settings.seed)
    net = build_network(problem, settings.network).to(device=device, dtype=dtype)
    opt = torch.optim.Adam(net.parameters(), lr=settings.lr)
    start, history, wall, offset = 0, [], 0.0, 0
    checkpoint = Path(checkpoint)
    if checkpoint.is_file():
        # An unreadable file, another kind's or a finished model is refused, never overwritten: this
        # trainer only ever writes complete resume checkpoints (atomically), so such a file is not its own.
        keep = "; it was left untouched: pass another checkpoint path, or delete it to train from scratch"
        try:
            data = read_checkpoint(checkpoint, problem.kind)
        except CheckpointError as exc:
            raise CheckpointError(f"cannot resume from {checkpoint}: {exc}{keep}") from exc
        train_state = data["meta"].get("train_state")
        if not train_state:
            raise CheckpointError(f"resume checkpoint {checkpoint} is a finished {problem.kind} model, not a resume "
                                  f"checkpoint (it has no training state){keep}")
        if train_state["config_hash"] != config_hash:   # hours of another run: refused, never overwritten
            raise CheckpointError(f"resume checkpoint {checkpoint} belongs to another training configuration "
                                  f"(hash {train_state['config_hash']}, this run's is {config_hash}){keep}")
        net.load_state_dict(data["state_dict"])
        opt.load_state_dict(train_state["optimizer"])
        start = int(train_state["iteration"])
        history = train_state["history"].tolist()
        wall = float(train_state["wall_s"])
        offset = int(train_state.get("batch_offset", 0))
        print(f"{problem.kind}: resuming from {checkpoint} at iteration {start}")
    if settings.init_from and start == 0:
        offset = load_initial_weights(problem, settings, net)
        print(f"{problem.kind}: fine-tuning from {settings.init_from} (batches from index {offset})")

    def save(iteration: int) -> None:
        meta = {"train_state": {"config_hash": config_hash, "iteration": iteration, "optimizer": opt.state_dict(),
                                "batch_offset": offset,
                                "history": torch.tensor(history, dtype=torch.float64), "wall_s": wall}}
        save_atomic(model_payload(problem, net, settings.output_scale, meta), checkpoint)

    final = settings.end_iteration
    end = final if stop_after is None else min(final, start + stop_after)
    bar = tqdm(range(start, end), initial=start, total=final, desc=f"train {problem.kind}",
               disable=not progress, mininterval=5.0)
    t0 = time.perf_counter()
    for it in bar:
        history.append(train_step(problem, net, opt, settings, it, device, dtype, offset))
        if deadline is not None and it + 1 < end and time.monotonic() >= deadline:
            end = it + 1
        if on_iteration is not None:
            on_iteration(it + 1, history[-1])
        if (it + 1) % 50 == 0:
            bar.set_postfix(loss=f"{sum(history[-50:]) / 50:.4g}", refresh=False)
        if (it + 1) % settings.checkpoint_every == 0 and it + 1 < final:
            wall_now = wall + time.perf_counter() - t0
            wall, t0 = wall_now, time.perf_counter()
            save(it + 1)
        if it + 1 == end:
            break
    wall += time.perf_counter() - t0
    if end < final or (deadline is not None and end > start):
        save(end)   # time-boxed pieces also keep a finished stage, so the next piece skips it
    return net, {"history": history, "iterations": end, "wall_s": wall, "completed": end >= final,
                 "batch_offset": offset}


def fine_tune(problem, settings: TrainSettings, net, info: dict, ft: dict, stage1: Path, ckpt: Path, chash: str,
              device, dtype, progress: bool = True, stop_after: int | None = None,
              on_iteration: Callable[[int, float], None] | None = None, deadline: float | None = None):
    """Second stage of ``value_functions.<kind>.fine_tune``: save the first stage's model at
    ``stage1``, then train from it with a fresh optimizer and schedule (:func:`load_initial_weights`;
    no curriculum, its batches continue the first stage's stream); ``on_iteration`` and
    ``deadline`` as in :func:`train`. Returns ``(network, info)`` over both stages (``completed``
    false when the second stage stopped early; the caller reports it)."""
    from dataclasses import replace

    from madpinn.value_functions.model import model_payload, save_atomic

    save_atomic(model_payload(problem, net, settings.output_scale,
                              {"config_hash": chash, "iterations": info["iterations"], "batch_offset": info["batch_offset"]}),
                stage1)
    s2 = replace(settings, iterations=int(ft["iterations"]), lr=float(ft["lr"]), lr_final=float(ft["lr_final"]),
                 curriculum_fraction=0.0, init_from=str(stage1), stop_at=None)
    net2, info2 = train(problem, s2, ckpt.with_name(ckpt.name.replace(".ckpt", ".fine_tune.ckpt")), chash + "/fine_tune",
                        device=device, dtype=dtype, progress=progress, stop_after=stop_after, on_iteration=on_iteration,
                        deadline=deadline)
    return net2, {"history": info["history"] + info2["history"], "iterations": info["iterations"] + info2["iterations"],
                  "wall_s": info["wall_s"] + info2["wall_s"], "completed": info2["completed"],
                  "batch_offset": info["batch_offset"]}


def train_stages(problem: PINNProblem, settings: TrainSettings, fine_tune_settings: dict | None, checkpoint: Path,
                 stage1: Path, config_hash: str, device, dtype, progress: bool = True, stop_after: int | None = None,
                 on_iteration: Callable[[int, float], None] | None = None, deadline: float | None = None):
    """The training job's stages: :func:`train` (resumable from ``checkpoint``), then, when
    ``fine_tune_settings`` (``value_functions.<kind>.fine_tune``) is set and the first stage is
    complete, :func:`fine_tune` from the first stage's model saved at ``stage1``.
    ``on_iteration(i, loss)`` gets the iteration counted over both stages (1-based). Returns
    ``(network, info)``; ``info["stage"]`` names the last stage run (``"train"`` or
    ``"fine_tune"``), ``info["completed"]`` is false when it stopped early (time limit,
    ``stop_after``): the checkpoints hold the state to resume from."""
    net, info = train(problem, settings, checkpoint, config_hash, device=device, dtype=dtype, progress=progress,
                      stop_after=stop_after, on_iteration=on_iteration, deadline=deadline)
    if not info["completed"] or not fine_tune_settings:
        return net, {**info, "stage": "train"}
    offset = info["iterations"]
    shifted = None if on_iteration is None else (lambda i, loss: on_iteration(i + offset, loss))
    net, info = fine_tune(problem, settings, net, info, fine_tune_settings, stage1, checkpoint, config_hash, device, dtype,
                          progress=progress, stop_after=stop_after, on_iteration=shifted, deadline=deadline)
    return net, {**info, "stage": "fine_tune"}


def model_meta(info: dict, settings: TrainSettings, training_settings: dict, config_hash: str) -> dict:
    """The metadata of a trained model file: what the weights are a function of (configuration
    hash and settings, iterations, initial model, batch stream) and the final loss; never the
    run's wall time, commit or date (the ``_train.json`` summary and MLflow keep those), so that
    identical weights give an identical file."""
    import numpy as np

    return {"config_hash": config_hash, "iterations": info["iterations"], "init_from": settings.init_from,
            "batch_offset": info["batch_offset"], "final_loss": float(np.mean(info["history"][-100:])),
            "settings": {**training_settings, "seed": settings.seed}}


def save_trained_model(problem: PINNProblem, net: torch.nn.Module, settings: TrainSettings, info: dict,
                       training_settings: dict, config_hash: str, out: Path, device, dtype):
    """Write the trained model to ``out`` (:func:`model_meta`, plus the held-out residual over one
    training batch of fresh states: ``validate-vhat`` uses the validation's count) and return it
    loaded (:class:`~madpinn.value_functions.model.PINNValueFunction`, with that metadata)."""
    from madpinn.value_functions.model import model_from_payload

    meta = model_meta(info, settings, training_settings, config_hash)
    model = model_from_payload(model_payload(problem, net, settings.output_scale, meta), device=device, dtype=dtype)
    meta["residual"] = model.meta["residual"] = residual_stats(problem, model, settings.batch_size, settings.seed)
    save_atomic(model_payload(problem, net, settings.output_scale, meta), out)
    return model
