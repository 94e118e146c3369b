"""Configuration: loading, overlaying, schema validation with one clear message, hashing.

The schema lives in ``workflow/schemas/config.schema.yaml``; the workflow and the CLI both call
:func:`validate_config` before any work starts. One module per concern:

- :mod:`~madpinn.config.errors`: the error classes;
- :mod:`~madpinn.config.merge`: :func:`deep_merge`, the one overlay rule;
- :mod:`~madpinn.config.loading`: YAML files read, merged and validated (:func:`load_config`);
- :mod:`~madpinn.config.schema`: the JSON schema;
- :mod:`~madpinn.config.validation` and :mod:`~madpinn.config.rules`: the schema check and the
  cross-field rules (:func:`validate_config`);
- :mod:`~madpinn.config.runs`: a study's and a run's resolved settings;
- :mod:`~madpinn.config.vf_variants`: value-function variants;
- :mod:`~madpinn.config.models`: the agent model a study flies and a value function is trained for;
- :mod:`~madpinn.config.hashing`: hashes of config parts;
- :mod:`~madpinn.config.paths`: the repository root and the output directories;
- :mod:`~madpinn.config.cells`: the checks of one cell named by a target.

The names below are the package's interface; import them from ``madpinn.config``.
"""

from madpinn.config.cells import check_cell
from madpinn.config.errors import ConfigError, ConfigFileError, TargetError, WorkingDirectoryError
from madpinn.config.hashing import config_hash, hashed_agents, hashed_key, lookup_key, subtree_hash
from madpinn.config.loading import load_config, load_yaml
from madpinn.config.merge import deep_merge
from madpinn.config.models import describe_model, model_methods, model_identity, study_agents
from madpinn.config.paths import OUTPUT_PATH_KEYS, REPO_ROOT, unwritable_reason, write_if_changed
from madpinn.config.runs import (DEPLOYMENT_ONLY_KEYS, FAN_OUT_KEYS, TRAINING_ONLY_KEYS, RunSettings, hashed_method,
                                 job_config, method_config, run_agents, run_observation, run_vhat, run_vs, study_backend,
                                 study_pattern, study_sim)
from madpinn.config.schema import FILLED, SCHEMA_PATH, backend_names, fill_defaults
from madpinn.config.validation import validate_config
from madpinn.config.vf_variants import VF_VARIANTS, split_vf_model, vf_model_name, with_vf_variant


__all__ = [
    "ConfigError", "ConfigFileError", "TargetError", "WorkingDirectoryError", "check_cell", "config_hash", "hashed_agents", "hashed_key", "lookup_key",
    "subtree_hash", "load_config", "load_yaml", "deep_merge", "OUTPUT_PATH_KEYS", "REPO_ROOT", "unwritable_reason",
    "write_if_changed", "DEPLOYMENT_ONLY_KEYS", "FAN_OUT_KEYS", "TRAINING_ONLY_KEYS", "RunSettings", "job_config", "method_config",
    "run_agents", "run_observation", "run_vhat", "run_vs", "hashed_method", "study_backend", "study_pattern", "study_sim", "SCHEMA_PATH",
    "FILLED", "backend_names", "fill_defaults", "validate_config", "VF_VARIANTS", "split_vf_model", "vf_model_name", "with_vf_variant",
    "model_methods", "describe_model", "model_identity", "study_agents",
]
