"""The checks of one cell named by a workflow target or an ``evaluate`` run by hand."""

from __future__ import annotations

from typing import Any, Mapping

from madpinn.config.errors import ConfigError, TargetError
from madpinn.config.runs import method_config, study_pattern
from madpinn.config.schema import backend_names


def check_cell(cfg: Mapping[str, Any], n_agents: int, seed: int, study: str | None = None, run: str | None = None,
               arena: str | None = None, pattern: str | None = None, backend: str | None = None) -> None:
    """The checks :func:`validate_config` makes of configured cells, for one cell named by a
    workflow target or an ``evaluate`` run by hand instead (an evaluation cell: ``study``, ``run``,
    ``backend``; an oracle file: ``arena``, ``pattern``): the study, run, backend and arena exist,
    ``n_agents`` ≥ 1 and ``seed`` ≥ 0, and the agents fit in the arena (the scenario sampler's bound,
    :func:`madpinn.scenarios.max_agents`, or the pattern's layout). Raises :class:`TargetError`
    (a :class:`ConfigError`)."""
    from madpinn.scenarios import UNIFORM, Arena, ScenarioInfeasibleError, generate_scenario, max_agents

    if backend is not None and backend not in backend_names():
        raise TargetError(f"unknown simulation backend '{backend}' (known: {', '.join(backend_names())})")
    if n_agents < 1:
        raise TargetError(f"{n_agents} agents: a cell has at least 1 agent")
    if seed < 0:
        raise TargetError(f"seed {seed}: seeds are integers ≥ 0")
    if study is not None:
        if study not in cfg["studies"]:
            raise TargetError(f"unknown study '{study}' (this configuration's studies: {', '.join(sorted(cfg['studies']))})")
        arena, pattern = cfg["studies"][study]["arena"], study_pattern(cfg["studies"][study])
    if run is not None:
        try:
            method_config(cfg, run)
        except ConfigError as exc:
            raise TargetError(str(exc)) from exc
    if arena not in cfg["arenas"]:
        raise TargetError(f"unknown arena '{arena}' (this configuration's arenas: {', '.join(sorted(cfg['arenas']))})")
    sep = float(cfg["sim"]["start_separation"])
    limit = max_agents(float(cfg["arenas"][arena]["half_width"]), sep)
    if pattern in (None, UNIFORM) and not 1 <= n_agents <= limit:
        raise TargetError(f"{n_agents} agents do not fit in arena '{arena}' with start separation {sep:g} m (1 to "
                          f"{limit}: the scenario sampler's coverage limit)")
    if pattern not in (None, UNIFORM):   # as _infeasible_patterns: the pattern's first scenario
        try:
            generate_scenario(Arena.from_config(cfg, arena), n_agents, seed, 0, sep, pattern)
        except (ScenarioInfeasibleError, ValueError) as exc:   # ValueError: an unknown pattern
            raise TargetError(str(exc)) from exc
