"""benchmarks/suite_cpu.py: the hook in a real (throw-away) venv charges each Python process's own CPU
time to the test named in its environment, and the report sums it per file and per test."""

import os
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
SCRIPT = REPO / "benchmarks" / "suite_cpu.py"


def test_the_hook_records_each_process_under_its_test_and_the_report_sums_them(tmp_path):
    venv, log = tmp_path / "venv", tmp_path / "cpu.tsv"
    subprocess.run([sys.executable, "-m", "venv", "--without-pip", str(venv)], check=True, timeout=120)
    subprocess.run([sys.executable, str(SCRIPT), "install", str(venv), str(log)], check=True, timeout=60)
    busy = "import time\nt = time.process_time()\nwhile time.process_time() - t < 0.3: pass"
    env = {k: v for k, v in os.environ.items() if k not in ("PYTEST_CURRENT_TEST", "PYTEST_XDIST_WORKER")}
    for test in ("tests/test_a.py::test_x (call)", "tests/test_a.py::test_x (call)", "tests/test_b.py::test_y (setup)"):
        subprocess.run([str(venv / "bin" / "python"), "-c", busy], check=True, timeout=60,
                       env={**env, "PYTEST_CURRENT_TEST": test})
    subprocess.run([str(venv / "bin" / "python"), "-c", "pass"], check=True, timeout=60, env=env)   # outside a test
    rows = [line.split("\t") for line in log.read_text().splitlines()]
    assert [r[3] for r in rows] == ["tests/test_a.py::test_x", "tests/test_a.py::test_x", "tests/test_b.py::test_y", "-"]
    assert all(float(r[0]) >= 0.3 for r in rows[:3])            # each busy process counted its own 0.3 s at least
    out = subprocess.run([sys.executable, str(SCRIPT), "report", str(log)], check=True, capture_output=True,
                         text=True, timeout=60).stdout
    assert out.startswith("4 Python processes")
    files = out.split("per test file (CPU s)\n")[1].split("\n\n")[0].splitlines()
    assert files[0].endswith("tests/test_a.py") and float(files[0].split()[0]) >= 0.6   # two processes summed
