"""Trainer checkpoints: state dicts + normaliser statistics + metadata, loaded with
``torch.load(weights_only=True)`` and validated with clear errors."""

from __future__ import annotations

from pathlib import Path

import torch

from madpinn.atomic import save_torch
from madpinn.hints import build_hint, unreadable_reason
from madpinn.marl.networks import DEFAULT_ENCODER, GaussianActor
from madpinn.marl.normalize import ObsNormalizer

FORMAT = "madpinn-marl-ppo"
VERSION = 1
_META_KEYS = ("ego_features", "neighbour_features", "hidden", "neighbours", "critic_heads", "u_max", "train_dt", "obs_spec")


class CheckpointError(ValueError):
    """A MARL checkpoint is missing, unreadable or inconsistent."""


def save_checkpoint(path: str | Path, trainer, meta: dict | None = None, train_state: dict | None = None) -> Path:
    """Write the trainer's actor, critic, normalisers and metadata atomically to ``path``;
    ``train_state`` (resumable checkpoints): :meth:`PPOTrainer.training_state` plus the caller's
    keys (e.g. a configuration hash, the wall time so far) under ``"train_state"``."""
    path = Path(path)
    spec = trainer.env.obs_spec
    payload = {
        "format": FORMAT,
        "version": VERSION,
        "modules": {
            "actor": trainer.actor.state_dict(), "critic": trainer.critic.state_dict(),
            **{k: m.state_dict() for k, m in trainer.extra_modules().items()},
        },
        "normalizers": {"obs": trainer.obs_norm.state_dict(), "return": trainer.ret_norm.state_dict()},
        "meta": {
            "ego_features": trainer.obs_norm.ego.mean.numel(),
            "neighbour_features": trainer.obs_norm.neighbours.mean.numel(),
            "extra_features": trainer.extra_features,
            "hidden": trainer.hidden,
            "encoder": trainer.encoder,
            "neighbours": trainer.env.cfg.neighbours,
            "critic_heads": trainer.critic_heads,
            "u_max": float(trainer.u_max),
            "v_max": float(trainer.env.dynamics.v_max),
            "train_dt": float(trainer.env.cfg.train_dt),
            "obs_spec": {k: getattr(spec, k) for k in ("n_neighbours", "goal_range", "offset_range", "sensing_radius", "collision_radius")},
            "iterations": trainer.iteration,
            "seed": trainer.seed,
            **(meta or {}),
        },
    }
    if train_state is not None:
        payload["train_state"] = {**trainer.training_state(), **train_state}
    return save_torch(payload, path)


def restore_modules(trainer, ck: dict, path: str | Path) -> None:
    """Load a checkpoint's modules and normalisers (:func:`load_checkpoint`) into ``trainer``."""
    modules = {"actor": trainer.actor, "critic": trainer.critic, **trainer.extra_modules()}
    missing = sorted(set(modules) - set(ck["modules"]))
    if missing:
        raise CheckpointError(f"{path} lacks the modules {missing} this trainer needs")
    try:
        for k, m in modules.items():
            m.load_state_dict(ck["modules"][k])
        trainer.obs_norm.load_state_dict(ck["normalizers"]["obs"])
        trainer.ret_norm.load_state_dict(ck["normalizers"]["return"])
    except (RuntimeError, ValueError, KeyError) as exc:
        raise CheckpointError(f"{path} does not fit this trainer (network size or features differ): {exc}") from exc


def load_checkpoint(path: str | Path, device: torch.device | str = "cpu") -> dict:
    path = Path(path)
    if not path.is_file():
        raise CheckpointError(f"MARL checkpoint not found: {path}; {build_hint(path)}")
    try:
        ck = torch.load(path, map_location=device, weights_only=True)
    except Exception as exc:  # noqa: BLE001 - any unpickling failure means an unusable file
        raise CheckpointError(f"cannot read MARL checkpoint {path}: {unreadable_reason(exc)}") from exc
    if not isinstance(ck, dict) or ck.get("format") != FORMAT:
        raise CheckpointError(f"{path} is not a {FORMAT} checkpoint")
    if ck.get("version") != VERSION:
        raise CheckpointError(f"{path} has checkpoint version {ck.get('version')}, this code reads version {VERSION}")
    missing = [k for k in _META_KEYS if k not in ck.get("meta", {})]
    if missing or "actor" not in ck.get("modules", {}) or "obs" not in ck.get("normalizers", {}):
        raise CheckpointError(f"{path} is incomplete (missing {missing or 'actor/normaliser'})")
    return ck


def load_actor(path: str | Path, device: torch.device | str = "cpu", dtype: torch.dtype = torch.float32):
    """-> ``(actor, obs_normalizer, meta)`` in eval mode."""
    ck = load_checkpoint(path, device)
    m = ck["meta"]
    actor = GaussianActor(m["ego_features"], m["neighbour_features"], m["hidden"], encoder=m.get("encoder", DEFAULT_ENCODER))
    try:
        actor.load_state_dict(ck["modules"]["actor"])
        norm = ObsNormalizer(m["ego_features"], m["neighbour_features"])
        norm.load_state_dict(ck["normalizers"]["obs"])
    except (RuntimeError, ValueError, KeyError) as exc:
        raise CheckpointError(f"{path}: actor weights do not match its metadata: {exc}") from exc
    return actor.to(device=device, dtype=dtype).eval(), norm, m
