"""``python -m madpinn.tracking.flush --config FILE...``: log the runs a workflow's jobs kept as
pending records (:attr:`madpinn.tracking.TrackingSettings.deferred`) into the store, and print the
counts. The rule ``track_cells`` runs it before it reads the cell runs; the workflow's end
(``onsuccess`` / ``onerror``) calls :func:`madpinn.tracking.flush_pending` itself. Tracking glue: it
writes no result, so no job's provenance hash depends on it."""

from __future__ import annotations

import argparse
import json


def main(argv=None) -> int:
    from madpinn.config import load_config
    from madpinn.tracking import TrackingSettings, flush_pending

    parser = argparse.ArgumentParser(prog="python -m madpinn.tracking.flush", description=__doc__.split("\n\n")[0])
    parser.add_argument("--config", nargs="+", required=True, help="config file(s), as the job's")
    args = parser.parse_args(argv)
    print(json.dumps({"pending_runs": flush_pending(TrackingSettings.from_config(load_config(args.config)))}))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
