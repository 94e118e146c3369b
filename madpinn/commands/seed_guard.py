"""Protocol-seed guard of commands run by hand (issue 61): the protocol seeds (below
:data:`~madpinn.marl.validation.MIN_VALIDATION_SEED`) are for the workflow's table cells; a person
choosing, tuning or diagnosing uses validation seeds. ``evaluate`` by hand refuses a protocol seed
unless ``--protocol-seed-reason`` says why; the reason is recorded in the cell's JSON summary and its
MLflow run (tag :data:`REASON_KEY`).

The workflow's jobs are told apart by :data:`WORKFLOW_ENV`, which ``workflow/rules/common.smk`` sets
for every job it runs (an environment variable, not a flag in the rule's command: the rule's text is
part of the output cache's provenance hash, so a new flag would invalidate every cached cell).
"""

from __future__ import annotations

import os
from typing import Mapping

MIN_VALIDATION_SEED = 100
"""validation seeds start here (:data:`madpinn.marl.validation.MIN_VALIDATION_SEED`; not imported: a
cell job would then load a module its source hash does not cover)"""
WORKFLOW_ENV = "MADPINN_WORKFLOW_JOB"
REASON_KEY = "protocol_seed_reason"


class ProtocolSeedError(ValueError):
    """A protocol seed asked for by hand without a reason."""


def protocol_seed_reason(seed: int, reason: str | None, environ: Mapping[str, str] = os.environ) -> str | None:
    """The reason to record for ``seed`` (None: nothing to record); raises :class:`ProtocolSeedError`
    for a protocol seed run by hand without a reason."""
    if seed >= MIN_VALIDATION_SEED or environ.get(WORKFLOW_ENV):
        return reason.strip() if reason and reason.strip() else None
    if not reason or not reason.strip():
        raise ProtocolSeedError(f"seed {seed} is a protocol seed (< {MIN_VALIDATION_SEED}: the tables' cells), "
                                "evaluated by hand without a reason")
    return reason.strip()
