"""Headless-Chromium screenshots of what a researcher opens after a run: the MLflow UI (the
experiment's runs table, a training run's page, its metric curves) and the Snakemake report.

    python scripts/screenshots.py --store mlflow/mlflow.db --experiment madpinn-paper \\
        --report report.zip --out screenshots/

Starts ``mlflow server`` on a free local port for the SQLite store (stopped at the end; only the
process it started), finds the experiment and the trained run with a loss curve and the most iterations (a training job,
or on the shipped path a shipped model's install run: :func:`training_run`), and writes
``mlflow_experiment.png`` (the experiment's paper view: cells with the paper's metric columns),
``mlflow_models.png`` (logged models), ``mlflow_run.png``,
``mlflow_run_metrics.png`` and, with ``--report``, ``report.png`` (the report's landing page with
its sections), ``report_1.png`` (the claims page, first in "Paper vs ours"), ``report_2.png`` (Table I) and
``report_3.png`` (the paper's figures, listed) into ``--out``. Needs a ``chromium`` (or ``--chromium PATH``) on the machine
(Debian: ``apt-get install chromium``); prints each file written.
"""

from __future__ import annotations

import argparse
import os
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
import urllib.request
import zipfile
from pathlib import Path

START_TIMEOUT_S = 240     # the server imports its whole app: ~15 s idle, longer on a loaded machine


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _start_server(store: Path, workdir: Path) -> tuple[subprocess.Popen, str]:
    port = _free_port()
    uri = f"http://127.0.0.1:{port}"
    cmd = [sys.executable, "-m", "mlflow", "server", "--host", "127.0.0.1", "--port", str(port), "--workers", "1",
           "--backend-store-uri", f"sqlite:///{store.resolve()}"]
    log = open(workdir / "mlflow_server.log", "ab")
    proc = subprocess.Popen(cmd, cwd=store.resolve().parent.parent, stdout=log, stderr=subprocess.STDOUT,
                            start_new_session=True, env={**os.environ, "MLFLOW_SERVER_ENABLE_JOB_EXECUTION": "false"})
    deadline = time.monotonic() + START_TIMEOUT_S
    while time.monotonic() < deadline:
        if proc.poll() is not None:
            raise SystemExit(f"screenshots: mlflow server exited, see {workdir / 'mlflow_server.log'}")
        try:
            with urllib.request.urlopen(uri + "/health", timeout=2) as r:
                if r.status == 200:
                    return proc, uri
        except OSError:
            time.sleep(0.5)
    _stop(proc)
    raise SystemExit(f"screenshots: mlflow server did not answer within {START_TIMEOUT_S} s")


def _stop(proc: subprocess.Popen) -> None:
    if proc.poll() is None:
        os.killpg(proc.pid, signal.SIGTERM)
        try:
            proc.wait(timeout=30)
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait(timeout=30)


def shoot(chromium: str, url: str, out: Path, size=(1500, 950), wait_ms: int = 15000) -> Path:
    """One screenshot of ``url`` after ``wait_ms`` of page time (React pages render after load)."""
    with tempfile.TemporaryDirectory(prefix="madpinn-chromium-") as profile:
        subprocess.run([chromium, "--headless", "--no-sandbox", "--disable-gpu", "--hide-scrollbars",
                        "--run-all-compositor-stages-before-draw",      # charts drawn (MLflow's metric plots)
                        f"--user-data-dir={profile}", f"--window-size={size[0]},{size[1]}",
                        f"--virtual-time-budget={wait_ms}", f"--screenshot={out}", url],
                       check=True, capture_output=True, timeout=180)
    if not out.is_file():
        raise SystemExit(f"screenshots: chromium wrote no {out}")
    print(out)
    return out


