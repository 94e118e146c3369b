"""The workflow's terminal summary (madpinn/run_log.py): per-job blocks out, progress every 10 %,
warnings and errors always."""

import logging

from madpinn.run_log import SummaryFilter, install_summary


def _rec(msg=None, level=logging.INFO, **extra):
    r = logging.LogRecord("snakemake.logging", level, __file__, 1, msg, None, None)
    r.__dict__.update(extra)
    return r


def test_summary_keeps_errors_and_a_progress_line_every_ten_percent():
    f = SummaryFilter(step_pct=10.0)
    assert not f.filter(_rec(event="job_info", rule_name="all"))          # the `all` rule's target list
    assert not f.filter(_rec(event="shellcmd"))
    assert not f.filter(_rec("Select jobs to execute..."))
    assert not f.filter(_rec("Symlinking output file results/x.parquet from cache."))
    assert f.filter(_rec("Building DAG of jobs..."))
    assert f.filter(_rec(event="job_error", level=logging.ERROR))
    assert f.filter(_rec("Missing metadata", level=logging.WARNING))
    shown = [done for done in range(1, 355) if f.filter(_rec(event="progress", done=done, total=354))]
    assert len(shown) == 10 and shown[-1] == 354                          # 10 %, 20 %, …, 100 %
    assert all(100 * d / 354 >= 10 * (i + 1) for i, d in enumerate(shown[:-1]))


def test_full_output_on_request(monkeypatch):
    monkeypatch.setenv("MADPINN_LOG", "full")
    assert install_summary("madpinn.test.full") is None
    monkeypatch.delenv("MADPINN_LOG")
    f = install_summary("madpinn.test.summary")
    logger = logging.getLogger("madpinn.test.summary")
    assert f in logger.filters
    logger.removeFilter(f)
