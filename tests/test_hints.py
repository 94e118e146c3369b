"""Hints in error messages name real commands: a missing checkpoint's suggested Snakemake target
has a rule that builds it (checked with a real dry run of the smoke workflow)."""

from __future__ import annotations

import re

import pytest
import torch

from madpinn.config import method_config
from madpinn.evaluation.job import policy_context
from madpinn.marl.checkpoint import CheckpointError as MarlCheckpointError
from madpinn.policies import make_policy
from madpinn.value_functions import CheckpointError, load_vs

from conftest import run_snakemake


def _hint_target(exc) -> str:
    msg = str(exc.value)
    assert "not found" in msg
    match = re.search(r"snakemake -j2 (\S+)", msg)
    assert match, f"no Snakemake command in: {msg}"
    return match.group(1)


def test_missing_checkpoint_hints_name_targets_with_a_rule(tmp_path, monkeypatch, smoke_cfg):
    monkeypatch.chdir(tmp_path)  # the workflow's directory, before any training
    targets = []
    for run in ("madpinn", "safemarl", "defmarl-n3", "defmarl-n8"):  # the first file each one loads
        method, mcfg = method_config(smoke_cfg, run)
        ctx = policy_context(smoke_cfg, mcfg, seed=0, batch_index=0, device=torch.device("cpu"), dtype=torch.float32)
        with pytest.raises((CheckpointError, MarlCheckpointError)) as exc:
            make_policy(method, ctx)
        targets.append(_hint_target(exc))
    with pytest.raises(CheckpointError) as exc:
        load_vs(ctx.models_dir / "vs.pt")
    targets.append(_hint_target(exc))
    assert len(set(targets)) == 5
    proc = run_snakemake(tmp_path, "-n", *targets)  # fails (MissingRuleException) for a target without a rule
    out = proc.stdout + proc.stderr
    for rule in ("train_vhat", "train_vs", "train_safemarl_nominal", "train_defmarl"):
        assert f"rule {rule}:" in out or f"localrule {rule}:" in out, out[-3000:]
