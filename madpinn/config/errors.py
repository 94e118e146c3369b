"""The configuration's errors: one class per kind of bad input, each message naming its key or file."""

from __future__ import annotations


class ConfigError(ValueError):
    """Invalid configuration; the message names the offending key."""


class ConfigFileError(ConfigError):
    """A config file named on the command line (or the repository's config.yaml) does not exist
    or holds no mapping."""


class WorkingDirectoryError(ConfigError):
    """The workflow was started outside the repository without naming its directory (--directory)."""


class TargetError(ConfigError):
    """A workflow target (an output path asked for by name) outside this configuration."""
