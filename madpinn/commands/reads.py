"""What each command's jobs read of the config: one function per command, ``reads(cfg, **job)``,
set beside the command's parser (``p.set_defaults(reads=...)``) and hashed into the rules'
``settings`` param (:func:`madpinn.provenance.settings_hash`). A trained model's own training hash
(never validation or deployment-only settings), an evaluation cell's :func:`madpinn.config.job_config`,
and for the checks and outputs the config subtrees they read. Light: no torch, read while the
workflow plans."""

from __future__ import annotations

from typing import Mapping

from madpinn.config import hashed_agents, hashed_key


def keys(*keys: str):
    """A job that reads these config subtrees (dotted keys) and nothing else."""
    return lambda cfg, **_: {k: hashed_key(cfg, k) for k in keys}


def labels(cfg: Mapping, *studies: str) -> dict:
    """The labels tables, figures and the report print for the studies' runs."""
    from madpinn.config import method_config

    return {st: {run: method_config(cfg, run)[1]["label"] for run in cfg["studies"][st]["runs"]}
            for st in studies}


def training(cfg: Mapping, kind: str, variant: str | None = None) -> str:
    from madpinn.config import with_vf_variant
    from madpinn.value_functions.build import training_hash

    return training_hash(with_vf_variant(cfg, kind, variant), kind)


def marl(cfg: Mapping, name: str) -> str:
    from madpinn.marl_hash import marl_training_hash

    return marl_training_hash(cfg, name)


def governors(cfg: Mapping, study: str) -> dict:
    """What fig_large_arena_frontier reads of each run of ``study`` besides its cells: its V̂, carrot
    and speed bound (:class:`madpinn.figures.frontier.FrontierRun`)."""
    from madpinn.config import RunSettings

    runs = (RunSettings.resolve(cfg, study, run) for run in cfg["studies"][study]["runs"])
    return {r.run: {"vhat": r.vhat, "observation": r.observation, "agents": hashed_agents(r.agents)} for r in runs}


def table_ii_readings(cfg: Mapping, **_) -> dict:
    """What the Table II readings page reads besides its cells (:class:`madpinn.evaluation.table_ii_settings.ReadingsSettings`)."""
    import dataclasses

    from madpinn.evaluation.table_ii_settings import ReadingsSettings

    return {"experiment": cfg["experiment"], **dataclasses.asdict(ReadingsSettings.from_config(cfg))}


def cell(cfg: Mapping, study: str, run: str) -> dict:
    from madpinn.config import RunSettings

    return {**RunSettings.resolve(cfg, study, run).job_config, "dtype": cfg["dtype"]}


def study_sim_override(cfg: Mapping, study: str) -> dict | None:
    """A study's own ``sim`` overrides (None: none)."""
    return cfg["studies"][study]["sim"] or None


def gap_rows(cfg: Mapping) -> dict:
    """What names the gap decomposition's rows (its cells are its inputs): the section, the
    configured carrot margin, each gap study's backend and its runs' settings."""
    from madpinn.config import hashed_method, method_config, study_backend

    def settings(run):
        return hashed_method(method_config(cfg, run)[1])   # as a cell's hash reads them (a base V_s: no `vs`)

    gap = cfg["gap_decomposition"]
    return {"gap_decomposition": gap, "carrot_margin": cfg["observation"]["carrot_margin"],
            "studies": {s: {"backend": study_backend(cfg, s), "runs": {r: settings(r) for r in cfg["studies"][s]["runs"]}}
                        for s in gap["studies"]}}


VF_RUN = ("value_functions.seed", "dtype")   # a value-function job's seeding and precision
Z_TOL = "methods.madpinn.z_tolerance"         # the deployed z* grid, which verify-vhat and the heatmap search


def agent_model_rows(cfg: Mapping) -> dict:
    """What the agent-model table reads besides its cells: the section, each study's agent model,
    backend and runs (with their labels and planar references)."""
    from madpinn.config import describe_model, study_agents, study_backend

    sec = cfg["agent_models"]
    return {"experiment": cfg["experiment"], "agent_models": sec, "labels": labels(cfg, *sec["studies"]),
            "studies": {s: {"model": describe_model(study_agents(cfg, s)), "backend": study_backend(cfg, s),
                            "runs": cfg["studies"][s]["runs"]} for s in sec["studies"]}}
