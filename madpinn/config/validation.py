"""Validation of a configuration: the schema, each value-function variant merged over its base,
the cross-field rules (:mod:`madpinn.config.rules`) and the output paths, all violations at once."""

from __future__ import annotations

import math
from typing import Any, Mapping

from madpinn.config.errors import ConfigError
from madpinn.config.paths import _unwritable_output_paths
from madpinn.config.rules import _cross_field_errors, _infeasible_agent_counts, _infeasible_patterns
from madpinn.config.schema import FILLED, _declared_keys, _schema, fill_defaults
from madpinn.config.vf_variants import VF_VARIANTS, with_vf_variant


def _key_path(error) -> str:
    parts = [str(p) for p in error.absolute_path]
    return ".".join(parts) if parts else "<top level>"


def _unknown_keys(error, root: Mapping[str, Any]) -> list[str]:
    """The keys an ``unevaluatedProperties`` error really rejects. A failing ``allOf`` part (e.g.
    ``value_functions.vhat.iterations: 0``) drops its annotations, so the validator lists every key
    that part declares as unexpected; only the keys no part declares are."""
    declared = _declared_keys(error.schema, root)
    return sorted(k for k in error.instance if k not in declared)


def validate_config(cfg: dict) -> None:
    """Validate against the JSON schema, fill every absent key with its schema default, in place
    (:func:`~madpinn.config.schema.fill_defaults`: code reads every key, never a second default),
    then check the cross-field rules and that the output paths can be written
    (:func:`unwritable_reason`, writes nothing); raise :class:`ConfigError`. The one validator of
    the workflow (Snakefile), ``validate-config`` and every job (:func:`load_config`).

    All violations are reported at once, one line each, each naming its key; an invalid config is
    left as it was.
    """
    import jsonschema

    validator = jsonschema.Draft202012Validator(_schema())
    written = {k: v for k, v in cfg.items() if k != FILLED}   # FILLED: the loader's record, no config key
    errors = sorted(validator.iter_errors(written), key=lambda e: list(map(str, e.absolute_path)))
    lines = [f"  - '{key}': {value} is not a finite number" for key, value in _non_finite(written)]
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
        fill_defaults(cfg, validator.schema)
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


def _vf_variant_errors(cfg: Mapping[str, Any], validator) -> list[str]:
    """Schema errors of each value-function variant merged over its base (a variant is a partial
    section: what it yields must be a valid ``value_functions.<kind>``). Only that section is
    validated (against its own schema node, the root's ``$defs`` beside it): the rest of the merged
    config is the base's, already valid."""
    lines = []
    root = validator.schema
    for kind, section in VF_VARIANTS.items():
        variants = cfg["value_functions"].get(section) or {}
        if not variants:
            continue
        node = root["properties"]["value_functions"]["properties"][kind]
        sub = validator.evolve(schema={**node, "$defs": root["$defs"]})
        for variant in variants:
            try:
                merged = with_vf_variant(cfg, kind, variant)["value_functions"][kind]
            except ConfigError as e:   # an unknown or circular `from`
                lines.append(f"  - 'value_functions.{section}.{variant}.from': {e}")
                continue
            for err in sub.iter_errors(merged):
                key = ".".join(["value_functions", section, variant, *map(str, err.absolute_path)])
                message = err.message
                if err.validator == "unevaluatedProperties":
                    unknown = _unknown_keys(err, root)
                    if not unknown:   # only a sibling error (reported on its own) left the known keys unevaluated
                        continue
                    message = f"unknown keys {', '.join(map(repr, unknown))}"
                lines.append(f"  - '{key}' (merged over value_functions.{kind}): {message}")
    return lines
