"""Cross-field rules of a configuration that its schema cannot state: names that must exist,
agent counts that must fit their arena, the gap decomposition's and the deployment overrides' limits,
the agent model a study flies against its runs and their value functions."""

from __future__ import annotations

from typing import Any, Mapping

from madpinn.config.models import describe_model, methods_flying, model_identity, study_agents
from madpinn.config.runs import method_config, study_backend, study_pattern, study_sim


def _agent_count_settings(cfg: Mapping[str, Any]):
    """``(key path, arena name, agent counts)`` of every place that samples uniform scenarios: the
    studies without a conflict pattern and any method setting (or variant) holding an ``arena``
    with ``agent_counts``."""
    from madpinn.scenarios import UNIFORM

    for name, study in cfg["studies"].items():
        if study_pattern(study) == UNIFORM:
            yield f"studies.{name}", study["arena"], study["agent_counts"]

    def walk(node, path):
        if isinstance(node, Mapping):
            if isinstance(node.get("arena"), str) and isinstance(node.get("agent_counts"), list):
                yield path, node["arena"], node["agent_counts"]
            for key, value in node.items():
                yield from walk(value, f"{path}.{key}")

    for method in cfg["methods"]:
        yield from walk(cfg["methods"][method], f"methods.{method}")
        for variant in cfg["methods"][method]["variants"]:
            _, merged = method_config(cfg, f"{method}-{variant}")
            yield from walk(merged, f"methods.{method}.variants.{variant}")


def _infeasible_agent_counts(cfg: Mapping[str, Any]) -> list[str]:
    """Agent counts the scenario sampler cannot place in their arena (``madpinn.scenarios``)."""
    from madpinn.scenarios import max_agents

    sep = float(cfg["sim"]["start_separation"])
    lines, seen = [], set()
    for path, arena, counts in _agent_count_settings(cfg):
        if arena not in cfg["arenas"]:
            continue  # reported by _cross_field_errors
        limit = max_agents(float(cfg["arenas"][arena]["half_width"]), sep)
        for n in counts:
            if n > limit and (path, n) not in seen:
                seen.add((path, n))
                lines.append(
                    f"  - '{path}.agent_counts': {n} agents do not fit in arena '{arena}' with start separation "
                    f"{sep:g} m (at most {limit}: the scenario sampler's coverage limit); "
                    f"use fewer agents or a larger arena"
                )
    return lines


def _infeasible_patterns(cfg: Mapping[str, Any]) -> list[str]:
    """Agent counts a study's conflict pattern cannot lay out in its arena (its first scenario)."""
    from madpinn.scenarios import UNIFORM, Arena, ScenarioInfeasibleError, generate_scenario

    lines = []
    for name, study in cfg["studies"].items():
        pattern = study_pattern(study)
        if pattern == UNIFORM or study["arena"] not in cfg["arenas"]:
            continue
        arena = Arena.from_config(cfg, study["arena"])
        for n in study["agent_counts"]:
            try:
                generate_scenario(arena, n, min(study["seeds"]), 0, float(study_sim(cfg, name)["start_separation"]), pattern)
            except ScenarioInfeasibleError as exc:
                lines.append(f"  - 'studies.{name}.agent_counts': {exc}")
    return lines


def _gap_errors(cfg: Mapping[str, Any]) -> list[str]:
    """The gap decomposition's studies exist, run MAD-PINN only (its collision probe) on validation
    seeds (≥ 100); its reference row is one of their (backend, run) rows."""
    gap = cfg["gap_decomposition"]
    if not gap:
        return []
    lines, studies = [], cfg["studies"]
    for name in gap["studies"]:
        st = studies.get(name)
        if st is None:
            lines.append(f"  - 'gap_decomposition.studies': unknown study '{name}'")
            continue
        if min(st["seeds"]) < 100:
            lines.append(f"  - 'studies.{name}.seeds': the gap decomposition runs on validation seeds ≥ 100 only, got {st['seeds']}")
        if any(r.partition("-")[0] != "madpinn" for r in st["runs"]):
            lines.append(f"  - 'studies.{name}.runs': the gap decomposition runs MAD-PINN runs only (madpinn[-variant])")
    ref = gap["reference"]
    if not any(study_backend(cfg, s) == ref["backend"] and ref["run"] in studies[s]["runs"]
               for s in gap["studies"] if s in studies):
        lines.append(f"  - 'gap_decomposition.reference': no study of the decomposition runs {ref['run']} on {ref['backend']}")
    return lines


