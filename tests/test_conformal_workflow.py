"""Issue 62: the calibration is a workflow step. With the conformal overlay (smoke sizes) `all` plans
the calibration of the base V̂ and its table, and the cells of a run that deploys a level depend
on the calibration report (passed as --model calibration=); without the overlay nothing changes."""

from __future__ import annotations

from pathlib import Path

import yaml

from conftest import REPO
from workflow_helpers import copy_repo, planned_jobs, run_in


def _overlay(copy: Path) -> Path:
    """The conformal overlay at smoke size: one tiny cell per study, the runs as shipped."""
    cfg = yaml.safe_load((REPO / "workflow" / "configs" / "conformal.yaml").read_text())
    for name, study in cfg["studies"].items():
        study.update(agent_counts=[study["agent_counts"][0] if study["arena"] == "small" else 16], scenarios=1)
    path = copy / "conformal.yaml"
    path.write_text(yaml.safe_dump(cfg, sort_keys=False))
    return path


def test_calibration_is_planned_and_the_cp_cells_load_it(tmp_path):
    copy = copy_repo(tmp_path / "repo")
    plain = planned_jobs(run_in(copy, "-n", "all"))
    assert "calibrate_vhat" not in plain            # the protocol deploys no level
    overlay = _overlay(copy)
    jobs = planned_jobs(run_in(copy, "-n", "all", configfiles=("smoke.yaml", overlay.name)))
    assert jobs.get("calibrate_vhat") == 1, jobs
    assert {k: v for k, v in jobs.items() if k != "calibrate_vhat"} == plain   # the cp studies are not in all
    proc = run_in(copy, "-n", "-p", "conformal_cells", configfiles=("smoke.yaml", overlay.name))
    cells = planned_jobs(proc)
    assert cells.get("calibrate_vhat") == 1 and cells.get("evaluate", 0) >= 5, cells
    out = proc.stdout
    assert "calibration=results/conformal/validation/vhat_calibration.json" in out   # the overlay's own results
    assert out.count("--model calibration=") == sum(1 for ln in out.splitlines()
                                                    if "python -m madpinn evaluate" in ln and "-cpeps" in ln)
    # the page reads every cell of those studies and the calibration
    page = planned_jobs(run_in(copy, "-n", "conformal_page", configfiles=("smoke.yaml", overlay.name)))
    assert page.get("conformal_page") == 1 and page.get("evaluate") == cells.get("evaluate"), page
