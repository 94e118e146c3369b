"""A workflow run's terminal output that fits on a screen: Snakemake's per-job blocks (rule, input,
output, reason, shell command; the ``all`` rule's alone lists every target) are left out, and its
progress line comes at every ``step_pct`` percent of the jobs instead of after each job. Warnings,
errors and failed jobs' logs pass unchanged; every job's full output is still in its ``log:`` file
and in Snakemake's own log (``.snakemake/log/``). ``MADPINN_LOG=full`` keeps everything.

Installed by the Snakefile on real runs only (a dry run's job listing is its purpose), as a
``logging.Filter`` on Snakemake's logger: the standard library's hook, no Snakemake internals.
"""

from __future__ import annotations

import logging
import os

FULL_ENV = "MADPINN_LOG"          # =full: Snakemake's complete output
# events (snakemake_interface_logger_plugins.common.LogEvent values) left out of the summary
_DROPPED_EVENTS = {"job_info", "group_info", "shellcmd", "job_started", "job_finished"}
# plain messages left out: one per scheduling round or per restored file
_DROPPED_PREFIXES = ("Select jobs to execute", "Symlinking output file", "Copying output file")


class SummaryFilter(logging.Filter):
    """Drop per-job chatter; pass a progress record only at every ``step_pct`` % and at the end."""

    def __init__(self, step_pct: float = 10.0):
        super().__init__()
        self.step_pct = step_pct
        self._next_pct = step_pct

    def filter(self, record: logging.LogRecord) -> bool:
        if record.levelno >= logging.WARNING:
            return True
        event = str(getattr(record, "event", "") or "")
        if event in _DROPPED_EVENTS:
            return False
        if event == "progress":
            done, total = int(getattr(record, "done", 0)), int(getattr(record, "total", 0) or 1)
            pct = 100.0 * done / total
            if done >= total or pct >= self._next_pct:
                while self._next_pct <= pct:
                    self._next_pct += self.step_pct
                return True
            return False
        msg = record.msg if isinstance(record.msg, str) else ""
        return not msg.startswith(_DROPPED_PREFIXES)


def install_summary(logger_name: str = "snakemake.logging", step_pct: float = 10.0) -> SummaryFilter | None:
    """Add a :class:`SummaryFilter` to the named logger (Snakemake's) unless ``MADPINN_LOG=full``;
    returns it (None when not installed)."""
    if os.environ.get(FULL_ENV, "").lower() == "full":
        return None
    f = SummaryFilter(step_pct)
    logging.getLogger(logger_name).addFilter(f)
    return f
