"""The configuration's JSON schema (``workflow/schemas/config.schema.yaml``): read once per
process (while the file is unchanged), its nodes resolved, and its defaults filled in.

Every key of a configuration is either required or has a schema ``default`` (the one place its
absent value is written, ``tests/test_settings_once.py``), except inside an *overlay*: a node marked
``x-overlay: <base>`` (a method's variants, a study's ``sim``, a run's ``agents`` / ``observation``,
the V̂ variants) holds a partial section merged over its base, where an absent key means "the
base's value", so nothing is filled there.
"""

from __future__ import annotations

import copy
from functools import lru_cache
from typing import Any, Mapping

from madpinn.config.paths import REPO_ROOT
from madpinn.config.yaml_text import parse_yaml


SCHEMA_PATH = REPO_ROOT / "workflow" / "schemas" / "config.schema.yaml"
OVERLAY = "x-overlay"
"""schema keyword of a partial section merged over its base (value: the base, e.g. ``sim``)"""


def _schema() -> dict:
    """The schema (parsed once while the file keeps its mtime and size; do not modify it)."""
    st = SCHEMA_PATH.stat()
    return _parsed(st.st_mtime_ns, st.st_size)


@lru_cache(maxsize=2)
def _parsed(mtime_ns: int, size: int) -> dict:
    return parse_yaml(SCHEMA_PATH.read_text())


def _declared_keys(schema: Mapping[str, Any], root: Mapping[str, Any]) -> set[str]:
    """Property names a schema declares itself or through ``allOf`` / local ``$ref`` parts."""
    keys = set(schema.get("properties", {}))
    ref = schema.get("$ref", "")
    if ref.startswith("#/"):
        node: Any = root
        for part in ref[2:].split("/"):
            node = node[part]
        keys |= _declared_keys(node, root)
    for part in schema.get("allOf", []):
        keys |= _declared_keys(part, root)
    return keys


def resolve(node: Mapping[str, Any], root: Mapping[str, Any]) -> dict:
    """A schema node with its local ``$ref`` and ``allOf`` parts merged: their ``properties`` and
    ``required`` joined, their other keywords under the node's own."""
    parts = list(node.get("allOf", []))
    if "$ref" in node:
        target: Any = root
        for part in node["$ref"][2:].split("/"):
            target = target[part]
        parts.append(target)
    merged, props, required = {}, {}, set()
    for part in parts:
        sub = resolve(part, root)
        merged.update(sub)
        props.update(sub["properties"])
        required |= sub["required"]
    merged.update({k: v for k, v in node.items() if k not in ("$ref", "allOf")})
    props.update(node.get("properties", {}))
    required |= set(node.get("required", []))
    return {**merged, "properties": props, "required": required}


def object_branch(node: Mapping[str, Any], root: Mapping[str, Any]) -> dict | None:
    """The resolved node, or its ``oneOf`` / ``anyOf`` branch, that describes a mapping (None: none does)."""
    node = resolve(node, root)
    for branch in [node, *(resolve(b, root) for b in node.get("oneOf", []) + node.get("anyOf", []))]:
        if branch.get("type") == "object" or branch["properties"] or isinstance(branch.get("additionalProperties"), dict):
            return branch
    return None


FILLED = "_defaults_filled"
"""top-level config entry the loader writes: the dotted keys it filled with their default (no
config key; the schema check skips it): a record of which values came from the schema. Hashes of
settings read the filled values (a changed default reruns what reads it), so a resolved config
written out and loaded again (the workflow's ``config.resolved.yaml``) hashes as the original."""


def fill_defaults(cfg: dict, schema: Mapping[str, Any] | None = None) -> dict:
    """Set every absent key of ``cfg`` that has a schema ``default`` to (a copy of) it, in place,
    at every level but inside overlays, and add its dotted key to ``cfg[FILLED]``; ``cfg`` must
    already satisfy the schema. Returns ``cfg``."""
    root = _schema() if schema is None else schema
    filled: list[str] = []
    _fill(cfg, root, root, "", filled)
    if filled or FILLED not in cfg:
        cfg[FILLED] = sorted(set(cfg.get(FILLED, ())) | set(filled))
    return cfg


def _fill(instance: Any, node: Mapping[str, Any], root: Mapping[str, Any], path: str, filled: list[str]) -> None:
    if not isinstance(instance, dict):
        return
    branch = object_branch(node, root)
    if branch is None or OVERLAY in branch:
        return
    props = branch["properties"]
    for key, sub in props.items():
        here = f"{path}.{key}" if path else key
        if key not in instance:
            default = resolve(sub, root)
            if "default" in default:
                instance[key] = copy.deepcopy(default["default"])
                filled.append(here)
        if key in instance and OVERLAY not in resolve(sub, root):
            _fill(instance[key], sub, root, here, filled)
    extra = branch.get("additionalProperties")
    if isinstance(extra, dict) and OVERLAY not in resolve(extra, root):
        for key, value in instance.items():
            if key not in props and key != FILLED:
                _fill(value, extra, root, f"{path}.{key}" if path else key, filled)


def node_at(path: str, schema: Mapping[str, Any] | None = None) -> dict:
    """The resolved schema node of a dotted config key (``"methods.madpinn"``, ``"studies.main"``;
    ``""``: the root); a mapping's node is its object branch."""
    root = _schema() if schema is None else schema
    node = resolve(root, root)
    for part in filter(None, path.split(".")):
        branch = object_branch(node, root) or node
        if part in branch["properties"]:
            node = resolve(branch["properties"][part], root)
        elif isinstance(branch.get("additionalProperties"), dict):
            node = resolve(branch["additionalProperties"], root)
        else:
            raise KeyError(f"the schema has no key '{part}' in '{path}'")
    return node


def backend_names() -> list[str]:
    """The simulation backends a config may name: the schema's ``sim.backend`` enum (where a new
    backend is added, docs/reference/architecture.md)."""
    return list(_schema()["properties"]["sim"]["properties"]["backend"]["enum"])
