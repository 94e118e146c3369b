"""What config a job depends on is said once, by each command beside its parser (``reads``,
``madpinn.commands.command_reads``), and the
workflow's rules carry it: a training reruns for its own training settings only (never for a
deployment knob or a validation setting), a check for the settings it reads."""

from __future__ import annotations

import re

import pytest

from conftest import REPO
from madpinn.config import deep_merge
from madpinn.commands import command_reads, settings_hash
from madpinn.value_functions.build import training_hash

RULES = REPO / "workflow" / "rules"


def _changed(cfg, overlay, command, **job) -> bool:
    return settings_hash(deep_merge(cfg, overlay), command, **job) != settings_hash(cfg, command, **job)


DEPLOYMENT = [{"observation": {"carrot_margin": 0.35}}, {"observation": {"neighbour_goal": "ego"}},
              {"methods": {"madpinn": {"look_ahead": 0.05}}}]
VALIDATION = [{"value_functions": {"vhat": {"validation": {"samples": 1024}}}},
              {"value_functions": {"vhat": {"validation": {"scenario": {"samples": 32}}}}},
              {"value_functions": {"vs": {"validation": {"rollout_samples": 500}}}},
              {"value_functions": {"vs": {"validation": {"grid": {"nodes": 11}}}}}]


@pytest.mark.parametrize("kind", ["vhat", "vs"])
def test_value_training_reruns_for_its_training_settings_only(smoke_cfg, kind):
    for overlay in DEPLOYMENT + VALIDATION:
        assert not _changed(smoke_cfg, overlay, "train-value", kind=kind), overlay
    assert _changed(smoke_cfg, {"value_functions": {kind: {"iterations": 31}}}, "train-value", kind=kind)
    assert _changed(smoke_cfg, {"value_functions": {"seed": 7}}, "train-value", kind=kind)
    assert _changed(smoke_cfg, {"agents": {"u_max": 9.0}}, "train-value", kind=kind)
    other = "vs" if kind == "vhat" else "vhat"
    assert not _changed(smoke_cfg, {"value_functions": {other: {"iterations": 31}}}, "train-value", kind=kind)
    # the package's own training hash (checked against shipped models) is the rule's param
    assert settings_hash(smoke_cfg, "train-value", kind=kind) == settings_hash(
        deep_merge(smoke_cfg, {"value_functions": {kind: {"validation": {}}}}), "train-value", kind=kind)
    assert training_hash(smoke_cfg, kind) in str(command_reads()["train-value"](smoke_cfg, kind=kind))


def test_marl_trainings_rerun_for_their_own_method_only(smoke_cfg):
    for overlay in VALIDATION + [{"methods": {"mppi": {"samples": 17}}}]:
        assert not _changed(smoke_cfg, overlay, "train-safemarl-nominal"), overlay
        assert not _changed(smoke_cfg, overlay, "train-defmarl", variant="n3"), overlay
    assert _changed(smoke_cfg, {"methods": {"safemarl": {"nominal": {"ppo": {"iterations": 4}}}}}, "train-safemarl-nominal")
    assert not _changed(smoke_cfg, {"methods": {"safemarl": {"nominal": {"ppo": {"iterations": 4}}}}},
                        "train-defmarl", variant="n3")


def test_each_check_reruns_for_the_settings_it_reads(smoke_cfg):
    vhat_samples, vhat_scenario, vs_rollouts, vs_grid = VALIDATION
    assert _changed(smoke_cfg, vhat_samples, "validate-vhat") and not _changed(smoke_cfg, vhat_scenario, "validate-vhat")
    assert _changed(smoke_cfg, vhat_scenario, "verify-vhat") and not _changed(smoke_cfg, vhat_samples, "verify-vhat")
    assert _changed(smoke_cfg, vs_rollouts, "validate-vs") and not _changed(smoke_cfg, vhat_samples, "validate-vs")
    assert _changed(smoke_cfg, vs_grid, "solve-vs-grid") and not _changed(smoke_cfg, vs_rollouts, "solve-vs-grid")
    # the grid solves the pair system that PairSystem.from_config builds from V_s's own domain
    assert _changed(smoke_cfg, {"value_functions": {"vs": {"horizon": 0.5}}}, "solve-vs-grid")


def test_outputs_and_cells_follow_what_they_read(smoke_cfg):
    assert _changed(smoke_cfg, {"oracle": {"steps": 7}}, "oracle", arena="small")
    assert not _changed(smoke_cfg, {"arenas": {"large": {"half_width": 9.0}}}, "oracle", arena="small")
    assert _changed(smoke_cfg, {"methods": {"nominal": {"label": "PD"}}}, "table", study="main")
    assert not _changed(smoke_cfg, {"studies": {"main": {"scenarios": 3}}}, "table", study="main")
    assert _changed(smoke_cfg, {"observation": {"carrot_margin": 0.35}}, "evaluate", study="main", run="madpinn")
    assert not _changed(smoke_cfg, {"studies": {"main": {"seeds": [0, 1, 2]}}}, "evaluate", study="main", run="madpinn")


def test_every_rule_declares_the_settings_of_the_command_it_runs():
    """Each rule's ``settings=settings_hash("<command>", ...)`` names its ``shell:`` command, and
    every such command declares its config dependency beside its parser (`reads`)."""
    checked = 0
    for smk in sorted(RULES.glob("*.smk")):
        for block in re.split(r"\n\s*rule\b", smk.read_text())[1:]:
            shell = re.search(r"python -m madpinn ([a-z-]+)", block)
            settings = re.search(r"settings=settings_hash\(\"([a-z-]+)\"", block)
            if shell is None or shell.group(1) in ("tracking-init", "track-cells", "install-shipped"):   # MLflow glue, model copy
                continue
            assert settings is not None, (smk.name, shell.group(1))
            assert settings.group(1) == shell.group(1) and settings.group(1) in command_reads(), (smk.name, settings.group(0))
            checked += 1
    assert checked >= 15, checked
