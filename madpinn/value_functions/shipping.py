"""Shipped checkpoints (issue 15): ``models/`` at the repository root and its ``manifest.json``.

The manifest maps a model name (``vs``, ``vhat``, ``safemarl_nominal``, ``defmarl_3``, ...) to
``{file, sha256, bytes, training_config_hash, git_commit, iterations, batch_size, samples,
device, wall_s, validation}``, read from the checkpoint's own metadata (any checkpoint written
by this project: a dict with a ``meta`` entry) plus the validation reports given. The workflow's
``shipped`` overlay installs a shipped file into ``results/models/`` only after its sha256
matches the manifest (:func:`install`), so a changed or corrupted file stops the run with a
clear error instead of silently evaluating another model.
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

from madpinn.checksum import sha256

MANIFEST = "manifest.json"


class ShippedModelError(RuntimeError):
    """A shipped model is missing from the manifest or its file does not match its sha256."""


def describe_checkpoint(path: str | Path) -> dict:
    """Training metadata of a project checkpoint (``torch.load(weights_only=True)``)."""
    import torch

    data = torch.load(path, map_location="cpu", weights_only=True)
    meta = dict(data.get("meta", {})) if isinstance(data, dict) else {}
    settings = meta.get("settings") or {}
    batch = meta.get("batch_size", settings.get("batch_size"))
    iterations = meta.get("iterations")
    return {
        "training_config_hash": meta.get("config_hash"), "git_commit": meta.get("git_commit"),
        "iterations": iterations, "batch_size": batch,
        "samples": int(iterations) * int(batch) if iterations is not None and batch is not None else None,
        "wall_s": meta.get("wall_s"), "device": meta.get("device"),
        "init_from": meta.get("init_from"), "final_loss": meta.get("final_loss"),
    }


def read_manifest(directory: str | Path) -> dict:
    path = Path(directory) / MANIFEST
    return json.loads(path.read_text()) if path.is_file() else {"models": {}}


def ship(models: dict, directory: str | Path, validation: dict | None = None, device: str | None = None,
         notes: dict | None = None) -> dict:
    """Copy ``models`` (name -> checkpoint path) into ``directory`` as ``<name>.pt`` and merge their
    entries into its manifest; ``validation`` maps a name to JSON report paths whose contents are
    stored with the entry. Returns the manifest."""
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    manifest = read_manifest(directory)
    for name, src in models.items():
        src = Path(src)
        if not src.is_file():
            raise ShippedModelError(f"cannot ship {name}: {src} does not exist")
        dst = directory / f"{name}.pt"
        if src.resolve() != dst.resolve():
            shutil.copyfile(src, dst)
        entry = {"file": dst.name, "sha256": sha256(dst), "bytes": dst.stat().st_size, **describe_checkpoint(dst)}
        if device and not entry["device"]:
            entry["device"] = device
        reports = (validation or {}).get(name, [])
        entry["validation"] = {Path(p).stem: json.loads(Path(p).read_text()) for p in reports}
        if notes and name in notes:
            entry["note"] = notes[name]
        manifest["models"][name] = entry
    tmp = directory / (MANIFEST + ".tmp")
    tmp.write_text(json.dumps(manifest, indent=2, sort_keys=True) + "\n")
    tmp.replace(directory / MANIFEST)
    return manifest


def verify(directory: str | Path, name: str) -> Path:
    """The shipped file of ``name`` after checking its sha256 against the manifest."""
    directory = Path(directory)
    manifest = read_manifest(directory)
    entry = manifest["models"].get(name)
    if entry is None:
        raise ShippedModelError(f"{directory / MANIFEST} has no model '{name}' (shipped: {sorted(manifest['models'])}); "
                                f"ship it with `python -m madpinn ship-models --model {name}=PATH` or train it "
                                "(drop the shipped overlay)")
    path = directory / entry["file"]
    if not path.is_file():
        raise ShippedModelError(f"shipped model '{name}': {path} is missing")
    digest = sha256(path)
    if digest != entry["sha256"]:
        raise ShippedModelError(f"shipped model '{name}': {path} has sha256 {digest}, the manifest says {entry['sha256']}; "
                                "the file was changed or corrupted (restore it from git, or re-ship it)")
    return path


def check_training_hash(directory: str | Path, name: str, expected: str) -> None:
    """Refuse a shipped value function trained for another configuration: its manifest entry's
    ``training_config_hash`` must equal ``expected`` (:func:`madpinn.value_functions.build.training_hash`
    of the configuration in use). A missing entry is left to :func:`verify`."""
    entry = read_manifest(directory)["models"].get(name)
    if entry is None or entry.get("training_config_hash") == expected:
        return
    raise ShippedModelError(
        f"shipped model '{name}' ({Path(directory) / entry['file']}) was trained for configuration hash "
        f"{entry.get('training_config_hash')}, this configuration's {name} training hash is {expected} "
        f"(value_functions.{name}, agents, observation, seed or dtype changed since it was shipped); drop '{name}' "
        "from shipped_models.names to train it, or re-ship a model trained with this configuration")


def install(directory: str | Path, name: str, out: str | Path) -> Path:
    """Copy the verified shipped ``name`` to ``out`` (e.g. ``results/models/vs.pt``)."""
    src = verify(directory, name)
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.with_name(out.name + ".tmp")
    shutil.copyfile(src, tmp)
    tmp.replace(out)
    return out
