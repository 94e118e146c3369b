"""``conformal-page``: the calibrated level in closed loop (issue 62, not in the paper), one of the
page commands. Its own module, with the ``reads`` its jobs declare: the other jobs' source hashes
stay as they were."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Mapping

from madpinn.commands.args import add_config_arg, config_of
from madpinn.commands.finish import JobRecord, finish, job


def reads(cfg: Mapping, **_) -> dict:
    """What the page reads besides its cells and the calibration (:class:`madpinn.evaluation.conformal_settings.ConformalSettings`)."""
    import dataclasses

    from madpinn.evaluation.conformal_settings import ConformalSettings

    return {"experiment": cfg["experiment"], **dataclasses.asdict(ConformalSettings.from_config(cfg))}


def _calibration(path: str) -> dict:
    """The calibrate-vhat report at ``path``, or a one-line error naming the command that writes it."""
    from madpinn.config import TargetError

    try:
        report = json.loads(Path(path).read_text())
    except (OSError, ValueError) as exc:
        raise TargetError(f"calibration report {path} is unreadable ({exc}); write it with python -m madpinn calibrate-vhat "
                          "(rule calibrate_vhat)") from exc
    if not isinstance(report, dict) or "distributions" not in report:
        raise TargetError(f"{path} is not a calibrate-vhat report (no 'distributions')")
    return report


def _conformal_page(args) -> int:
    from madpinn.evaluation.conformal_page import load_frame, write_conformal_page
    from madpinn.evaluation.conformal_settings import ConformalSettings
    from madpinn.figures.conformal import plot_conformal

    cfg = config_of(args)
    settings = ConformalSettings.from_config(cfg)   # the studies' rules, before any file is read
    report = _calibration(args.calibration) if args.calibration else None
    record = JobRecord(job_key="table/conformal", rule="conformal_page", params={"inputs": len(args.inputs)})
    with job(cfg, record, not args.no_track) as run:
        files, rows = write_conformal_page(load_frame(args.inputs, settings), settings, report, args.out_dir)
        record.artifacts = files + plot_conformal(rows, settings, Path(args.out_dir) / "fig_conformal")
        return finish(run, record, echo=list(record.artifacts))


def register(sub) -> None:
    p = sub.add_parser("conformal-page", help="V̂ with a calibrated safety level in closed loop (issue 62, not in the paper)")
    add_config_arg(p)
    p.add_argument("--inputs", nargs="+", required=True, help="result .parquet files of the studies whose runs deploy a level")
    p.add_argument("--calibration", default=None, help="the calibrate-vhat report (JSON) of the levels' V̂")
    p.add_argument("--out-dir", required=True)
    p.add_argument("--no-track", action="store_true")
    p.set_defaults(func=_conformal_page, reads=reads)
