"""Code that can change a result is hashed into exactly the jobs that run it (issue 48).

The V̂/V_s training stages, the DEF-MARL checkpoint choice and a run's ``agents`` override used to
live in the command layer, which no job hashes: editing them reran nothing. Each now lives in the
library; here a semantic edit of each (in a copy of the repository) must make the dry run plan
exactly the jobs that run it (for their changed ``source`` param, or downstream of another of
them) and no other job except their downstream ones.

No job runs: the copy's smoke DAG is marked complete with empty outputs (``--touch``), which
records every job's params as a real run would; the dry runs then read them. Seconds.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from workflow_helpers import NO_TRACKING, copy_repo, run_in, write_overlay

FILES = ("smoke.yaml", "notrack.yaml")


@pytest.fixture(scope="module")
def touched(tmp_path_factory) -> Path:
    """A copy of the repository whose smoke DAG (``all``) is complete: every output exists (empty)
    and Snakemake's metadata holds every job's params."""
    copy = copy_repo(tmp_path_factory.mktemp("moved") / "clone")
    write_overlay(copy / "notrack.yaml", NO_TRACKING)
    for line in run_in(copy, "--summary", "-j1", "all", configfiles=FILES).stdout.splitlines()[1:]:
        path = copy / line.split("\t")[0]
        path.parent.mkdir(parents=True, exist_ok=True)
        path.touch()
    run_in(copy, "--touch", "--forceall", "-j1", "all", configfiles=FILES)
    assert _plan(copy) == {}
    return copy


def _plan(copy: Path) -> dict[tuple[str, str], str]:
    """(rule, wildcards) -> reason of every job the dry run plans (``all`` left out)."""
    out = run_in(copy, "-n", "-j1", "all", configfiles=FILES).stdout
    if "Nothing to be done" in out:
        return {}
    jobs = {}
    for rule, body in re.findall(r"^rule (\w+):\n((?:    .*\n?)*)", out, re.M):
        wildcards = re.search(r"^    wildcards: (.*)$", body, re.M)
        jobs[rule, wildcards.group(1) if wildcards else ""] = re.search(r"^    reason: (.*)$", body, re.M).group(1)
    jobs.pop(("all", ""), None)
    assert jobs, out[-3000:]
    return jobs


def _assert_plans_exactly(jobs: dict[tuple[str, str], str], expected: set[tuple[str, str]]) -> None:
    """The dry run plans every job of ``expected`` (each for its changed params, or downstream of
    another such job), no other job for its params, and every other job only downstream of them."""
    changed = {job for job, reason in jobs.items() if "Params have changed" in reason}
    assert changed and changed <= expected <= set(jobs), (sorted(changed), sorted(expected), sorted(jobs))
    downstream = {job: reason for job, reason in jobs.items() if job not in expected}
    assert all(reason.startswith("Input files updated by another job") and ";" not in reason
               for reason in downstream.values()), downstream


def _edit_and_plan(copy: Path, rel: str, old: str, new: str) -> dict[tuple[str, str], str]:
    """Replace the one occurrence of ``old`` by ``new`` in ``madpinn/<rel>``, plan, restore."""
    path = copy / "madpinn" / rel
    original = path.read_text()
    assert original.count(old) == 1, (rel, old)
    path.write_text(original.replace(old, new))
    try:
        return _plan(copy)
    finally:
        path.write_text(original)


def _cells(copy: Path, runs: set[str]) -> set[tuple[str, str]]:
    """Jobs (as the dry run prints them) of the smoke DAG's evaluation cells of ``runs``."""
    out = set()
    for p in (copy / "results" / "smoke" / "eval").glob("*/*/*/*.parquet"):
        backend, study, run = p.parts[-4:-1]
        n, seed = re.fullmatch(r"n(\d+)_seed(\d+)", p.stem).groups()
        if run in runs:
            out.add(("evaluate", f"backend={backend}, study={study}, run={run}, n={n}, seed={seed}"))
    return out


def test_editing_the_checkpoint_choice_reruns_the_defmarl_trainings_only(touched):
    jobs = _edit_and_plan(touched, "marl/best_model.py", "key > best_key", "key >= best_key")
    _assert_plans_exactly(jobs, {("train_defmarl", "variant=n3"), ("train_defmarl", "variant=n8")})
    assert ("train_safemarl_nominal", "") not in jobs   # the same training run, never validated


def test_editing_the_training_stages_reruns_the_value_function_trainings_only(touched):
    jobs = _edit_and_plan(touched, "value_functions/train.py", "net, info, fine_tune_settings, stage1,",
                          "net, info, {**fine_tune_settings, \"lr\": 0.5 * fine_tune_settings[\"lr\"]}, stage1,")
    variants = {p.stem[len("vhat_"):] for p in (touched / "results" / "smoke" / "models").glob("vhat_*.pt")}
    assert variants, "the smoke DAG trains no V̂ variant"
    _assert_plans_exactly(jobs, {("train_vhat", ""), ("train_vs", "")} | {("train_vhat_variant", f"variant={v}") for v in variants})
    assert not any(rule in ("train_defmarl", "train_safemarl_nominal") for rule, _ in jobs), jobs


def test_editing_the_agents_override_reruns_the_governed_cells_only(touched):
    cfg = _smoke_cfg(touched)
    governed = {f"{m}-{v}" for m, mcfg in cfg["methods"].items() for v, vcfg in (mcfg.get("variants") or {}).items()
                if vcfg.get("agents")}
    expected = _cells(touched, governed)
    assert expected, "the smoke DAG has no run with an agents override"
    jobs = _edit_and_plan(touched, "evaluation/run_overrides.py", "{**agents, **override}", "{**override, **agents}")
    _assert_plans_exactly(jobs, expected)
    assert {job for job in jobs if job[0] == "evaluate"} == expected, sorted(jobs)


def _smoke_cfg(copy: Path) -> dict:
    from madpinn.config import load_config

    return load_config([copy / "config.yaml", copy / "smoke.yaml"])


# --- issue 63: the command layer is hashed, definition by definition --------------------------------------------------
# A line of the command layer, which no job hashed before issue 63, yet changes a result: editing
# it plans exactly the job that runs it. (The other such lines are checked without a dry run, on
# the commands' source hashes: tests/test_workflow_sources.py.)

def test_editing_a_validation_seed_in_the_command_layer_reruns_that_check_only(touched):
    jobs = _edit_and_plan(touched, "commands/value_functions.py",
                          'seed=int(cfg["value_functions"]["seed"]) + 1)', 'seed=int(cfg["value_functions"]["seed"]) + 2)')
    _assert_plans_exactly(jobs, {("validate_vhat", "")})
