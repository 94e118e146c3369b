"""Stable short hashes of configuration parts: what a job's result depends on."""

from __future__ import annotations

import hashlib
import json
from typing import Any, Iterable, Mapping


def config_hash(obj: Any, length: int = 12) -> str:
    """Stable short hash of a JSON-serialisable object (sorted keys)."""
    blob = json.dumps(obj, sort_keys=True, default=str).encode()
    return hashlib.sha256(blob).hexdigest()[:length]


def lookup_key(cfg: Mapping[str, Any], dotted: str) -> Any:
    """The config value at a dotted key (``"value_functions.vhat"``); a missing key is None."""
    node: Any = cfg
    for part in dotted.split("."):
        if not isinstance(node, Mapping) or part not in node:
            return None
        node = node[part]
    return node


def subtree_hash(cfg: Mapping[str, Any], keys: Iterable[str], extra: Any = None) -> str:
    """Hash of the config subtrees at ``keys`` (dotted) plus ``extra``: what a job's result depends
    on (the workflow's rule params; the MARL policies' training hash, :mod:`madpinn.marl_hash`)."""
    return config_hash({"keys": {k: lookup_key(cfg, k) for k in keys}, "extra": extra})
