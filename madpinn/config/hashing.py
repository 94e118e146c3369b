"""Stable short hashes of configuration parts: what a job's result depends on."""

from __future__ import annotations

import hashlib
import json
from typing import Any, Iterable, Mapping


def config_hash(obj: Any, length: int = 12) -> str:
    """Stable short hash of a JSON-serialisable object (sorted keys)."""
    blob = json.dumps(obj, sort_keys=True, default=str).encode()
    return hashlib.sha256(blob).hexdigest()[:length]


PAPER_AGENT_MODEL = "double_integrator"
"""``agents.model``'s schema default, the paper's planar model (= ``madpinn.dynamics.PAPER_MODEL``;
``tests/test_agent_model_3d.py`` ties the three)"""
AGENT_MODEL_KEYS = ("model", "altitude_band")
"""the keys of ``agents`` that choose and shape the agent model (issue 63 item 2)"""


def hashed_agents(agents: Mapping[str, Any] | None) -> Any:
    """``agents`` as every hash reads it: without :data:`AGENT_MODEL_KEYS` when the model is the paper's
    planar one (which ignores the altitude band), so every hash written before the keys existed
    holds; any other model hashes with both keys."""
    if not isinstance(agents, Mapping) or "model" not in agents or agents["model"] != PAPER_AGENT_MODEL:
        return agents   # another model, or agents written without the keys (as every hash before them read it)
    return {k: v for k, v in agents.items() if k not in AGENT_MODEL_KEYS}


_HASH_VIEWS = {"agents": hashed_agents}
"""config subtrees a hash reads through a view (the rest as they are)"""


def hashed_key(cfg: Mapping[str, Any], dotted: str) -> Any:
    """:func:`lookup_key` as hashes read it (``agents`` through :func:`hashed_agents`)."""
    value = lookup_key(cfg, dotted)
    return _HASH_VIEWS[dotted](value) if dotted in _HASH_VIEWS else value


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
    return config_hash({"keys": {k: hashed_key(cfg, k) for k in keys}, "extra": extra})
