"""``validate-config`` and ``tracking-init``: the checks and the store made once before the fan-out."""

from __future__ import annotations

import json

from madpinn.commands.args import add_config_arg, config_of


def _validate(args) -> int:
    config_of(args)
    print("config OK")
    return 0


def _tracking_init(args) -> int:
    from madpinn.tracking import TrackingSettings, write_marker

    info = write_marker(TrackingSettings.from_config(config_of(args)), args.out)
    print(json.dumps(info))
    return 0


def register(sub) -> None:
    p = sub.add_parser("validate-config", help="validate config file(s) against the schema")
    add_config_arg(p)
    p.set_defaults(func=_validate)

    p = sub.add_parser("tracking-init", help="create the MLflow store and experiment once")
    add_config_arg(p)
    p.add_argument("--out", required=True, help="marker JSON written on success")
    p.set_defaults(func=_tracking_init)
