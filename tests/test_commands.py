"""The command layer: it alone knows the command line, and every expected error is one line.

Layering (issue 13): no module under ``madpinn/`` outside ``madpinn/commands`` imports argparse
or the command layer (checked on the source's AST). Errors (issue 18 item 7): expected failures
print one line naming the problem and the fix and exit ≠ 0; ``--debug`` / ``MADPINN_DEBUG=1``
show the traceback (checked through real subprocesses of ``python -m madpinn``).
"""

from __future__ import annotations

import ast
import os
import subprocess
import sys

import pytest

from conftest import REPO, SMOKE
from madpinn.commands.args import parse_models
from madpinn.commands.errors import one_line, run_reporting
from madpinn.config import ConfigError

PACKAGE = REPO / "madpinn"
COMMANDS = PACKAGE / "commands"


def imported_modules(path) -> set[str]:
    tree = ast.parse(path.read_text(), filename=str(path))
    names = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names.update(a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module:
            names.add(node.module)
            names.update(f"{node.module}.{a.name}" for a in node.names)
    return names


def test_only_the_command_layer_knows_the_command_line():
    offenders = {}
    for path in PACKAGE.rglob("*.py"):
        if COMMANDS in path.parents or path == PACKAGE / "__main__.py":
            continue
        bad = {m for m in imported_modules(path)
               if m == "argparse" or m.startswith(("madpinn.commands", "madpinn.cli")) or m == "madpinn.cli"}
        if bad:
            offenders[str(path.relative_to(REPO))] = sorted(bad)
    assert offenders == {}
    assert not (PACKAGE / "cli.py").exists()


def test_the_checker_sees_an_argparse_import(tmp_path):
    p = tmp_path / "m.py"
    p.write_text("def f():\n    from madpinn.commands.args import add_config_arg\n    import argparse\n")
    assert {"argparse", "madpinn.commands.args"} <= imported_modules(p)


def test_model_arguments():
    assert parse_models(["vhat=a/b.pt", "vs=c.pt"]) == {"vhat": REPO.__class__("a/b.pt"), "vs": REPO.__class__("c.pt")}
    for bad in (["vhat"], ["=x.pt"], ["vhat=a.pt", "vhat=b.pt"]):
        with pytest.raises(ConfigError, match="--model"):
            parse_models(bad)


def test_expected_errors_are_one_line_and_others_keep_their_traceback(capsys):
    def diverge():
        raise FloatingPointError("non-finite episode return at iteration 3")

    assert run_reporting(diverge, debug=False) == 5
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "iteration 3" in err[0] and "fix:" in err[0]
    with pytest.raises(FloatingPointError):
        run_reporting(diverge, debug=True)
    with pytest.raises(KeyError):   # a bug, not an expected error
        run_reporting(lambda: {}["x"], debug=False)
    assert one_line(ConfigError("invalid configuration:\n  - 'a': bad\n  - 'b': worse")) == \
        "invalid configuration: 'a': bad; 'b': worse"


def madpinn(*args, env=None, cwd=None):
    e = {**os.environ, "PYTHONPATH": str(REPO), "OMP_NUM_THREADS": "1", **(env or {})}
    if not (env and "MADPINN_DEBUG" in env):
        e.pop("MADPINN_DEBUG", None)
    return subprocess.run([sys.executable, "-m", "madpinn", *args], capture_output=True, text=True, env=e,
                          cwd=cwd or REPO, timeout=300)


def overlay(tmp_path, text: str):
    p = tmp_path / f"overlay{len(list(tmp_path.glob('overlay*.yaml')))}.yaml"
    p.write_text(f"paths: {{results: {tmp_path / 'r'}, figures: {tmp_path / 'f'}}}\ntracking: {{enabled: false}}\n" + text)
    return [str(REPO / "config.yaml"), str(SMOKE), str(p)]


def assert_one_line(res, *words, code=None):
    lines = res.stderr.strip().splitlines()
    assert res.returncode != 0 and (code is None or res.returncode == code), res.stderr
    assert len(lines) == 1 and "Traceback" not in res.stderr, res.stderr
    assert lines[0].startswith("madpinn: ") and "fix:" in lines[0]
    for w in words:
        assert w in lines[0], lines[0]


def test_expected_errors_through_main(tmp_path, capsys):
    cfg = overlay(tmp_path, "")
    cell = ["--n-agents", "3", "--seed", "100", "--out", str(tmp_path / "x.parquet"), "--no-progress", "--no-track"]

    def check(*args, words, code):
        from madpinn.commands import main

        assert main(list(args)) == code
        cap = capsys.readouterr()
        lines = cap.err.strip().splitlines()
        assert len(lines) == 1 and lines[0].startswith("madpinn: ") and "fix:" in lines[0], cap.err
        for w in words:
            assert w in lines[0], lines[0]

    check("evaluate", "--config", *cfg, "--study", "main", "--run", "warp", *cell, words=["unknown method 'warp'"], code=2)
    check("evaluate", "--config", *cfg, "--study", "main", "--run", "madpinn", *cell, "--backend", "double_integrator",
          words=["--model vhat=PATH"], code=2)
    (tmp_path / "bad.pt").write_bytes(b"not a torch file")
    check("validate-vhat", "--config", *cfg, "--model", f"vhat={tmp_path / 'bad.pt'}", "--out", str(tmp_path / "v.json"),
          words=["bad.pt", "corrupted"], code=4)
    check("validate-config", "--config", *overlay(tmp_path, "sim: {dt: -1}\n"), words=["sim.dt"], code=2)
    on = tmp_path / "on.yaml"
    on.write_text("tracking: {enabled: true, uri: 'http://127.0.0.1:9'}\n")
    check("tracking-init", "--config", *cfg, str(on), "--out", str(tmp_path / "t.json"), words=["unreachable"], code=6)


def test_cli_errors_are_one_line_with_the_fix(tmp_path):
    """Real processes: unknown study, infeasible scenario, missing checkpoint; ``--debug`` and
    ``MADPINN_DEBUG=1`` show the traceback instead."""
    cfg = overlay(tmp_path, "")
    cell = ["--seed", "0", "--out", str(tmp_path / "x.parquet"), "--no-progress", "--no-track", "--backend", "double_integrator"]
    res = madpinn("evaluate", "--config", *cfg, "--study", "nope", "--run", "nominal", "--n-agents", "3", *cell)
    assert_one_line(res, "unknown study 'nope'", code=2)
    res = madpinn("evaluate", "--config", *cfg, "--study", "main", "--run", "nominal", "--n-agents", "5000", *cell)
    assert_one_line(res, "5000 agents do not fit in arena 'small'", "1 to 69", code=2)   # config.check_cell (issue 50)
    args = ["validate-vhat", "--config", *cfg, "--model", f"vhat={tmp_path / 'missing.pt'}", "--out", str(tmp_path / "v.json")]
    assert_one_line(madpinn(*args), "not found", "missing.pt", code=4)
    for res in (madpinn("--debug", *args), madpinn(*args, env={"MADPINN_DEBUG": "1"})):
        assert res.returncode != 0 and "Traceback" in res.stderr and "CheckpointError" in res.stderr


def test_command_line_and_result_files_jobs_start_without_the_heavy_libraries():
    """Every workflow job starts ``python -m madpinn``: building its parser, loading and validating
    the config (agent-count feasibility included), and the table, figure and report code import
    neither torch nor MLflow nor MuJoCo (≈ 2–4 s per job otherwise)."""
    probe = ("import sys; from madpinn.commands import build_parser; build_parser(); "
             f"from madpinn.config import load_config; load_config([{str(REPO / 'config.yaml')!r}, {str(SMOKE)!r}]); "
             "import madpinn.evaluation.tables, madpinn.evaluation.reproduction, madpinn.figures; "
             "print(' '.join(m for m in ('torch', 'mlflow', 'mujoco', 'cvxpy') if m in sys.modules))")
    proc = subprocess.run([sys.executable, "-c", probe], cwd=REPO, capture_output=True, text=True, check=True)
    assert proc.stdout.split() == []


def test_ctrl_c_on_a_job_run_by_hand_is_one_line_and_keeps_the_checkpoint(tmp_path):
    """Issue 50 item 6: Ctrl-C on `train-value` printed a 41-line KeyboardInterrupt traceback
    (recovery was fine). Now one line and exit 130; the resume checkpoint stays."""
    import signal
    import time

    from conftest import subprocess_env

    long = tmp_path / "long.yaml"
    long.write_text("value_functions: {vs: {iterations: 100000, checkpoint_every: 5}}\ntracking: {enabled: false}\n")
    out = tmp_path / "models" / "vs.pt"
    ckpt = out.parent / "checkpoints" / "vs.ckpt.pt"
    proc = subprocess.Popen([sys.executable, "-m", "madpinn", "train-value", "--config", str(REPO / "config.yaml"),
                             str(SMOKE), str(long), "--kind", "vs", "--out", str(out), "--no-progress"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=subprocess_env(), cwd=tmp_path,
                            # as a terminal's shell starts it: a suite started with `nohup … &` passes SIGINT ignored
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    deadline = time.monotonic() + 300
    while not ckpt.exists() and proc.poll() is None and time.monotonic() < deadline:
        time.sleep(0.1)
    assert ckpt.exists(), proc.communicate()[1][-3000:]
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 130 and "Traceback" not in err, err[-3000:]
    assert err.startswith("madpinn: interrupted (Ctrl-C)") and err.count("\n") == 1, err   # all it prints
    assert ckpt.exists() and not out.exists()
