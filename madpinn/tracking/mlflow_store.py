"""The MLflow store: reachability, one experiment per configuration, replaying a run record, and
permanent removal of replaced runs.

- :func:`check_store` is read-only (runs at every workflow start, dry runs included).
- :func:`init_store` creates the store and the experiment once, before the fan-out (parallel
  first writers race on SQLite schema creation).
- :func:`purge_runs` deletes runs permanently on a store that allows it (SQLite and other
  database stores: what ``mlflow gc --run-ids`` does — metadata and artifacts); a tracking
  server only accepts soft deletes, so on a server run ``mlflow gc --backend-store-uri <its
  store>`` there (docs: README, MLflow section).
"""

from __future__ import annotations

import json
import os
import subprocess
from pathlib import Path

from madpinn.config import REPO_ROOT
from madpinn.tracking.settings import TrackingSettings

JOB_TAG = "madpinn.job"
SOURCE_TAG = "madpinn.source"
RESULTS_TAG = "madpinn.results"   # the results path that owns a run (absolute); runs are replaced only within it

# Fail fast against an unreachable server instead of MLflow's minutes of exponential backoff.
os.environ.setdefault("MLFLOW_HTTP_REQUEST_MAX_RETRIES", "2")
os.environ.setdefault("MLFLOW_HTTP_REQUEST_BACKOFF_FACTOR", "1")   # an int in MLflow 3.17
os.environ.setdefault("MLFLOW_HTTP_REQUEST_TIMEOUT", "15")


def run_name(job_key: str) -> str:
    """The run's name in MLflow's runs table: what tells it from its neighbours first (an evaluation
    cell "madpinn · N=64 · seed 0 · scaling · mujoco", an oracle bound "oracle · N=16 · seed 0 ·
    small · 2 scenarios"); other jobs keep their short key ("train/vhat"). The key stays the
    ``madpinn.job`` tag."""
    parts = job_key.split("/")
    if parts[0] == "evaluate" and len(parts) == 6:
        _, backend, study, run, n, seed = parts
        return f"{run} · N={n.removeprefix('n')} · seed {seed.removeprefix('seed')} · {study} · {backend}"
    if parts[0] == "oracle" and len(parts) >= 5:
        *where, n, seed, scenarios = parts[1:]
        return (f"oracle · N={n.removeprefix('n')} · seed {seed.removeprefix('seed')} · {'/'.join(where)} · "
                f"{scenarios.removeprefix('s')} scenario{'' if scenarios == 's1' else 's'}")
    return job_key


class TrackingError(RuntimeError):
    """The tracking store cannot be used (e.g. unreachable server)."""


def _sqlite_path(uri: str) -> Path | None:
    return Path(uri[len("sqlite:///"):]) if uri.startswith("sqlite:///") else None


def check_store(settings: TrackingSettings, timeout_s: float = 5.0) -> None:
    """Raise :class:`TrackingError` if the store cannot be used; writes nothing.

    Server: ``GET /health`` answers. SQLite: the database file is a readable and writable file,
    or the nearest existing parent directory is writable (the store is created at a real start).
    """
    if not settings.enabled:
        return
    uri = settings.uri
    fix = ("Start it, fix MLFLOW_TRACKING_URI / tracking.uri, or set tracking.enabled: false "
           "to run without tracking.")
    if settings.is_remote:
        import urllib.request

        try:
            with urllib.request.urlopen(uri.rstrip("/") + "/health", timeout=timeout_s) as resp:
                if resp.status >= 400:
                    raise TrackingError(f"MLflow tracking server {uri} is unreachable (HTTP {resp.status}). {fix}")
        except TrackingError:
            raise
        except Exception as exc:  # noqa: BLE001 - any transport failure means unreachable
            raise TrackingError(f"MLflow tracking server {uri} is unreachable ({exc}). {fix}") from exc
        return
    db = _sqlite_path(uri)
    if db is None:
        return   # other database URIs: checked by init_store when the workflow runs
    if db.exists():
        if not db.is_file() or not os.access(db, os.R_OK | os.W_OK):
            raise TrackingError(f"MLflow store {db} is unreachable (not a readable and writable file). {fix}")
        return
    parent = db.parent
    while not parent.exists() and parent != parent.parent:
        parent = parent.parent
    if not parent.is_dir() or not os.access(parent, os.W_OK):
        raise TrackingError(f"MLflow store {db} is unreachable (cannot create it under {parent}). {fix}")