def _table_ii_errors(cfg: Mapping[str, Any]) -> list[str]:
    """The Table II readings' studies exist, lie in the large arena at Table II's agent counts or a
    subset, the anchor is a small-arena uniform study with its agent count, and the protocol's run
    is one of its study's runs."""
    sec = cfg["table_ii_readings"]
    if not sec:
        return []
    lines, studies = [], cfg["studies"]
    for key, name in [("studies", s) for s in sec["studies"]] + [("baselines", s) for s in sec["baselines"]]:
        st = studies.get(name)
        if st is None:
            lines.append(f"  - 'table_ii_readings.{key}': unknown study '{name}'")
        elif st["arena"] != "large":
            lines.append(f"  - 'studies.{name}.arena': a Table II reading runs in the large arena, got '{st['arena']}'")
    anchor = studies.get(sec["anchor"]["study"])
    if anchor is None:
        lines.append(f"  - 'table_ii_readings.anchor.study': unknown study '{sec['anchor']['study']}'")
    elif anchor["arena"] != "small" or anchor["pattern"] != "uniform" or sec["anchor"]["n_agents"] not in anchor["agent_counts"]:
        lines.append(f"  - 'table_ii_readings.anchor': Table I's setting is a small-arena uniform study with "
                     f"{sec['anchor']['n_agents']} agents among its agent_counts")
    proto = sec["protocol"]
    if proto["study"] not in sec["studies"]:
        lines.append(f"  - 'table_ii_readings.protocol.study': '{proto['study']}' is not one of table_ii_readings.studies")
    elif proto["study"] in studies and proto["run"] not in studies[proto["study"]]["runs"]:
        lines.append(f"  - 'table_ii_readings.protocol.run': study '{proto['study']}' has no run '{proto['run']}'")
    return lines


def _variant_errors(cfg: Mapping[str, Any]) -> list[str]:
    """Deployment overrides of MAD-PINN runs name an existing V̂ / V_s variant and only lower the speed
    bound (a governor: V̂ and V_s are trained at ``agents.v_max``)."""
    lines = []
    madpinn = cfg["methods"].get("madpinn")
    if madpinn is None:
        return lines
    for variant in [None, *madpinn["variants"]]:
        where = "methods.madpinn" + (f".variants.{variant}" if variant else "")
        mcfg = madpinn if variant is None else madpinn["variants"][variant]
        for kind, name in (("vhat", "V̂"), ("vs", "V_s")):
            known = sorted(cfg["value_functions"][f"{kind}_variants"])
            if mcfg.get(kind) is not None and mcfg[kind] not in known:   # a variant: absent keeps the base's
                lines.append(f"  - '{where}.{kind}': unknown {name} variant '{mcfg[kind]}' (value_functions.{kind}_variants: "
                             f"{', '.join(known) or 'none'})")
        v_max = (mcfg.get("agents") or {}).get("v_max")
        if v_max is not None and v_max > cfg["agents"]["v_max"]:
            lines.append(f"  - '{where}.agents.v_max': {v_max} exceeds agents.v_max = {cfg['agents']['v_max']} "
                         "(a run may only lower the speed bound its models were trained with)")
    return lines


