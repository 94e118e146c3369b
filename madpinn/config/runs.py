"""A study's and a run's resolved settings: a run ``method[-variant]`` merged over its method,
a study's ``sim`` overrides merged over ``sim``, and the config part an evaluation cell depends on."""

from __future__ import annotations

from typing import Any, Mapping

from madpinn.config.errors import ConfigError
from madpinn.config.merge import deep_merge
from madpinn.config.vf_variants import vf_model_name


def study_pattern(study: Mapping[str, Any]) -> str:
    """A study's scenarios: ``uniform`` (SPEC §2, the default) or its structured-conflict pattern."""
    from madpinn.scenarios import UNIFORM

    return str(study["pattern"])


def method_config(cfg: Mapping[str, Any], run: str) -> tuple[str, dict]:
    """Split a run name ``method[-variant]`` and return ``(method, merged method config)``."""
    method, _, variant = run.partition("-")
    if method not in cfg["methods"]:
        raise ConfigError(f"unknown method '{method}' (configured: {sorted(cfg['methods'])})")
    base = {k: v for k, v in cfg["methods"][method].items() if k != "variants"}
    if not variant:
        return method, base
    variants = cfg["methods"][method]["variants"]
    if variant not in variants:
        raise ConfigError(f"unknown variant '{variant}' of method '{method}' (have {sorted(variants)})")
    return method, deep_merge(base, variants[variant])

FAN_OUT_KEYS = ("runs", "agent_counts", "seeds")

WORKFLOW_ONLY_KEYS = ("in_all",)
"""study keys only the workflow reads (which targets build the study's cells): not in the cells' hash"""
TRAINING_ONLY_KEYS = ("validation",)
"""method keys that only a training job reads (its validation curve): not in the cells' hash"""

# ``observation`` keys that only change the deployment mapping, not what V̂ / V_s are trained on
# (value_functions.build.training_hash leaves them out); here, not in madpinn.observation, so that
# the workflow reads them without importing torch
DEPLOYMENT_ONLY_KEYS = ("carrot_margin", "neighbour_goal")


def study_sim(cfg: Mapping[str, Any], study: str | None = None) -> dict:
    """The ``sim`` section a study's cells run with: ``sim`` with the study's own ``sim`` overrides
    (e.g. ``{contacts: true}``) merged over it; the plain ``sim`` when ``study`` is None."""
    override = (cfg["studies"].get(study) or {}).get("sim") if study is not None else None
    return deep_merge(cfg["sim"], override) if override else dict(cfg["sim"])


def run_observation(cfg: Mapping[str, Any], run: str) -> dict:
    """The ``observation`` section run ``method[-variant]``'s cells deploy with: ``observation``
    with the run's own deployment overrides (``methods.<method>[.variants.<v>].observation``, e.g.
    the gap decomposition's old mapping) merged over it; the plain ``observation`` without them."""
    override = method_config(cfg, run)[1].get("observation")
    return deep_merge(cfg["observation"], override) if override else dict(cfg["observation"])


def run_agents(cfg: Mapping[str, Any], run: str) -> dict:
    """The ``agents`` section run ``method[-variant]``'s cells simulate with: ``agents`` with the
    run's own deployment override (``methods.<method>[.variants.<v>].agents``, e.g. a lower
    ``v_max``: the speed governor of issue 33) merged over it; V̂ and V_s are trained on ``agents``."""
    override = method_config(cfg, run)[1].get("agents")
    return deep_merge(cfg["agents"], override) if override else dict(cfg["agents"])


def run_vhat(cfg: Mapping[str, Any], run: str) -> str:
    """The V̂ model a MAD-PINN run ``madpinn[-variant]`` loads: ``vhat``, or ``vhat_<name>`` when
    its settings select a V̂ variant (``vhat: <name>``, a key of ``value_functions.vhat_variants``)."""
    return vf_model_name("vhat", method_config(cfg, run)[1].get("vhat"))


def study_backend(cfg: Mapping[str, Any], study: str) -> str:
    """The backend a study's cells run on: its own ``sim.backend`` (e.g. the gap decomposition's
    double-integrator study), else ``sim.backend``."""
    return str(study_sim(cfg, study)["backend"])


def job_config(cfg: Mapping[str, Any], study: str, run: str) -> dict:
    """The part of the config an evaluation job depends on (hashed to trigger re-runs). The study's
    fan-out (``runs``, ``agent_counts``, ``seeds``) and what only the workflow reads (``in_all``)
    are left out: adding a run or a seed to a study does not change the cells already computed.
    Keys the loader filled with their default are left out too (:func:`~madpinn.config.schema.as_written`):
    filling them at load changes no cell's hash."""
    from madpinn.config.schema import as_written

    method, mcfg = method_config(cfg, run)
    return {
        "study": {k: v for k, v in as_written(cfg, f"studies.{study}").items()
                  if k not in FAN_OUT_KEYS + WORKFLOW_ONLY_KEYS},
        "arena": cfg["arenas"][cfg["studies"][study]["arena"]],
        "agents": cfg["agents"],
        "sim": study_sim(cfg, study),
        "observation": run_observation(cfg, run),
        "method": method,
        "method_config": {k: v for k, v in as_written(cfg, f"methods.{method}", mcfg).items() if k not in TRAINING_ONLY_KEYS},
    }
