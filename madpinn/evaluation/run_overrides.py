"""A run's own deployment override of the shared ``agents`` section (the speed governor of
issue 33: a lower ``v_max`` for one run; V̂ and V_s keep the section's trained limits).

Imported by :mod:`madpinn.evaluation.cell` by name (its registry ``_MODULES``) only for a run
that has such an override, so this module is hashed into those cells alone
(``eval_source_hash`` in ``workflow/rules/common.smk``): editing it reruns the governed cells and
no other.
"""

from __future__ import annotations

from typing import Mapping

from madpinn.settings import AgentSettings


def governed_limits(agents: Mapping, override: Mapping) -> AgentSettings:
    """The agents a run simulates: its ``agents`` override (e.g. ``{v_max: 0.8}``, m/s) merged
    key by key over the shared ``agents`` section."""
    return AgentSettings.from_config({"agents": {**agents, **override}})
