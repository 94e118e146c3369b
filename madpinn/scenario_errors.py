"""The error of a scenario request that cannot be met: a leaf module (no package imports), so
both scenario generators (:mod:`madpinn.scenarios`, :mod:`madpinn.conflicts`) raise it without
importing each other."""

from __future__ import annotations


class ScenarioInfeasibleError(ValueError):
    """The requested number of agents cannot be placed with the required separation."""