def training_run(c, exp_id: str):
    """The run with a ``loss`` curve and the most iterations: a training job's (rule ``train*``) or, on the shipped
    path where nothing trains, a shipped model's install run with its committed training log; None
    if no run logged a ``loss``."""
    runs = [r for rule in ("LIKE 'train%'", "= 'install_shipped_model'")
            for r in c.search_runs([exp_id], filter_string=f"tags.`madpinn.rule` {rule}", max_results=200)
            if "loss" in r.data.metrics]
    return max(runs, key=lambda r: (r.data.tags.get("madpinn.rule", "").startswith("train"),
                                    r.data.metrics.get("iterations", 0)), default=None)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--store", required=True, help="the workflow's SQLite MLflow store (e.g. mlflow/mlflow.db)")
    p.add_argument("--experiment", required=True, help="experiment name (the config's `experiment`)")
    p.add_argument("--report", default=None, help="snakemake --report output (.zip or .html)")
    p.add_argument("--out", default="screenshots", help="output directory")
    p.add_argument("--chromium", default=shutil.which("chromium") or shutil.which("chromium-browser"))
    args = p.parse_args(argv)
    if not args.chromium:
        raise SystemExit("screenshots: no chromium found; install it (apt-get install chromium) or pass --chromium")
    store, out = Path(args.store), Path(args.out)
    if not store.is_file():
        raise SystemExit(f"screenshots: no MLflow store at {store}")
    out.mkdir(parents=True, exist_ok=True)

    from mlflow.tracking import MlflowClient

    from madpinn.tracking.mlflow_store import view_url

    c = MlflowClient(f"sqlite:///{store.resolve()}")
    exp = c.get_experiment_by_name(args.experiment)
    if exp is None:
        raise SystemExit(f"screenshots: no experiment '{args.experiment}' in {store}")
    run = training_run(c, exp.experiment_id)
    if run is None:   # no training curve anywhere: any run
        runs = c.search_runs([exp.experiment_id], max_results=1)
        if not runs:
            raise SystemExit(f"screenshots: experiment '{args.experiment}' has no run")
        run = runs[0]
    print(f"run {run.info.run_id} ({run.data.tags.get('madpinn.job', '?')})")

    proc, uri = _start_server(store, out)
    try:
        # MLflow 3.17's UI opens in its GenAI mode (a per-browser toggle, top left); the URL picks
        # the model-training mode, as README's link does
        base, mode = f"{uri}/#/experiments/{exp.experiment_id}", "?workflowType=machine_learning"
        shoot(args.chromium, view_url(uri, exp.experiment_id), out / "mlflow_experiment.png", size=(1900, 950))
        shoot(args.chromium, f"{base}/models{mode}", out / "mlflow_models.png")
        shoot(args.chromium, f"{base}/runs/{run.info.run_id}{mode}", out / "mlflow_run.png", size=(1500, 1500))
        shoot(args.chromium, f"{base}/runs/{run.info.run_id}/model-metrics{mode}", out / "mlflow_run_metrics.png",
              wait_ms=30000)   # the charts fetch their histories after the page
    finally:
        _stop(proc)

    if args.report:
        report = Path(args.report)
        if report.suffix == ".zip":
            dest = out / "report"
            shutil.rmtree(dest, ignore_errors=True)
            with zipfile.ZipFile(report) as z:
                z.extractall(dest)
            report = next(dest.rglob("report.html"))
        shoot(args.chromium, report.resolve().as_uri(), out / "report.png", size=(1500, 1100), wait_ms=5000)
        # the report is one page without URLs per view: a copy that clicks through to each section
        sections = ["1 · Paper vs ours", "2 · Paper tables (I–IV)", "3 · Paper figures"]
        first_view = "css:tr a[href='#']"       # the eye button of a section's first item
        for i, clicks in enumerate([[sections[0], first_view], [sections[1], first_view], [sections[2]]], 1):
            page = report.with_name(f"report_view{i}.html")
            page.write_text(report.read_text() + _clicks(clicks))
            shoot(args.chromium, page.resolve().as_uri(), out / f"report_{i}.png", size=(1500, 1100), wait_ms=8000)
    return 0


def _clicks(texts: list[str]) -> str:
    """A script that clicks, one after another, the report's elements showing exactly ``texts``
    (``css:<selector>``: the first element matching it)."""
    import json

    return ("<script>window.addEventListener('load', () => {let texts = " + json.dumps(texts) + ";"
            "function next() {if (!texts.length) return; const t = texts.shift();"
            "const el = [...document.querySelectorAll('a, button, li, td, span, div')].reverse()"
            ".find(e => e.textContent.trim() === t);"
            "const hit = t.startsWith('css:') ? document.querySelector(t.slice(4)) : el;"
            "if (hit) hit.click(); setTimeout(next, 700);}"
            "setTimeout(next, 700);});</script>")


if __name__ == "__main__":
    sys.exit(main())
