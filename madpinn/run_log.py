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


# --- Ctrl-C: one line, the same command resumes (issue 66 item 3) ---

INTERRUPTED = ("madpinn: interrupted (Ctrl-C) — fix: run the same command again: finished jobs are kept and the "
               "interrupted ones rerun")
_TERMINATING = "Terminating processes on user request"


class InterruptFilter(logging.Filter):
    """After Snakemake's "Terminating processes on user request" (Ctrl-C, or SIGINT to snakemake),
    drop the rest of its terminal output (an "Error in rule … exit status 130" block per stopped
    job, the failed job's log, "At least one job did not complete successfully") and print
    :data:`INTERRUPTED` once at exit instead. Snakemake's log file keeps everything (the filter
    sits on its terminal handler only); with ``MADPINN_LOG=full`` nothing is dropped, the line
    still comes last."""

    def __init__(self, drop: bool = True):
        super().__init__()
        self.drop = drop
        self.interrupted = False

    def filter(self, record: logging.LogRecord) -> bool:
        if not self.interrupted:
            msg = record.msg if isinstance(record.msg, str) else ""
            if msg.startswith(_TERMINATING):
                self.interrupted = True
                import atexit

                atexit.register(self._last_line)
                return not self.drop
            return True
        return not self.drop

    def _last_line(self) -> None:
        import sys

        sys.stderr.write(f"\n{INTERRUPTED}\n")
        sys.stderr.flush()


def _terminal_handlers(logger: logging.Logger) -> list[logging.Handler]:
    return [h for h in logger.handlers if isinstance(h, logging.StreamHandler) and not isinstance(h, logging.FileHandler)]


def install_interrupt_line(logger_name: str = "snakemake.logging") -> InterruptFilter:
    """Add an :class:`InterruptFilter` to Snakemake's terminal handler (to the logger itself when
    it has none of its own, e.g. with a logger plugin)."""
    logger = logging.getLogger(logger_name)
    f = InterruptFilter(drop=os.environ.get(FULL_ENV, "").lower() != "full")
    for target in _terminal_handlers(logger) or [logger]:
        target.addFilter(f)
    return f


def remove_own_logfile(workflow) -> None:
    """Remove the log file Snakemake opened for this start (``.snakemake/log/<time>.snakemake.log``,
    before any workflow code ran) and the ``.snakemake/log`` and ``.snakemake`` directories when
    that leaves them empty: for a start refused before it did anything (run in the wrong
    directory), so that nothing stays behind. Anything else in ``.snakemake/`` is kept."""
    from pathlib import Path

    manager = getattr(workflow, "logger_manager", None)
    handlers = dict(getattr(manager, "logfile_handlers", {}) or {})
    for handler, path in handlers.items():
        try:
            handler.close()
            logging.getLogger("snakemake.logging").removeHandler(handler)
            manager.logfile_handlers.pop(handler, None)
            Path(path).unlink(missing_ok=True)
        except OSError:
            continue
        for d in (Path(path).parent, Path(path).parent.parent):
            if d.name in ("log", ".snakemake"):
                try:
                    d.rmdir()   # only when empty
                except OSError:
                    break