def _model_errors(cfg: Mapping[str, Any]) -> list[str]:
    """Each study's agent model (``agents``, with the study's own ``agents`` merged over it) is flown by
    every run's method (the schema's ``$defs.agent_model.x-flown-by``, :func:`madpinn.config.models.model_methods`), and each MAD-PINN run loads a V̂
    and a V_s trained for it (the base ones: ``agents``; a variant: its own ``agents`` merged over it)."""
    from madpinn.config.vf_variants import with_vf_variant

    lines, methods = [], cfg["methods"]
    for name, st in cfg["studies"].items():
        agents = study_agents(cfg, name)
        flying = methods_flying(agents["model"])
        for run in st["runs"]:
            method, _, variant = run.partition("-")
            if method not in methods or (variant and variant not in methods[method]["variants"]):
                continue   # reported by _cross_field_errors
            if flying is not None and method not in flying:
                lines.append(f"  - 'studies.{name}.runs': run '{run}' cannot fly the study's agent model {agents['model']} "
                             f"(the methods that do: {', '.join(flying) or 'none'}; the schema's agent_model x-flown-by)")
                continue
            if method != "madpinn":
                continue
            mcfg = method_config(cfg, run)[1]
            for kind, label in (("vhat", "V̂"), ("vs", "V_s")):
                if mcfg.get(kind) is not None and mcfg[kind] not in cfg["value_functions"][f"{kind}_variants"]:
                    continue   # reported by _variant_errors
                trained = with_vf_variant(cfg, kind, mcfg.get(kind))["agents"]
                if model_identity(trained) != model_identity(agents):
                    lines.append(f"  - 'studies.{name}.runs': run '{run}' loads a {label} trained for {describe_model(trained)}, "
                                 f"but the study flies {describe_model(agents)} (give the run a {kind} variant trained for "
                                 f"it: value_functions.{kind}_variants.<name>.agents, `{kind}: <name>`)")
    return lines


def _agent_models_errors(cfg: Mapping[str, Any]) -> list[str]:
    """The agent-model table's studies exist, share their scenarios (arena, pattern, agent counts,
    validation seeds ≥ 100, scenario count; a study cannot change the start separation) and, per
    backend, one flies the planar model (the reference) and at least one another model, with a run
    of each method of the others."""
    from madpinn.config.hashing import PAPER_AGENT_MODEL

    sec = cfg["agent_models"]
    if not sec:
        return []
    lines, studies = [], cfg["studies"]
    known = [s for s in sec["studies"] if s in studies]
    lines += [f"  - 'agent_models.studies': unknown study '{s}'" for s in sec["studies"] if s not in studies]
    if not known:
        return lines
    first = studies[known[0]]
    for name in known:
        st = studies[name]
        if min(st["seeds"]) < 100:
            lines.append(f"  - 'studies.{name}.seeds': the agent-model table runs on validation seeds ≥ 100 only, got {st['seeds']}")
        differ = [k for k in ("arena", "pattern", "agent_counts", "seeds", "scenarios") if st[k] != first[k]]
        if differ:
            lines.append(f"  - 'studies.{name}': the agent-model table pairs the same scenarios; its {', '.join(differ)} "
                         f"differ from studies.{known[0]}'s")
    for backend in sorted({study_backend(cfg, s) for s in known}):
        on = [s for s in known if study_backend(cfg, s) == backend]
        models = [study_agents(cfg, s)["model"] for s in on]
        if models.count(PAPER_AGENT_MODEL) != 1 or len(models) < 2:
            lines.append(f"  - 'agent_models.studies': on backend {backend} one study must fly the planar model "
                         f"{PAPER_AGENT_MODEL} (the reference) and at least one another model, got {models}")
            continue
        planar = on[models.index(PAPER_AGENT_MODEL)]
        methods = {r.partition("-")[0] for r in studies[planar]["runs"]}
        for name in on:
            for run in studies[name]["runs"]:
                if run.partition("-")[0] not in methods:
                    lines.append(f"  - 'studies.{name}.runs': run '{run}' has no planar reference in studies.{planar} "
                                 "(a run of the same method, paired on the same scenarios)")
    return lines


