"""A study's and a run's resolved settings: a run ``method[-variant]`` merged over its method,
a study's ``sim`` overrides merged over ``sim`` and its agent model over ``agents``, and the config
part an evaluation cell depends on."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Mapping

from madpinn.config.errors import ConfigError
from madpinn.config.hashing import hashed_agents
from madpinn.config.merge import deep_merge
from madpinn.config.models import study_agents
from madpinn.config.vf_variants import vf_model_name


def study_pattern(study: Mapping[str, Any]) -> str:
    """A study's scenarios: ``uniform`` (SPEC §2, the default) or its structured-conflict pattern."""
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
HASHED_WHEN_SET = ("vs",)
"""method keys added after the cells were first hashed: in a cell's hash only when set (null, the
base model, hashes as the key's absence did, so those cells keep their hashes)"""

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
    return _merged(cfg["observation"], method_config(cfg, run)[1].get("observation"))   # only MAD-PINN runs have one


def run_agents(cfg: Mapping[str, Any], run: str) -> dict:
    """The ``agents`` section run ``method[-variant]``'s cells simulate with: ``agents`` with the
    run's own deployment override (``methods.<method>[.variants.<v>].agents``, e.g. a lower
    ``v_max``: the speed governor of issue 33) merged over it; V̂ and V_s are trained on ``agents``."""
    return _merged(cfg["agents"], method_config(cfg, run)[1].get("agents"))   # only MAD-PINN runs have one


def run_vhat(cfg: Mapping[str, Any], run: str) -> str:
    """The V̂ model a MAD-PINN run ``madpinn[-variant]`` loads: ``vhat``, or ``vhat_<name>`` when
    its settings select a V̂ variant (``vhat: <name>``, a key of ``value_functions.vhat_variants``)."""
    return vf_model_name("vhat", method_config(cfg, run)[1].get("vhat"))


def run_vs(cfg: Mapping[str, Any], run: str) -> str:
    """The V_s model a MAD-PINN run loads: ``vs``, or ``vs_<name>`` when its settings select a V_s
    variant (``vs: <name>``, a key of ``value_functions.vs_variants``)."""
    return vf_model_name("vs", method_config(cfg, run)[1].get("vs"))   # a run of another method has no such key


def hashed_method(mcfg: Mapping[str, Any]) -> dict:
    """A run's merged method settings as a cell's hash reads them: without the training-only keys,
    and without the :data:`HASHED_WHEN_SET` keys left at null."""
    return {k: v for k, v in mcfg.items() if k not in TRAINING_ONLY_KEYS and not (k in HASHED_WHEN_SET and v is None)}


def study_backend(cfg: Mapping[str, Any], study: str) -> str:
    """The backend a study's cells run on: its own ``sim.backend`` (e.g. the gap decomposition's
    double-integrator study), else ``sim.backend``."""
    return str(study_sim(cfg, study)["backend"])


@dataclass(frozen=True)
class RunSettings:
    """One run ``method[-variant]`` of one study, resolved once (:meth:`resolve`): every merge a
    cell's settings, its record and its hash need, so that no helper merges the config again.
    Sections are plain dicts (the validated config's values); treat them as read-only."""

    study: str
    """study name (``studies.<study>``)"""
    run: str
    """run name ``method[-variant]``"""
    method: str
    """the run's method (``methods.<method>``)"""
    method_config: dict
    """the run's settings: its variant merged over its method (``variants`` left out)"""
    study_config: dict
    """``studies.<study>``"""
    arena: dict
    """the study's arena (``arenas.<name>``)"""
    sim: dict
    """``sim`` with the study's own overrides merged over it (:func:`study_sim`)"""
    observation: dict
    """``observation`` with the run's deployment overrides merged over it (:func:`run_observation`)"""
    study_agents: dict
    """``agents`` with the study's agent model merged over it (:func:`madpinn.config.models.study_agents`):
    the model its cells fly and its value functions must be trained for"""
    agents: dict
    """:attr:`study_agents` with the run's deployment override merged over it (:func:`run_agents`)"""
    job_config: dict
    """the part of the config the run's cells depend on (:func:`job_config`)"""

    @classmethod
    def resolve(cls, cfg: Mapping[str, Any], study: str, run: str) -> "RunSettings":
        """The run's settings from the validated ``cfg``; :class:`ConfigError` for an unknown study,
        method or variant."""
        if study not in cfg["studies"]:
            raise ConfigError(f"unknown study '{study}' (configured: {sorted(cfg['studies'])})")
        method, mcfg = method_config(cfg, run)
        st = cfg["studies"][study]
        sim, observation = study_sim(cfg, study), _merged(cfg["observation"], mcfg.get("observation"))
        agents = study_agents(cfg, study)   # the study's model (its own `agents` is in the hashed study too)
        hashed = {
            "study": {k: v for k, v in st.items() if k not in FAN_OUT_KEYS + WORKFLOW_ONLY_KEYS},
            "arena": cfg["arenas"][st["arena"]],
            "agents": hashed_agents(agents),
            "sim": sim,
            "observation": observation,
            "method": method,
            "method_config": hashed_method(mcfg),
        }
        return cls(study=study, run=run, method=method, method_config=mcfg, study_config=st, arena=cfg["arenas"][st["arena"]],
                   sim=sim, observation=observation, study_agents=agents, agents=_merged(agents, mcfg.get("agents")),
                   job_config=hashed)

    @property
    def vhat(self) -> str:
        """The V̂ model a MAD-PINN run loads (:func:`run_vhat`)."""
        return vf_model_name("vhat", self.method_config.get("vhat"))   # a run of another method has no such key

    @property
    def vs(self) -> str:
        """The V_s model a MAD-PINN run loads (:func:`run_vs`)."""
        return vf_model_name("vs", self.method_config.get("vs"))


def _merged(section: Mapping[str, Any], override: Mapping[str, Any] | None) -> dict:
    """``section`` with a run's deployment ``override`` merged over it (none: a copy of it)."""
    return deep_merge(section, override) if override else dict(section)


def job_config(cfg: Mapping[str, Any], study: str, run: str) -> dict:
    """The part of the config an evaluation job depends on (hashed to trigger re-runs). The study's
    fan-out (``runs``, ``agent_counts``, ``seeds``) and what only the workflow reads (``in_all``)
    are left out: adding a run or a seed to a study does not change the cells already computed.
    Every key as loaded, schema defaults filled in: a changed default reruns the cells that read it.
    :attr:`RunSettings.job_config`."""
    return RunSettings.resolve(cfg, study, run).job_config
