"""Configuration: loading, overlaying, schema validation with one clear message, hashing.

The schema lives in ``workflow/schemas/config.schema.yaml``; the workflow and the CLI both call
:func:`validate_config` before any work starts.
"""

from __future__ import annotations

import copy
import hashlib
import json
import math
from pathlib import Path
from typing import Any, Iterable, Mapping

import yaml

REPO_ROOT = Path(__file__).resolve().parents[1]
SCHEMA_PATH = REPO_ROOT / "workflow" / "schemas" / "config.schema.yaml"


class ConfigError(ValueError):
    """Invalid configuration; the message names the offending key."""


class ConfigFileError(ConfigError):
    """A config file named on the command line (or the repository's config.yaml) does not exist
    or holds no mapping."""


class WorkingDirectoryError(ConfigError):
    """The workflow was started outside the repository without naming its directory (--directory)."""


class TargetError(ConfigError):
    """A workflow target (an output path asked for by name) outside this configuration."""


def deep_merge(base: Mapping[str, Any], overlay: Mapping[str, Any]) -> dict:
    """Recursively merge ``overlay`` into a copy of ``base`` (dicts merge, everything else replaces)."""
    out = copy.deepcopy(dict(base))
    for key, value in overlay.items():
        if isinstance(value, Mapping) and isinstance(out.get(key), Mapping):
            out[key] = deep_merge(out[key], value)
        else:
            out[key] = copy.deepcopy(value)
    return out


def load_yaml(path: str | Path) -> dict:
    path = Path(path)
    if not path.is_file():
        raise ConfigFileError(f"config file not found: {path}")
    try:
        data = yaml.safe_load(path.read_text())
    except yaml.YAMLError as exc:
        raise ConfigError(f"config file {_yaml_error_text(path, exc)}") from exc
    if data is None:
        return {}
    if not isinstance(data, dict):
        raise ConfigFileError(f"config file {path} must hold a mapping at top level")
    return data


def _yaml_error_text(path: Path, exc: yaml.YAMLError) -> str:
    """``<file>:<line>:<column> is not valid YAML: <problem> (<context> at line L)``, one line."""
    mark, problem = getattr(exc, "problem_mark", None), getattr(exc, "problem", None)
    if mark is None or not problem:
        return f"{path} is not valid YAML: {' '.join(str(exc).split())}"
    text = f"{path}:{mark.line + 1}:{mark.column + 1} is not valid YAML: {problem}"
    context, cmark = getattr(exc, "context", None), getattr(exc, "context_mark", None)
    if context and cmark is not None:
        text += f" ({context} at line {cmark.line + 1}, column {cmark.column + 1})"
    return text


def load_config(paths: Iterable[str | Path]) -> dict:
    """Load and deep-merge config files in order (later files override), then validate."""
    cfg: dict = {}
    for path in paths:
        cfg = deep_merge(cfg, load_yaml(path))
    validate_config(cfg)
    return cfg


def _schema() -> dict:
    return yaml.safe_load(SCHEMA_PATH.read_text())


def _key_path(error) -> str:
    parts = [str(p) for p in error.absolute_path]
    return ".".join(parts) if parts else "<top level>"


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


def _unknown_keys(error, root: Mapping[str, Any]) -> list[str]:
    """The keys an ``unevaluatedProperties`` error really rejects. A failing ``allOf`` part (e.g.
    ``value_functions.vhat.iterations: 0``) drops its annotations, so the validator lists every key
    that part declares as unexpected; only the keys no part declares are."""
    declared = _declared_keys(error.schema, root)
    return sorted(k for k in error.instance if k not in declared)


def validate_config(cfg: Mapping[str, Any]) -> None:
    """Validate against the JSON schema and cross-field rules, and check that the output paths can
    be written (:func:`unwritable_reason`, writes nothing); raise :class:`ConfigError`. The one
    validator of the workflow (Snakefile), ``validate-config`` and every job (:func:`load_config`).

    All violations are reported at once, one line each, each naming its key.
    """
    import jsonschema

    validator = jsonschema.Draft202012Validator(_schema())
    errors = sorted(validator.iter_errors(cfg), key=lambda e: list(map(str, e.absolute_path)))
    lines = [f"  - '{key}': {value} is not a finite number" for key, value in _non_finite(cfg)]
    for err in errors:
        if err.validator == "additionalProperties":
            lines.append(f"  - '{_key_path(err)}': {err.message} (unknown key)")
        elif err.validator == "unevaluatedProperties":
            unknown = _unknown_keys(err, validator.schema)
            if unknown:   # else only a sibling error (reported on its own) left the known keys unevaluated
                were = "was" if len(unknown) == 1 else "were"
                lines.append(f"  - '{_key_path(err)}': Properties are not allowed ({', '.join(map(repr, unknown))} "
                             f"{were} unexpected) (unknown key)")
        else:
            lines.append(f"  - '{_key_path(err)}': {err.message}")
    if not lines:
        lines = _vf_variant_errors(cfg, validator)
    if not lines:
        lines = _cross_field_errors(cfg) + _infeasible_agent_counts(cfg) + _infeasible_patterns(cfg)
    if not lines:
        lines = _unwritable_output_paths(cfg)
    if lines:
        raise ConfigError("invalid configuration:\n" + "\n".join(lines))


