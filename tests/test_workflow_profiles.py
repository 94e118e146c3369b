"""Profiles and hygiene of the workflow: the default profile is loaded by the README command, the
Slurm profile requests the rules' resources (real sbatch jobs on a single-node cluster:
tests/test_workflow_reruns.py), `snakemake --lint` is clean,
and config strings never reach a shell (paths with spaces: tests/test_workflow_reruns.py)."""

import subprocess
import sys
import tomllib

import pytest
import yaml

from conftest import REPO, subprocess_env
from madpinn.config import ConfigError, deep_merge, validate_config


def _snakemake(*args, cwd=REPO, check=True):
    proc = subprocess.run([sys.executable, "-m", "snakemake", *args], cwd=cwd, capture_output=True, text=True,
                          env=subprocess_env(), timeout=600)
    if check:
        assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    return proc


def test_readme_command_loads_the_default_profile(tmp_path):
    out = _snakemake("-n", "-j2", "all", "-d", str(tmp_path))
    text = out.stdout + out.stderr
    assert "Using workflow specific profile profiles/default" in text
    assert "Shell command: python -m madpinn" in text            # printshellcmds: true (from the profile)


def test_lint_is_clean():
    out = _snakemake("--lint", "--configfile", "config.yaml", "workflow/configs/smoke.yaml")
    assert "Lints for" not in out.stdout + out.stderr, out.stdout + out.stderr


def test_conda_env_pins_match_pyproject():
    deps = tomllib.loads((REPO / "pyproject.toml").read_text())["project"]["dependencies"]
    env = yaml.safe_load((REPO / "workflow" / "envs" / "madpinn.yaml").read_text())
    pip = next(d["pip"] for d in env["dependencies"] if isinstance(d, dict))
    assert pip == deps


def test_slurm_profile_requests_the_rules_resources(tmp_path):
    overlay = tmp_path / "gpu.yaml"
    overlay.write_text("device: cuda\n")
    out = _snakemake("--profile", "profiles/slurm", "-n", "all", "-d", str(tmp_path),
                     "--configfile", "config.yaml", str(overlay))
    text = out.stdout + out.stderr
    blocks = {b.split(":", 1)[0].strip(): b for b in text.split("\nrule ")[1:]}
    vhat = blocks["train_vhat"]
    assert "gpu=1" in vhat and "mem_mb=4000" in vhat and "priority: 100" in vhat
    # the paper's budget: two 30 000-iteration stages of 4 096 samples, ~1.7 min per 1000 on a core
    runtime = int(vhat.split("runtime=")[1].split(",")[0].split()[0])
    assert 100 <= runtime <= 1000
    assert "gpu=1" not in blocks["evaluate"] and "runtime=" in blocks["evaluate"]
    # evaluation cells: the longest first (256 agents in the large arena before 3 in the small one),
    # all after the trainings
    prio = {b.split("output: ")[1].split(",")[0]: int(b.split("priority: ")[1].split()[0])
            for b in text.split("\nrule evaluate:")[1:]}
    big = prio["results/eval/mujoco/scaling/madpinn/n256_seed0.parquet"]
    small = prio["results/eval/mujoco/main/madpinn/n3_seed0.parquet"]
    assert small < big < 50, (small, big)


@pytest.mark.parametrize("bad", ["r$(touch pwned)", "r`touch pwned`", "r; touch pwned", "-rf", "a'b", 'a"b', "a|b"])
def test_schema_rejects_shell_metacharacters_in_paths(bad, paper_cfg):
    with pytest.raises(ConfigError, match="paths.results"):
        validate_config(deep_merge(paper_cfg, {"paths": {"results": bad}}))


def test_injected_path_never_runs(tmp_path):
    bad = tmp_path / "bad.yaml"
    bad.write_text(yaml.safe_dump({"paths": {"results": "r$(touch pwned)"}}))
    proc = _snakemake("-j1", "all", "-d", str(tmp_path), "--configfile", "config.yaml", str(bad), check=False)
    assert proc.returncode != 0 and "paths.results" in proc.stderr
    assert not list(tmp_path.rglob("pwned")) and not (REPO / "pwned").exists()


def test_a_second_concurrent_run_is_refused(tmp_path):
    """Snakemake's lock files are off (they outlive a kill -9); the kernel lock held by a running
    workflow (here: by this test) refuses a second real run before any job starts."""
    import fcntl

    lock = tmp_path / ".snakemake" / "madpinn.lock"
    lock.parent.mkdir()
    with open(lock, "a") as fh:
        fcntl.flock(fh, fcntl.LOCK_EX | fcntl.LOCK_NB)
        proc = _snakemake("-j1", "results/smoke/tracking/store.json", "-d", str(tmp_path), "--configfile",
                          "config.yaml", "workflow/configs/smoke.yaml", check=False)
    assert proc.returncode != 0 and "another snakemake run is active" in proc.stderr, proc.stderr[-2000:]
    assert not (tmp_path / "results" / "smoke" / "tracking").exists()
