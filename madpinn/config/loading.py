"""Loading config files: YAML with one clear message per error, overlays merged in order, validated."""

from __future__ import annotations

from pathlib import Path
from typing import Iterable

import yaml

from madpinn.config.errors import ConfigError, ConfigFileError
from madpinn.config.merge import deep_merge
from madpinn.config.yaml_text import parse_yaml
from madpinn.config.validation import validate_config


def load_yaml(path: str | Path) -> dict:
    path = Path(path)
    if not path.is_file():
        raise ConfigFileError(f"config file not found: {path}")
    try:
        data = parse_yaml(path.read_text())
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
