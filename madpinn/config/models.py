"""The agent model each part of a configuration flies or is trained for (issue 63): ``agents``, a
study's own model (``studies.<s>.agents``) and a value-function variant's
(``value_functions.<kind>_variants.<v>.agents``), each an overlay merged over ``agents``; and the
methods that fly a model other than the paper's."""

from __future__ import annotations

from typing import Any, Mapping

from madpinn.config.hashing import AGENT_MODEL_KEYS, PAPER_AGENT_MODEL
from madpinn.config.merge import deep_merge
from madpinn.config.schema import node_at

FLOWN_BY = "x-flown-by"
"""schema keyword of ``$defs.agent_model``: agent model -> the methods whose policies fly it (the
paper's planar model: every method, another model not listed there: none). The others refuse it in
one line when they are built: MPPI plans planar rollouts, the MARL baselines (SafeMARL, DEF-MARL)
read planar features (``tests/test_agent_model_study.py`` ties it to the policies and to
:data:`madpinn.dynamics.MODELS`)"""


def model_methods() -> dict[str, tuple[str, ...]]:
    """Agent model other than the paper's -> the methods that fly it, from the schema's
    ``$defs.agent_model`` through ``agents.model`` (the one place a model's name and its methods are written)."""
    return {m: tuple(runs) for m, runs in node_at("agents.model").get(FLOWN_BY, {}).items()}


def with_model(agents: Mapping[str, Any], overlay: Mapping[str, Any] | None) -> dict:
    """``agents`` with an agent-model ``overlay`` (``{model, altitude_band}``, either) merged over it;
    a copy of ``agents`` without one."""
    return deep_merge(agents, overlay) if overlay else dict(agents)


def study_agents(cfg: Mapping[str, Any], study: str) -> dict:
    """The ``agents`` section study ``study``'s cells fly: ``agents`` with the study's own model
    (``studies.<study>.agents``) merged over it."""
    return with_model(cfg["agents"], cfg["studies"][study].get("agents"))   # an overlay: absent = agents'


def model_identity(agents: Mapping[str, Any]) -> tuple:
    """What two ``agents`` sections must share for value functions trained on one to fly the other:
    the model, and its altitude band where the model has one (the planar model ignores the band)."""
    if agents["model"] == PAPER_AGENT_MODEL:
        return (PAPER_AGENT_MODEL,)
    return tuple(agents[k] if not isinstance(agents[k], list) else tuple(agents[k]) for k in AGENT_MODEL_KEYS)


def describe_model(agents: Mapping[str, Any]) -> str:
    """``double_integrator`` or ``double_integrator_3d (altitude band [0.5, 1.5] m)``: a model in one phrase."""
    ident = model_identity(agents)
    return ident[0] if len(ident) == 1 else f"{ident[0]} (altitude band {list(ident[1])} m)"


def methods_flying(model: str) -> tuple[str, ...] | None:
    """The methods that fly ``model`` (None: every method, the paper's planar model; a model
    :func:`model_methods` does not list: none)."""
    return None if model == PAPER_AGENT_MODEL else model_methods().get(model, ())