def client(settings: TrackingSettings):
    import mlflow
    from mlflow.tracking import MlflowClient

    # mlflow.set_tracking_uri also exports MLFLOW_TRACKING_URI, which would then override
    # tracking.uri for every later job in this process: keep the environment as it was.
    previous = os.environ.get("MLFLOW_TRACKING_URI")
    mlflow.set_tracking_uri(settings.uri)   # model logging (mlflow.pytorch) uses the global URI
    if previous is None:
        os.environ.pop("MLFLOW_TRACKING_URI", None)
    else:
        os.environ["MLFLOW_TRACKING_URI"] = previous
    return MlflowClient(tracking_uri=settings.uri)


def _artifact_location(settings: TrackingSettings) -> str | None:
    db = _sqlite_path(settings.uri)
    return (db.parent / "artifacts" / settings.experiment).as_uri() if db else None   # a server decides itself


# The experiment's kind for MLflow 3: model training (runs, metric curves, models), not GenAI traces.
# The 3.17 UI itself opens in the mode of its per-browser toggle (GenAI by default) or of the URL's
# `?workflowType=machine_learning` (README, MLflow section); the tag is what the API reports.
EXPERIMENT_KIND_TAG, EXPERIMENT_KIND = "mlflow.experimentKind", "custom_model_development"


# The paper's view of the runs table: the cells and the paper's columns. MLflow 3.17's UI keeps the
# chosen columns per browser, but opens a *shared view* stored as an experiment tag
# `mlflow.sharedViewState.<key>` (JSON of the runs page's state) when the URL names its key,
# `?viewStateShareKey=<key>` (view_url). Column ids are the UI's `<type>.`<name>``.
PAPER_VIEW_KEY = "paper"
PAPER_VIEW_TAG = f"mlflow.sharedViewState.{PAPER_VIEW_KEY}"
PAPER_METRICS = ("safety_rate", "safe_scenarios", "cost_time_avg", "cost", "cost_all_time_avg", "min_separation",
                 "infeasible_share")   # Tables I–II safety, safe scenarios, the paper's cost, ..., MAD-PINN's z_max share
PAPER_PARAMS = ("study", "run", "n_agents", "seed")
CELL_FILTER = "tags.`madpinn.rule` = 'evaluate'"
PAPER_VIEW = json.dumps({
    "searchFilter": CELL_FILTER,
    "orderByKey": "attributes.start_time", "orderByAsc": False,
    "selectedColumns": [*(f"metrics.`{m}`" for m in PAPER_METRICS), *(f"params.`{p}`" for p in PAPER_PARAMS),
                        "tags.`madpinn.restored`"],
}, sort_keys=True)


def view_url(ui: str, exp_id: str) -> str:
    """The runs page of experiment ``exp_id`` on the MLflow UI at ``ui`` in the paper's view (model-training mode)."""
    return f"{ui.rstrip('/')}/#/experiments/{exp_id}/runs?viewStateShareKey={PAPER_VIEW_KEY}&workflowType=machine_learning"


# The experiment's description (shown above its runs): which runs and columns are the paper's.
NOTE_TAG = "mlflow.note.content"
EXPERIMENT_NOTE = (
    "madpinn: one run per workflow job (docs/reference/tracking.md). **The paper's cells**: search "
    f"`{CELL_FILTER}`, one run per (study, run, N, seed), computed here or "
    "restored from output_cache/ (tag `madpinn.restored`, provenance hash `madpinn.provenance_hash`). **The "
    f"paper's view** (this page's URL + `?viewStateShareKey={PAPER_VIEW_KEY}`, or Views): metrics "
    f"{', '.join(f'`{m}`' for m in PAPER_METRICS)}; params {', '.join(f'`{p}`' for p in PAPER_PARAMS)}. "
    "**Training curves**: runs `train/*` and `install/*` (shipped models, curves from the committed training "
    "logs). **Networks**: the Models tab and the Model Registry, one registered model `<experiment>.<name>` per "
    "network. Results are files first: tables and figures are built from results/, not from this store.")