def _non_finite(node: Any, path: str = "") -> list[tuple[str, float]]:
    """``(key path, value)`` of every NaN or ±inf in the config (YAML ``.nan``, ``.inf``): JSON
    schema's ``number`` type and its bounds let them through (NaN compares false to every bound)."""
    if isinstance(node, float):
        return [] if math.isfinite(node) else [(path or "<top level>", node)]
    if isinstance(node, Mapping):
        items = node.items()
    elif isinstance(node, (list, tuple)):
        items = enumerate(node)
    else:
        return []
    return [bad for key, value in items for bad in _non_finite(value, f"{path}.{key}" if path else str(key))]


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
        for variant in cfg["methods"][method].get("variants", {}):
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
    gap = cfg.get("gap_decomposition")
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


def _variant_errors(cfg: Mapping[str, Any]) -> list[str]:
    """Deployment overrides of MAD-PINN runs name an existing V̂ variant and only lower the speed
    bound (a governor: V̂ and V_s are trained at ``agents.v_max``)."""
    lines = []
    madpinn = cfg["methods"].get("madpinn")
    if madpinn is None:
        return lines
    known = sorted(cfg["value_functions"].get("vhat_variants") or {})
    for variant in [None, *madpinn.get("variants", {})]:
        where = "methods.madpinn" + (f".variants.{variant}" if variant else "")
        mcfg = madpinn if variant is None else madpinn["variants"][variant]
        if "vhat" in mcfg and mcfg["vhat"] not in known:
            lines.append(f"  - '{where}.vhat': unknown V̂ variant '{mcfg['vhat']}' (value_functions.vhat_variants: "
                         f"{', '.join(known) or 'none'})")
        v_max = (mcfg.get("agents") or {}).get("v_max")
        if v_max is not None and v_max > cfg["agents"]["v_max"]:
            lines.append(f"  - '{where}.agents.v_max': {v_max} exceeds agents.v_max = {cfg['agents']['v_max']} "
                         "(a run may only lower the speed bound its models were trained with)")
    return lines


def _vf_variant_errors(cfg: Mapping[str, Any], validator) -> list[str]:
    """Schema errors of each value-function variant merged over its base (a variant is a partial
    section: what it yields must be a valid ``value_functions.<kind>``)."""
    lines = []
    for kind, section in VF_VARIANTS.items():
        for variant in cfg["value_functions"].get(section) or {}:
            merged = with_vf_variant(cfg, kind, variant)
            for err in validator.iter_errors(merged):
                path = list(map(str, err.absolute_path))
                if path[:2] != ["value_functions", kind]:
                    continue
                key = ".".join(["value_functions", section, variant, *path[2:]])
                message = err.message
                if err.validator == "unevaluatedProperties":
                    unknown = _unknown_keys(err, validator.schema)
                    if not unknown:   # only a sibling error (reported on its own) left the known keys unevaluated
                        continue
                    message = f"unknown keys {', '.join(map(repr, unknown))}"
                lines.append(f"  - '{key}' (merged over value_functions.{kind}): {message}")
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
            elif variant and variant not in methods[method].get("variants", {}):
                lines.append(f"  - 'studies.{name}.runs': unknown variant '{variant}' of method '{method}'")
    lines += _gap_errors(cfg)
    lines += _variant_errors(cfg)
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


def study_pattern(study: Mapping[str, Any]) -> str:
    """A study's scenarios: ``uniform`` (SPEC §2, the default) or its structured-conflict pattern."""
    from madpinn.scenarios import UNIFORM

    return str(study.get("pattern", UNIFORM))


def method_config(cfg: Mapping[str, Any], run: str) -> tuple[str, dict]:
    """Split a run name ``method[-variant]`` and return ``(method, merged method config)``."""
    method, _, variant = run.partition("-")
    if method not in cfg["methods"]:
        raise ConfigError(f"unknown method '{method}' (configured: {sorted(cfg['methods'])})")
    base = {k: v for k, v in cfg["methods"][method].items() if k != "variants"}
    if not variant:
        return method, base
    variants = cfg["methods"][method].get("variants", {})
    if variant not in variants:
        raise ConfigError(f"unknown variant '{variant}' of method '{method}' (have {sorted(variants)})")
    return method, deep_merge(base, variants[variant])


