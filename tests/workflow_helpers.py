"""A throw-away copy of the repository (a fresh clone's layout) and real snakemake runs in it; a
single-node Slurm cluster to run them on.

Tests that edit sources or kill runs work on such a copy, never on the repository itself."""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import yaml

REPO = Path(__file__).resolve().parents[1]
COPIED = ("Snakefile", "config.yaml", "madpinn", "workflow", "profiles")

# The smallest configuration that still builds every table and figure through the real code paths
# (the smoke overlay with one cell per run, double-integrator physics). NO_TRACKING: for tests of
# the DAG alone (MLflow logging is covered by the recovery tests and tests/test_workflow.py).
TINY = {
    "sim": {"backend": "double_integrator"},
    "studies": {
        "main": {"agent_counts": [3], "seeds": [0], "scenarios": 1, "runs": ["madpinn", "nominal"]},
        "scaling": {"agent_counts": [8], "seeds": [0], "scenarios": 1, "runs": ["nominal"]},
        "ablation_neighbours": {"runs": ["madpinn-nearest"]},
        "ablation_update": {"runs": ["madpinn-k1"]},
        "conflict_circle": {"runs": ["nominal"]},
        "large_arena_frontier": {"in_all": False},   # its own target (tests/test_frontier.py)
    },
}


NO_TRACKING = {"tracking": {"enabled": False}}


def copy_repo(dest: Path) -> Path:
    """Copy what a clone needs to run the workflow into ``dest`` (no caches, no results)."""
    dest.mkdir(parents=True, exist_ok=True)
    ignore = shutil.ignore_patterns("__pycache__", "*.pyc", "results", "mlflow", ".snakemake")
    for name in COPIED:
        src = REPO / name
        if src.is_dir():
            shutil.copytree(src, dest / name, ignore=ignore)
        else:
            shutil.copy2(src, dest / name)
    shutil.copy2(REPO / "workflow" / "configs" / "smoke.yaml", dest / "smoke.yaml")
    return dest


def write_overlay(path: Path, *overlays: dict) -> Path:
    from madpinn.config import deep_merge

    cfg: dict = {}
    for o in overlays:
        cfg = deep_merge(cfg, o)
    path.write_text(yaml.safe_dump(cfg, sort_keys=False))
    return path


def env_for(copy: Path, extra: dict | None = None) -> dict:
    env = dict(os.environ)
    env["PYTHONPATH"] = str(copy)  # jobs run the copy's package
    env["PYTHONDONTWRITEBYTECODE"] = "1"
    env.pop("MLFLOW_TRACKING_URI", None)
    env.update(extra or {})
    return env


def snakemake_cmd(*args: str) -> list[str]:
    return [sys.executable, "-m", "snakemake", *args]


def run_in(copy: Path, *args: str, configfiles=("smoke.yaml",), check=True, timeout=2400, env=None):
    """``snakemake ARGS --configfile ...`` run from the copy's root, as the README does (the default
    profile is found there)."""
    cmd = snakemake_cmd(*args, "--configfile", "config.yaml", *map(str, configfiles))
    proc = subprocess.run(cmd, cwd=copy, capture_output=True, text=True, env=env_for(copy, env), timeout=timeout)
    if check and proc.returncode != 0:
        raise AssertionError(f"snakemake {' '.join(args)} failed ({proc.returncode}):\n"
                             f"{proc.stdout[-4000:]}\n{proc.stderr[-6000:]}")
    return proc


def planned_jobs(proc) -> dict[str, int]:
    """Rule -> job count of a dry run's "Job stats" table (empty when nothing is to be done)."""
    out = proc.stdout + proc.stderr
    if "Nothing to be done" in out:
        return {}
    m = re.search(r"Job stats:\njob\s+count\n[- ]+\n(.*?)\ntotal\s+\d+", out, re.S)
    assert m, out[-3000:]
    return {rule: int(n) for rule, n in (line.split() for line in m.group(1).strip().splitlines())}


def tree_state(root: Path, skip=(".snakemake",)) -> dict[str, tuple[int, int]]:
    """Relative path -> (size, mtime_ns) of every file under ``root`` except ``skip`` dirs."""
    state = {}
    for p in sorted(root.rglob("*")):
        rel = p.relative_to(root)
        if rel.parts[0] in skip or "__pycache__" in rel.parts:
            continue
        st = p.stat()
        state[str(rel)] = (st.st_size if p.is_file() else -1, st.st_mtime_ns)
    return state


class LocalSlurm:
    """A single-node Slurm cluster on localhost (``scripts/local_slurm.sh``: Debian's slurm-wlm and
    munge, partition ``local``), its state under ``state``; :meth:`unavailable` says why it cannot
    start here (``None``: it can)."""

    BINARIES = ("slurmctld", "slurmd", "munged", "sbatch", "squeue", "scancel")
    CONF = Path("/etc/slurm/slurm.conf")

    def __init__(self, state: Path):
        self.state, self.script = state, REPO / "scripts" / "local_slurm.sh"
        self.pids: list[int] = []

    @classmethod
    def unavailable(cls) -> str | None:
        path = os.environ.get("PATH", "") + ":/usr/sbin:/sbin"       # the daemons live in sbin
        missing = [b for b in cls.BINARIES if not shutil.which(b, path=path)]
        if missing:
            return f"{', '.join(missing)} missing: apt-get install -y slurm-wlm munge (.ci/run does)"
        if os.geteuid() != 0:
            return "slurmd needs root"
        if cls.CONF.exists() and "madpinn scripts/local_slurm.sh" not in cls.CONF.read_text().split("\n", 1)[0]:
            return f"{cls.CONF} belongs to a real Slurm installation"
        return None

    @staticmethod
    def system_files() -> set[str]:
        """Every Slurm or munge path under /etc, /var, /run and /dev/shm (what a cluster could leave behind)."""
        found = set()
        for top in ("/etc", "/var", "/run", "/dev/shm"):
            for dirpath, dirnames, filenames in os.walk(top):
                for name in dirnames + filenames:
                    if re.search("slurm|munge", name, re.I) or re.search("slurm|munge", dirpath, re.I):
                        found.add(os.path.join(dirpath, name))
        return found

    def start(self) -> "LocalSlurm":
        subprocess.run([str(self.script), "start", str(self.state)], check=True, timeout=120, capture_output=True)
        self.pids = [int((self.state / f"{d}.pid").read_text()) for d in ("munged", "slurmctld", "slurmd")]
        return self

    def stop(self) -> None:
        subprocess.run([str(self.script), "stop", str(self.state)], timeout=180, capture_output=True)

    @staticmethod
    def squeue(*args: str) -> list[list[str]]:
        out = subprocess.run(["squeue", "-h", *args], capture_output=True, text=True, timeout=60).stdout
        return [line.split("|") for line in out.splitlines() if line.strip()]
