"""Rule files register what they add (tables, the trained files a run loads, final targets) through
one small API in ``workflow/rules/common.smk``; ``all``, the evaluate rule and the report read the
registry when they build their inputs, so the order of the includes does not change the DAG."""

from __future__ import annotations

import re

from workflow_helpers import copy_repo, planned_jobs, run_in

# the rule files that register something, moved to the front (the report before any table, the
# methods after it): only common.smk and tracking.smk stay first
MOVED = ("report.smk", "conflicts.smk", "madpinn.smk", "tables.smk", "figures.smk", "mujoco.smk")


def _permuted(snakefile: str) -> str:
    lines = snakefile.splitlines(keepends=True)
    moved = [next(ln for ln in lines if f'rules/{m}"' in ln) for m in MOVED]
    rest = [ln for ln in lines if ln not in moved]
    at = next(i for i, ln in enumerate(rest) if 'rules/tracking.smk"' in ln) + 1
    return "".join(rest[:at] + moved + rest[at:])


def test_all_does_not_depend_on_the_include_order(tmp_path):
    copy = copy_repo(tmp_path / "repo")
    before = planned_jobs(run_in(copy, "-n", "all"))
    original = (copy / "Snakefile").read_text()
    permuted = _permuted(original)
    includes = re.findall(r'rules/(\w+)\.smk"', permuted)
    assert includes.index("report") < min(includes.index(f) for f in ("tables", "madpinn", "train", "safemarl")), includes
    assert includes != re.findall(r'rules/(\w+)\.smk"', original)
    (copy / "Snakefile").write_text(permuted)
    after = planned_jobs(run_in(copy, "-n", "all"))
    assert after == before, (before, after)
    # every table, the report and the value-function checks are planned (smoke: 8 tables)
    assert sum(n for rule, n in after.items() if rule.startswith("table_")) == 8, after
    assert {"reproduction_report", "verify_vhat", "validate_vs_grid", "fig_trajectories"} <= set(after), after