FAN_OUT_KEYS = ("runs", "agent_counts", "seeds")
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


VF_VARIANTS = {"vhat": "vhat_variants"}
"""value-function kind -> its section of variants (``value_functions.<section>.<name>``, each
deep-merged over ``value_functions.<kind>``; trained model ``<kind>_<name>``)"""


def vf_model_name(kind: str, variant: str | None = None) -> str:
    """The model name of value function ``kind`` (``vhat``) or of its variant (``vhat_h04``)."""
    return f"{kind}_{variant}" if variant else kind


def split_vf_model(name: str) -> tuple[str, str | None] | None:
    """``(kind, variant)`` of a value-function model name (``vhat`` -> ``("vhat", None)``,
    ``vhat_h04`` -> ``("vhat", "h04")``); None for any other name."""
    if name in ("vhat", "vs"):
        return name, None
    kind, _, variant = name.partition("_")
    return (kind, variant) if kind in VF_VARIANTS and variant else None


def with_vf_variant(cfg: Mapping[str, Any], kind: str, variant: str | None) -> dict:
    """``cfg`` with ``value_functions.<kind>`` replaced by variant ``variant`` deep-merged over it
    (``variant`` None: ``cfg`` itself). What a variant's training, its training hash and its checks
    read: every other key is the base configuration's."""
    if not variant:
        return cfg
    section = VF_VARIANTS.get(kind)
    variants = (cfg["value_functions"].get(section) or {}) if section else {}
    if variant not in variants:
        raise ConfigError(f"unknown {kind} variant '{variant}' (value_functions.{section or kind + '_variants'}: "
                          f"{sorted(variants) or 'none'})")
    vf = {**cfg["value_functions"], kind: deep_merge(cfg["value_functions"][kind], variants[variant])}
    return {**cfg, "value_functions": vf}


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
    fan-out (``runs``, ``agent_counts``, ``seeds``) is left out: adding a run or a seed to a study
    does not change the cells already computed."""
    method, mcfg = method_config(cfg, run)
    return {
        "study": {k: v for k, v in cfg["studies"][study].items() if k not in FAN_OUT_KEYS},
        "arena": cfg["arenas"][cfg["studies"][study]["arena"]],
        "agents": cfg["agents"],
        "sim": study_sim(cfg, study),
        "observation": run_observation(cfg, run),
        "method": method,
        "method_config": {k: v for k, v in mcfg.items() if k not in TRAINING_ONLY_KEYS},
    }


def write_if_changed(path: str | Path, text: str) -> Path:
    """Write ``text`` only if the file content differs (keeps mtimes stable for Snakemake)."""
    from madpinn.atomic import atomic_write

    path = Path(path)
    if path.is_file() and path.read_text() == text:
        return path
    return atomic_write(path, lambda tmp: tmp.write_text(text))


OUTPUT_PATH_KEYS = ("paths.results", "paths.figures")
"""the directories the workflow writes (checked before any job, dry runs included)"""


def unwritable_reason(path: str | Path) -> str | None:
    """Why directory ``path`` could not be created or written, or None when it can, found without
    writing anything (a dry run's check): the path or its nearest existing ancestor must be a
    directory this process may write (``os.access``: permissions, read-only mounts, immutable
    directories) on a file system with storage (``/proc``, ``/sys`` have none)."""
    import os

    path = Path(path).absolute()
    node = path
    while not node.exists() and node != node.parent:
        node = node.parent
    if not node.is_dir():
        return f"{node} is not a directory"
    if not os.access(node, os.W_OK | os.X_OK):
        return f"{node} is not writable" + (" (read-only file system)" if os.statvfs(node).f_flag & os.ST_RDONLY else "")
    if os.statvfs(node).f_blocks == 0:
        return f"{node} is on a file system without storage (e.g. /proc, /sys)"
    return None


def _unwritable_output_paths(cfg: Mapping[str, Any]) -> list[str]:
    """A line naming each key of :data:`OUTPUT_PATH_KEYS` whose directory cannot be written
    (:func:`unwritable_reason`); relative paths are taken from the working directory."""
    lines = []
    for key in OUTPUT_PATH_KEYS:
        value = lookup_key(cfg, key)
        reason = unwritable_reason(value) if value is not None else None
        if reason:
            lines.append(f"  - '{key}': {value!r} cannot be written: {reason}")
    return lines


def backend_names() -> list[str]:
    """The simulation backends a config may name: the schema's ``sim.backend`` enum (where a new
    backend is added, docs/reference/architecture.md)."""
    return list(_schema()["properties"]["sim"]["properties"]["backend"]["enum"])


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
