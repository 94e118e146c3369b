"""Where the test suite's CPU goes: every Python process the suite starts (snakemake, its jobs, Slurm's
job steps, servers that exit cleanly), charged to the test that was running when it started.

    python benchmarks/suite_cpu.py install .venv /tmp/suite_cpu.tsv   # in a throw-away clone's venv
    CI=true .venv/bin/python -m pytest -q -n 3 --dist loadfile --no-loadscope-reorder -m "not slow"
    python benchmarks/suite_cpu.py report /tmp/suite_cpu.tsv [--top 30]

``install`` writes a ``sitecustomize.py`` into the venv's site-packages: each Python process of that
venv appends, when it exits, its own user + system CPU seconds (``os.times()``, children not
included: each process counts itself), its wall seconds, the xdist worker and the test named by
``PYTEST_CURRENT_TEST`` (pytest sets it while a test runs; subprocesses inherit it) to the log.
Processes killed by a signal (SIGKILL, an unhandled SIGTERM) write nothing, and processes that are
not Python (PostgreSQL, Slurm's daemons, git) are not counted. ``report`` sums the log per test file
and per test; ``-`` is CPU outside any test (the xdist workers themselves: tests that run in-process).
Use it in a throw-away clone only: the hook runs in every Python process of that venv.
"""

from __future__ import annotations

import argparse
import sysconfig
from collections import defaultdict
from pathlib import Path

HOOK = '''import atexit, os, sys, time
_t0 = time.time()
def _suite_cpu_record():
    try:
        t = os.times()
        with open({log!r}, "a") as f:
            f.write(f"{{t.user + t.system:.2f}}\\t{{time.time() - _t0:.2f}}\\t{{os.environ.get('PYTEST_XDIST_WORKER', '-')}}\\t"
                    f"{{os.environ.get('PYTEST_CURRENT_TEST', '-').split(' (')[0]}}\\t{{' '.join(sys.argv[:3])[:160]}}\\n")
    except Exception:
        pass
atexit.register(_suite_cpu_record)
'''


def site_packages(venv: Path) -> Path:
    """The purelib folder of ``venv`` (``lib/python3.X/site-packages``)."""
    rel = Path(sysconfig.get_path("purelib")).relative_to(sysconfig.get_path("data"))
    return venv / rel


def report(log: Path, top: int) -> None:
    per_test: dict[str, float] = defaultdict(float)
    per_file: dict[str, float] = defaultdict(float)
    processes = 0
    for line in log.read_text().splitlines():
        cpu, _wall, _worker, test, _argv = line.split("\t", 4)
        per_test[test] += float(cpu)
        per_file[test.split("::")[0]] += float(cpu)
        processes += 1
    print(f"{processes} Python processes, {sum(per_test.values()):.0f} CPU s")
    print("\nper test file (CPU s)")
    for name, cpu in sorted(per_file.items(), key=lambda kv: -kv[1])[:top]:
        print(f"{cpu:8.1f}  {name}")
    print("\nper test (CPU s)")
    for name, cpu in sorted(per_test.items(), key=lambda kv: -kv[1])[:top]:
        print(f"{cpu:8.1f}  {name}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    a = sub.add_parser("install", help="write the hook into a venv")
    a.add_argument("venv", type=Path)
    a.add_argument("log", type=Path)
    r = sub.add_parser("report", help="sum a log")
    r.add_argument("log", type=Path)
    r.add_argument("--top", type=int, default=30)
    args = ap.parse_args()
    if args.cmd == "install":
        target = site_packages(args.venv)
        if not target.is_dir():
            raise SystemExit(f"{target} is not a folder: is {args.venv} a virtual environment?")
        (target / "sitecustomize.py").write_text(HOOK.format(log=str(args.log.resolve())))
        print(f"wrote {target / 'sitecustomize.py'} (log: {args.log.resolve()})")
    else:
        report(args.log, args.top)


if __name__ == "__main__":
    main()
