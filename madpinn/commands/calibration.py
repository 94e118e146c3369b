"""``calibrate-vhat``: the safety level δ of V̂ per (ε, β), pooled and per closing-speed bin, with
its held-out coverage (issue 62, not in the paper; :mod:`madpinn.value_functions.calibration`):
a JSON report (read by the runs that deploy a level, ``methods.madpinn…conformal``) and its table
(CSV, Markdown, and the HTML page of the Snakemake report). Registered by
:func:`madpinn.commands.value_functions.register` (the value-function job family)."""

from __future__ import annotations

from pathlib import Path

from madpinn.commands.args import add_config_arg, add_job_args, add_model_arg, config_of, single_model
from madpinn.commands.finish import JobRecord, finish, job, write_json
from madpinn.commands.reads import VF_RUN, Z_TOL, keys

READS = ("value_functions.vhat.validation.calibration", "value_functions.vhat.validation.scenario", Z_TOL, *VF_RUN)
"""what the job reads of the config: its settings, the verification's rollouts and distributions,
the deployed z grid, the value functions' seeding and precision"""


def _calibrate_vhat(args) -> int:
    from madpinn.config import method_config
    from madpinn.device import resolve_device, resolve_dtype, seed_everything
    from madpinn.policies import policy_settings
    from madpinn.value_functions import load_vhat
    from madpinn.value_functions.calibration import CalibrationSettings, calibrate
    from madpinn.evaluation.calibration_table import write_calibration_table
    from madpinn.value_functions.verification import ScenarioSettings

    cfg = config_of(args)
    model = single_model(args.model, "vhat")
    validation = cfg["value_functions"]["vhat"]["validation"]
    settings = CalibrationSettings.from_config(validation["calibration"])   # bad ε, β or seed: before any work
    scenario = ScenarioSettings.from_config(validation["scenario"])
    record = JobRecord(job_key=f"validate/{Path(model).stem}_calibration", rule="calibrate_vhat")
    with job(cfg, record, not args.no_track) as run:
        # the value-function jobs' seeding and device (no import of their module: it registers this one)
        seed_everything(int(cfg["value_functions"]["seed"]), args.threads or int(cfg["value_functions"]["threads"]))
        vhat = load_vhat(model, device=resolve_device(cfg["device"]), dtype=resolve_dtype(cfg["dtype"]))
        z_tolerance = policy_settings(*method_config(cfg, "madpinn")).z_tolerance   # the deployed z grid
        report = {"model": str(model), "model_iterations": vhat.meta.get("iterations"),
                  "model_config_hash": vhat.meta.get("config_hash"), **calibrate(vhat, settings, scenario, z_tolerance)}
        table = write_calibration_table(report, args.table_csv, args.table_md, args.table_html)
        record.artifacts = [write_json(args.out, report), *table]
        record.metrics = {f"{d}_eps{r['epsilon']:g}_beta{r['beta']:g}_delta": -1.0 if r["delta"] is None else r["delta"]
                          for d, b in report["distributions"].items() for r in b["pooled"]}
        return finish(run, record, echo=dict(record.metrics))


def register(sub) -> None:
    p = sub.add_parser("calibrate-vhat", help="safety level δ of V̂ per (ε, β) and closing-speed bin, with held-out coverage")
    add_config_arg(p)
    add_model_arg(p, ("vhat",))
    add_job_args(p, threads_default=None, progress=False)
    p.add_argument("--out", required=True, help="JSON report")
    p.add_argument("--table-csv", required=True, help="table (CSV)")
    p.add_argument("--table-md", required=True, help="table (Markdown)")
    p.add_argument("--table-html", required=True, help="table (HTML page of the report)")
    p.set_defaults(func=_calibrate_vhat, reads=keys(*READS))
