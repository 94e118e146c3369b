"""Shipped checkpoints (issue 15): ``models/`` at the repository root and its ``manifest.json``.

The manifest maps a model name (``vs``, ``vhat``, ``safemarl_nominal``, ``defmarl_3``, ...) to
``{file, sha256, bytes, training_config_hash, git_commit, iterations, batch_size, samples,
device, wall_s, validation}``, read from the checkpoint's own metadata (any checkpoint written
by this project: a dict with a ``meta`` entry; ``wall_s`` and ``git_commit`` from the training's
summary beside it, :func:`training_record`, for checkpoints that no longer carry them) plus the
validation reports given. The workflow's
``shipped`` overlay checks every shipped file before any job, dry runs included
(:func:`check_shipped`: readable with ``weights_only=True``, of its kind, the manifest's sha256,
trained for this configuration) and installs it into ``results/models/`` only after the same
check (:func:`install`), so a changed, corrupted or swapped file stops the run with one clear
line instead of silently evaluating another model. :func:`ship` reads and checks every new file
before it writes anything.
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

from madpinn.checksum import sha256

MANIFEST = "manifest.json"


class ShippedModelError(RuntimeError):
    """A shipped model is missing from the manifest, unreadable, of another kind, not the manifest's
    bytes (sha256) or trained for another configuration; or a file given to ship is unusable."""


# The checkpoint formats, not imported from value_functions.model / marl.checkpoint (torch at import; the
# MARL package is not a source of the value-function jobs); tests/test_value_shipping.py checks they agree.
VALUE_FORMAT = "madpinn-value-function"   # = value_functions.model.FORMAT
MARL_FORMAT = "madpinn-marl-ppo"           # = marl.checkpoint.FORMAT


def model_kind(name: str) -> str | None:
    """The kind of checkpoint model ``name`` must hold: ``vhat``, ``vs``, ``safemarl_nominal``,
    ``defmarl`` (any ``defmarl_<variant>``), ``vhat`` / ``vs`` also for a variant ``vhat_<variant>`` /
    ``vs_<variant>``, or None for another name (not checked)."""
    if name in ("vhat", "vs", "safemarl_nominal"):
        return name
    if name.startswith(("vhat_", "vs_")):
        return name.partition("_")[0]
    return "defmarl" if name.startswith("defmarl_") else None


def checkpoint_kind(data) -> str | None:
    """The kind of a loaded project checkpoint (see :func:`model_kind`), None when it is none."""
    if not isinstance(data, dict):
        return None
    if data.get("format") == VALUE_FORMAT:
        return data.get("kind")
    if data.get("format") == MARL_FORMAT:
        method = (data.get("meta") or {}).get("method")
        return {"defmarl": "defmarl", "safemarl-nominal": "safemarl_nominal"}.get(method)
    return None


def read_model_file(path: str | Path, name: str) -> dict:
    """Load ``path`` as model ``name`` (``torch.load(weights_only=True)``: nothing in it is run) and
    check it holds that kind of model (V̂ and V_s swapped, a policy in place of a value function);
    :class:`ShippedModelError` naming the file and the problem otherwise. Returns the checkpoint."""
    import torch

    from madpinn.hints import unreadable_reason

    path = Path(path)
    if not path.is_file():
        raise ShippedModelError(f"model '{name}': {path} does not exist")
    try:
        data = torch.load(path, map_location="cpu", weights_only=True)
    except Exception as exc:  # noqa: BLE001 - truncated zip, garbage, blocked pickle: all unusable
        raise ShippedModelError(f"model '{name}': {path} was refused: {unreadable_reason(exc)}") from exc
    want, got = model_kind(name), checkpoint_kind(data)
    if want is not None and got != want:
        held = f"a '{got}' model" if got else "no madpinn model"
        raise ShippedModelError(f"model '{name}': {path} holds {held}, expected a '{want}' model (files swapped or "
                                "replaced)")
    return data


def describe_checkpoint(data: dict) -> dict:
    """Training metadata of a loaded project checkpoint (a dict with a ``meta`` entry)."""
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


def training_record(path: str | Path) -> dict:
    """The training job's summary beside checkpoint ``path`` (``<stem>_train.json`` of a value
    function, ``<stem>.json`` of a MARL policy), where a run's wall time and commit are kept (a
    checkpoint holds only what its weights are a function of); ``{}`` when there is none."""
    path = Path(path)
    for side in (path.with_name(path.stem + "_train.json"), path.with_suffix(".json")):
        try:
            record = json.loads(side.read_text())
        except (OSError, ValueError):
            continue
        if isinstance(record, dict):
            return record
    return {}


def read_manifest(directory: str | Path) -> dict:
    path = Path(directory) / MANIFEST
    if not path.is_file():
        return {"models": {}}
    try:
        manifest = json.loads(path.read_text())
    except (OSError, ValueError) as exc:
        raise ShippedModelError(f"{path} is unreadable ({exc})") from exc
    if not isinstance(manifest, dict) or not isinstance(manifest.get("models"), dict):
        raise ShippedModelError(f"{path} has no 'models' mapping")
    return manifest


def ship(models: dict, directory: str | Path, validation: dict | None = None, device: str | None = None,
         notes: dict | None = None, defaults: dict | None = None) -> dict:
    """Copy ``models`` (name -> checkpoint path) into ``directory`` as ``<name>.pt`` and merge their
    entries into its manifest; ``validation`` maps a name to JSON report paths whose contents are
    stored with the entry; ``defaults`` maps a name to entry fields the checkpoint does not record
    (e.g. a MARL policy's ``training_config_hash``). Every file and report is read and checked
    (:func:`read_model_file`) before anything is written, so a bad file leaves ``directory`` as it
    was; each file and then the manifest are replaced atomically. Returns the manifest."""
    from madpinn.atomic import UnwritableDirectoryError, atomic_write
    from madpinn.config import unwritable_reason

    directory = Path(directory)
    reason = unwritable_reason(directory)   # before any read: a read-only models/ is one line, not a traceback
    if reason:
        raise UnwritableDirectoryError(f"cannot ship into {directory}: {reason}; nothing was written")
    manifest = read_manifest(directory)
    entries, sources = {}, {}
    for name, src in models.items():   # read and check everything first
        src = Path(src)
        data = read_model_file(src, name)
        entry = {"file": f"{name}.pt", "sha256": sha256(src), "bytes": src.stat().st_size, **describe_checkpoint(data)}
        for key, value in training_record(src).items():   # timing and commit: beside a checkpoint, not in it
            if key in ("wall_s", "git_commit") and entry.get(key) is None:
                entry[key] = value
        for key, value in ((defaults or {}).get(name) or {}).items():
            if entry.get(key) is None:
                entry[key] = value
        if device and not entry["device"]:
            entry["device"] = device
        reports = (validation or {}).get(name, [])
        try:
            entry["validation"] = {Path(p).stem: json.loads(Path(p).read_text()) for p in reports}
        except (OSError, ValueError) as exc:
            raise ShippedModelError(f"cannot ship {name}: validation report unreadable ({exc})") from exc
        if notes and name in notes:
            entry["note"] = notes[name]
        entries[name], sources[name] = entry, src
    try:
        for name, src in sources.items():
            dst = directory / f"{name}.pt"
            if src.resolve() != dst.resolve():
                atomic_write(dst, lambda tmp, src=src: shutil.copyfile(src, tmp))
            manifest["models"][name] = entries[name]
        text = json.dumps(manifest, indent=2, sort_keys=True) + "\n"
        atomic_write(directory / MANIFEST, lambda tmp: tmp.write_text(text))
    except OSError as exc:   # e.g. a full disk: each file is whole (atomic), the manifest possibly stale
        raise UnwritableDirectoryError(f"cannot ship into {directory}: {exc.strerror or exc} ({exc.filename or directory})"
                                       ) from exc
    return manifest


def verify(directory: str | Path, name: str) -> Path:
    """The shipped file of ``name`` after checking that it holds that kind of model, readable with
    ``weights_only=True`` (:func:`read_model_file`), and that its sha256 is the manifest's."""
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
    read_model_file(path, name)
    digest = sha256(path)
    if digest != entry["sha256"]:
        raise ShippedModelError(f"shipped model '{name}': {path} has sha256 {digest}, the manifest says {entry['sha256']}; "
                                "the file was changed or corrupted (restore it from git, or re-ship it)")
    return path


def check_training_hash(directory: str | Path, name: str, expected: str) -> None:
    """Refuse a shipped model trained for another configuration: its manifest entry's
    ``training_config_hash`` must equal ``expected`` (:func:`madpinn.value_functions.build.training_hash`
    or :func:`madpinn.marl_hash.marl_training_hash` of the configuration in use). A missing entry
    is left to :func:`verify`."""
    entry = read_manifest(directory)["models"].get(name)
    if entry is None or entry.get("training_config_hash") == expected:
        return
    if model_kind(name) in ("vhat", "vs"):
        raise ShippedModelError(
            f"shipped model '{name}' ({Path(directory) / entry['file']}) was trained for configuration hash "
            f"{entry.get('training_config_hash')}, this configuration's {name} training hash is {expected} "
            f"(value_functions.{name}, agents, observation, seed or dtype changed since it was shipped); drop '{name}' "
            "from shipped_models.names to train it, or re-ship a model trained with this configuration")
    raise ShippedModelError(
        f"shipped policy '{name}' was trained for configuration hash {entry.get('training_config_hash')}, "
        f"this configuration's is {expected} (agents, observation, arenas, dtype or the method's "
        f"training settings changed since it was shipped); drop '{name}' from shipped_models.names "
        "to train it, or re-ship a policy trained with this configuration")


def check_shipped(directory: str | Path, expected: dict) -> None:
    """The check before any job of the shipped overlay (dry runs included): every model of
    ``expected`` (name -> training hash of the configuration in use, or None: not compared) is in
    the manifest, readable, of its kind, has the manifest's sha256 (:func:`verify`) and was
    trained for this configuration (:func:`check_training_hash`). Raises :class:`ShippedModelError`."""
    for name, training in expected.items():
        verify(directory, name)
        if training is not None:
            check_training_hash(directory, name, training)


def install(directory: str | Path, name: str, out: str | Path) -> Path:
    """Copy the verified shipped ``name`` to ``out`` (e.g. ``results/models/vs.pt``)."""
    src = verify(directory, name)
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.with_name(out.name + ".tmp")
    shutil.copyfile(src, tmp)
    tmp.replace(out)
    return out
