"""What a snakemake start costs: every dry run, every run and every Slurm job step (the plugin's
job step parses the whole workflow before it runs its job) plans the workflow. Planning imports
neither torch nor MuJoCo nor MLflow (≈ 2 s CPU per start otherwise), and a start of an unchanged
package reads the rules' source hashes back from the cache instead of computing them (≈ 1.5 s:
docs/reference/performance.md)."""

from __future__ import annotations

import shutil
import subprocess
import sys

from conftest import REPO, SMOKE, subprocess_env
from madpinn import source_cache
from madpinn.commands import handler_entry
from madpinn.provenance import source_hash

HEAVY = ("torch", "mujoco", "mlflow", "cvxpy")
PROBE = ("import atexit, sys\n"
         f"atexit.register(lambda: print('heavy:', *(m for m in {HEAVY!r} if m in sys.modules)))\n"
         "from snakemake.cli import main\n"
         "main(sys.argv[1:])\n")


def _plan(workdir, cache):
    cmd = [sys.executable, "-c", PROBE, "-s", str(REPO / "Snakefile"), "-d", str(workdir), "-n", "all",
           "--configfile", str(REPO / "config.yaml"), str(SMOKE)]
    proc = subprocess.run(cmd, capture_output=True, text=True, env=subprocess_env({"XDG_CACHE_HOME": str(cache)}),
                          timeout=600)
    assert proc.returncode == 0 and "Job stats:" in proc.stdout + proc.stderr, proc.stderr[-4000:]
    return proc


def test_planning_imports_no_heavy_library_and_keeps_the_source_hashes(tmp_path):
    cache = tmp_path / "cache"
    heavy = [ln for ln in _plan(tmp_path / "a", cache).stdout.splitlines() if ln.startswith("heavy:")]
    assert heavy == ["heavy:"], heavy

    kept = cache / "madpinn" / "source_hashes" / f"{source_cache.package_digest()}.json"
    hashes = source_cache.load(source_cache.package_digest(), kept.parent)
    for command in ("train-value", "table", "reproduction"):
        assert hashes[command] == source_hash(handler_entry(command)), command
    assert len(hashes) >= 20                     # every rule's: one per command, or command and method
    written = kept.stat().st_mtime_ns
    _plan(tmp_path / "b", cache)                 # the same package: every hash read back, none written
    assert kept.stat().st_mtime_ns == written


def test_the_package_digest_follows_every_module_and_data_file(tmp_path):
    copy = tmp_path / "madpinn"
    shutil.copytree(REPO / "madpinn", copy, ignore=shutil.ignore_patterns("__pycache__"))
    digest = source_cache.package_digest(copy)
    assert digest == source_cache.package_digest()
    (copy / "policies" / "nominal.py").touch()
    assert source_cache.package_digest(copy) == digest                            # bytes, not times
    module = copy / "policies" / "nominal.py"
    module.write_text(module.read_text() + "\n# edited\n")
    edited = source_cache.package_digest(copy)
    assert edited != digest
    (copy / "evaluation" / "extra.yaml").write_text("a: 1\n")                    # a data file a module may name
    assert source_cache.package_digest(copy) not in (digest, edited)

    source_cache.save("d", {"table": "abc"}, tmp_path / "kept")
    assert source_cache.load("d", tmp_path / "kept") == {"table": "abc"}
    (tmp_path / "kept" / "d.json").write_text("{not json")
    assert source_cache.load("d", tmp_path / "kept") == {} == source_cache.load("other", tmp_path / "kept")