def experiment_id(c, settings: TrackingSettings) -> str:
    """The configuration's experiment (restored when deleted, created when missing), tagged as
    model training for MLflow 3's UI, with :data:`EXPERIMENT_NOTE` as its description and the paper's
    shared view (:data:`PAPER_VIEW`)."""
    tags = {EXPERIMENT_KIND_TAG: EXPERIMENT_KIND, NOTE_TAG: EXPERIMENT_NOTE, PAPER_VIEW_TAG: PAPER_VIEW}
    exp = c.get_experiment_by_name(settings.experiment)
    if exp is not None:
        if exp.lifecycle_stage == "deleted":
            c.restore_experiment(exp.experiment_id)
        for k, v in tags.items():
            if exp.tags.get(k) != v:
                c.set_experiment_tag(exp.experiment_id, k, v)
        return exp.experiment_id
    return c.create_experiment(settings.experiment, artifact_location=_artifact_location(settings), tags=tags)


def init_store(settings: TrackingSettings) -> dict:
    """Create the store and the configuration's experiment; return ``{uri, experiment, experiment_id}``."""
    check_store(settings)
    db = _sqlite_path(settings.uri)
    if db is not None:
        db.parent.mkdir(parents=True, exist_ok=True)
    try:
        exp_id = experiment_id(client(settings), settings)
    except Exception as exc:  # noqa: BLE001
        raise TrackingError(f"cannot initialise MLflow store {settings.uri}: {exc}") from exc
    return {"uri": settings.uri, "experiment": settings.experiment, "experiment_id": exp_id}


def job_runs(c, exp_id: str, job_key: str, source: str, results: str | None) -> list:
    """Every run of ``job_key`` from ``source`` owned by the results path ``results`` (tag
    :data:`RESULTS_TAG`; active and soft-deleted): the runs a new run of that job replaces. Runs
    from before the source tag existed count as workflow runs; runs of another results path (another
    checkout or ``paths.results`` sharing the store) are never returned, and runs from before the
    results tag existed only for ``results=None``."""
    from mlflow.entities import ViewType

    key = job_key.replace("'", "\\'")
    runs = c.search_runs([exp_id], filter_string=f"tags.`{JOB_TAG}` = '{key}'", run_view_type=ViewType.ALL,
                         max_results=1000)
    return [r for r in runs if r.data.tags.get(SOURCE_TAG, "workflow") == source
            and r.data.tags.get(RESULTS_TAG) == results]


def purge_runs(c, settings: TrackingSettings, runs) -> None:
    """Delete ``runs`` permanently where the store allows it (metadata and artifacts, as
    ``mlflow gc --run-ids``), else soft-delete them (tracking server: ``mlflow gc`` there)."""
    from mlflow.store.artifact.artifact_repository_registry import get_artifact_repository
    from mlflow.tracking._tracking_service.utils import _get_store

    store = _get_store(settings.uri)
    hard = hasattr(store, "_hard_delete_run")
    for run in runs:
        for version in c.search_model_versions(filter_string=f"run_id = '{run.info.run_id}'"):
            c.delete_model_version(version.name, version.version)   # its registry versions first
        for model in c.search_logged_models([run.info.experiment_id],
                                            filter_string=f"source_run_id = '{run.info.run_id}'"):
            c.delete_logged_model(model.model_id)          # the replaced run's models go with it
            if hasattr(store, "_hard_delete_logged_model"):   # and their files (as mlflow gc)
                try:
                    get_artifact_repository(model.artifact_location).delete_artifacts()
                except Exception:  # noqa: BLE001 - no artifacts, or already gone
                    pass
                _remove_empty_dirs(model.artifact_location, model.model_id)
                store._hard_delete_logged_model(model.model_id)
        if run.info.lifecycle_stage != "deleted":
            c.delete_run(run.info.run_id)
        if hard:
            try:
                get_artifact_repository(run.info.artifact_uri).delete_artifacts()
            except Exception:  # noqa: BLE001 - no artifacts, or already gone (as mlflow gc)
                pass
            _remove_empty_dirs(run.info.artifact_uri, run.info.run_id)
            store._hard_delete_run(run.info.run_id)


