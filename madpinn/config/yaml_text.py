"""YAML text to Python, fast: libyaml's C loader where PyYAML has it (every job reads the config and
the schema; the pure-Python loader spent ≈ 0.4 s of each job's start on them), the same safe tag set.
On an error the pure-Python loader parses again, so a bad file gets its message and position."""

from __future__ import annotations

import yaml

FAST_SAFE_LOADER = getattr(yaml, "CSafeLoader", yaml.SafeLoader)
"""libyaml's safe loader (``yaml.SafeLoader`` where PyYAML was built without libyaml)"""


def parse_yaml(text: str):
    """``yaml.safe_load(text)``'s value; a :class:`yaml.YAMLError` is the pure-Python loader's."""
    try:
        return yaml.load(text, Loader=FAST_SAFE_LOADER)
    except yaml.YAMLError:
        return yaml.safe_load(text)
