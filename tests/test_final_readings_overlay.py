"""scripts/final_readings_overlay.py (issue 60): the pre-registered kept readings of a verdict become
a seed-0 overlay that the workflow's config accepts, with the protocol's and the anchor's cells keyed
exactly as the protocol's own; a verdict that names a study the validation overlay lacks is refused."""

from __future__ import annotations

import importlib.util

import pytest
import yaml

from conftest import REPO
from madpinn.commands import settings_hash
from madpinn.config import load_config

LAWS = REPO / "workflow" / "configs" / "scenario_laws.yaml"


def _script():
    spec = importlib.util.spec_from_file_location("final_readings_overlay", REPO / "scripts" / "final_readings_overlay.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _reading(study, run, checks=3):
    return {"study": study, "run": run, "horizon_s": 6.0, "checks_passed": checks, "checks": 9}


def test_kept_readings_make_a_valid_seed_0_overlay_keyed_like_the_protocol(tmp_path):
    script, laws = _script(), yaml.safe_load(LAWS.read_text())
    verdict = {"protocol": _reading("law_uniform", "madpinn"), "closest": _reading("grid_uniform", "madpinn-sensall", 5),
               "reproducing": [_reading("law_within_1m", "madpinn", 9), _reading("law_within_1m", "madpinn", 9)]}
    overlay = script.overlay(verdict, laws, chosen_on="paper_figures/table_ii_readings/verdict.json")
    assert overlay["studies"]["grid_uniform"]["runs"] == ["madpinn-sensall"]       # the closest, once
    assert overlay["table_ii_readings"]["chosen_on"] == "paper_figures/table_ii_readings/verdict.json"   # summarised by the page
    assert overlay["studies"]["law_within_1m"] == {"arena": "large", "pattern": "goals_within_1m", "agent_counts": [64, 128, 256],
                                                   "seeds": [0], "scenarios": 20, "in_all": False, "runs": ["madpinn"]}
    assert overlay["studies"]["baselines_large"]["seeds"] == [0]
    path = tmp_path / "final.yaml"
    path.write_text(yaml.safe_dump(overlay))
    base = load_config([REPO / "config.yaml", REPO / "workflow" / "configs" / "shipped.yaml"])
    final = load_config([REPO / "config.yaml", REPO / "workflow" / "configs" / "shipped.yaml", path])   # sensall: the overlay's methods
    for study in ("scaling", "main"):
        assert settings_hash(final, "evaluate", study=study, run="madpinn") == settings_hash(base, "evaluate", study=study, run="madpinn")
    # the protocol's reading is not a study of its own; a study the validation overlay lacks is refused
    assert script.kept_readings({"protocol": _reading("law_uniform", "madpinn"), "closest": _reading("law_uniform", "madpinn")}) == []
    with pytest.raises(SystemExit, match="not a study of the validation overlay"):
        script.overlay({"protocol": _reading("law_uniform", "madpinn"), "closest": _reading("nosuch", "madpinn")}, laws)
    with pytest.raises(SystemExit, match="T = 6 s"):
        script.overlay({"protocol": _reading("law_uniform", "madpinn"), "closest": {**_reading("law_within_1m", "madpinn"), "horizon_s": 10.0}}, laws)