def _remove_empty_dirs(artifact_uri: str, run_id: str) -> None:
    """A purged run's (or logged model's, ``run_id`` = its model id) local artifact directories
    ``…/<run_id>/artifacts`` and ``…/<run_id>``, once empty (``delete_artifacts`` empties them but
    leaves them: one empty directory per replaced run)."""
    from urllib.parse import unquote, urlparse

    parsed = urlparse(artifact_uri)
    if parsed.scheme not in ("", "file"):
        return
    artifacts = Path(unquote(parsed.path))
    for d in (artifacts, artifacts.parent):
        if d.name not in ("artifacts", run_id) or run_id not in d.parts:
            return
        try:
            d.rmdir()   # only when empty
        except FileNotFoundError:
            continue
        except OSError:
            return


def git_commit() -> str:
    try:
        sha = subprocess.run(
            ["git", "-C", str(REPO_ROOT), "rev-parse", "HEAD"], capture_output=True, text=True, timeout=10
        ).stdout.strip()
        # paper_figures/ holds the workflow's own committed outputs, which a run rewrites before
        # its report records the commit: they do not make the code dirty.
        dirty = subprocess.run(
            ["git", "-C", str(REPO_ROOT), "status", "--porcelain", "--untracked-files=no", "--", ".",
             ":(exclude)paper_figures"],
            capture_output=True, text=True, timeout=10,
        ).stdout.strip()
        return (sha or "unknown") + ("-dirty" if dirty else "")
    except Exception:  # noqa: BLE001
        return "unknown"


def write_marker(settings: TrackingSettings, marker: str | Path) -> dict:
    """Create the store and experiment (when tracking is enabled) and write the workflow's store
    marker ``marker`` atomically: ``{enabled, uri, experiment, experiment_id}``; return it."""
    from madpinn.atomic import atomic_write

    info = {"enabled": settings.enabled}
    if settings.enabled:
        info.update(init_store(settings))
    atomic_write(marker, lambda tmp: tmp.write_text(json.dumps(info, indent=2)))
    return info


def read_marker(marker: str | Path) -> dict:
    """The store marker ``marker`` (:func:`write_marker`) as written; ``{}`` when missing or not JSON."""
    marker = Path(marker)
    try:
        return json.loads(marker.read_text()) if marker.is_file() else {}
    except ValueError:
        return {}


def follow_store(settings: TrackingSettings, marker: str | Path) -> dict | None:
    """At a real workflow start, while the Snakefile is read: when the store marker ``marker`` is
    missing, or names another tracking URI or experiment, write it anew (``{enabled, uri,
    experiment}``; jobs take it as an ancient input, so nothing reruns: finished results stay
    finished when the store or its marker was deleted or moved); return the new content, or None
    when nothing changed. The store itself is not touched here: a run refused later (a target
    outside the configuration, an unknown rule) creates none; :func:`ensure_store` creates it when
    jobs are about to run. (tracking_init then only runs with tracking disabled.)"""
    if not settings.enabled:
        return None
    old = read_marker(marker)
    if old.get("uri") == settings.uri and old.get("experiment") == settings.experiment:
        return None
    from madpinn.atomic import atomic_write

    info = {"enabled": True, "uri": settings.uri, "experiment": settings.experiment}
    atomic_write(marker, lambda tmp: tmp.write_text(json.dumps(info, indent=2)))
    return info


def _experiment_exists(settings: TrackingSettings) -> bool:
    """Whether the store holds the configuration's experiment (active); never creates a SQLite file."""
    db = _sqlite_path(settings.uri)
    if db is not None and not db.is_file():
        return False
    try:
        exp = client(settings).get_experiment_by_name(settings.experiment)
    except Exception:  # noqa: BLE001 - unreadable: init_store says why
        return False
    return exp is not None and exp.lifecycle_stage != "deleted"


def ensure_store(settings: TrackingSettings, marker: str | Path) -> bool:
    """When jobs are about to run (the workflow's ``onstart``, under its run lock, before the
    fan-out: parallel first writers race while creating a SQLite schema): create the store and the
    configuration's experiment when missing and write the marker with the experiment's id; True
    when this created the store or the experiment (an existing one is not announced as created)."""
    if not settings.enabled:
        return False
    old = read_marker(marker)
    db = _sqlite_path(settings.uri)
    if (old.get("experiment_id") and old.get("uri") == settings.uri and old.get("experiment") == settings.experiment
            and (db is None or db.is_file())):
        return False
    existed = _experiment_exists(settings)
    write_marker(settings, marker)
    return not existed