def _cross_field_errors(cfg: Mapping[str, Any]) -> list[str]:
    lines = []
    arenas = cfg["arenas"]
    methods = cfg["methods"]
    for name, study in cfg["studies"].items():
        if study["arena"] not in arenas:
            lines.append(f"  - 'studies.{name}.arena': unknown arena '{study['arena']}' (have {sorted(arenas)})")
        for run in study["runs"]:
            method, _, variant = run.partition("-")
            if method not in methods:
                lines.append(f"  - 'studies.{name}.runs': unknown method '{method}' in run '{run}'")
            elif variant and variant not in methods[method]["variants"]:
                lines.append(f"  - 'studies.{name}.runs': unknown variant '{variant}' of method '{method}'")
    lines += _gap_errors(cfg)
    lines += _table_ii_errors(cfg)
    lines += _variant_errors(cfg)
    lines += _model_errors(cfg)
    lines += _agent_models_errors(cfg)
    lines += _stop_at_errors(cfg)
    lines += _horizon_errors(cfg)
    lines += _claims_input_errors(cfg)
    traj = cfg["figures"]["trajectories"]
    study = cfg["studies"].get(traj["study"])
    if study is None:
        lines.append(f"  - 'figures.trajectories.study': unknown study '{traj['study']}'")
    else:
        if traj["n_agents"] not in study["agent_counts"]:
            lines.append(f"  - 'figures.trajectories.n_agents': {traj['n_agents']} is not among studies.{traj['study']}.agent_counts")
        if traj["seed"] not in study["seeds"]:
            lines.append(f"  - 'figures.trajectories.seed': {traj['seed']} is not among studies.{traj['study']}.seeds")
    return lines


def _claims_input_errors(cfg: Mapping[str, Any]) -> list[str]:
    """``claims.<page>`` names a published page's file that exists, relative to the repository (the claims
    page reads it; a run whose overlay builds that page reads its own instead, so then it need not exist yet)."""
    from madpinn.config.paths import in_repository

    own = {"table_ii_verdict": "table_ii_readings", "vhat_recipe": "vhat_recipe"}
    return [f"  - 'claims.{key}': no file '{in_repository(path)}' (publish the page first: python -m madpinn publish --config <its configs>)"
            for key, path in cfg["claims"].items()
            if path is not None and not cfg[own[key]] and not in_repository(path).is_file()]


def _horizon_errors(cfg: Mapping[str, Any]) -> list[str]:
    """``studies.<name>.cost_horizons_s`` lie inside the study's episode, each a whole number of its ``sim.dt``."""
    from madpinn.scenarios import horizon_problem

    lines = []
    for name, st in cfg["studies"].items():
        arena = cfg["arenas"].get(st["arena"])
        if arena is None:
            continue   # reported as an unknown arena
        dt = float(study_sim(cfg, name)["dt"])
        for h in st["cost_horizons_s"]:
            problem = horizon_problem(float(h), float(arena["episode_s"]), dt)
            if problem:
                lines.append(f"  - 'studies.{name}.cost_horizons_s': {problem}")
    return lines


def _stop_at_errors(cfg: Mapping[str, Any]) -> list[str]:
    """``value_functions.<kind>.stop_at`` (each variant merged over its base) ends a training inside its
    schedule: at most ``iterations``."""
    from madpinn.config.vf_variants import VF_VARIANTS, stop_at_problem, with_vf_variant

    lines = []
    for kind in ("vhat", "vs"):
        section = VF_VARIANTS.get(kind)
        for variant in [None, *(cfg["value_functions"].get(section) or {} if section else {})]:
            v = with_vf_variant(cfg, kind, variant)["value_functions"][kind]
            problem = stop_at_problem(v["stop_at"], v["iterations"])
            if problem:
                key = f"value_functions.{section}.{variant}" if variant else f"value_functions.{kind}"
                lines.append(f"  - '{key}.stop_at': {problem}")
    return lines
