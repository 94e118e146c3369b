"""Log the runs a workflow's jobs kept as pending records (:attr:`madpinn.tracking.TrackingSettings.deferred`)
into the store. The rule ``track_cells`` calls :func:`flush_config` before it reads the cell runs; the
workflow's end (``onsuccess`` / ``onerror``) calls :func:`madpinn.tracking.flush_pending` itself.
Tracking glue: it writes no result, so no job's provenance hash depends on it."""

from __future__ import annotations

import json
from typing import Iterable


def flush_config(config_paths: Iterable[str]) -> dict:
    """Flush the pending runs of the configuration in ``config_paths`` (as a job's ``--config``);
    print and return the counts."""
    from madpinn.config import load_config
    from madpinn.tracking import TrackingSettings, flush_pending

    counts = flush_pending(TrackingSettings.from_config(load_config(list(config_paths))))
    print(json.dumps({"pending_runs": counts}))
    return counts
