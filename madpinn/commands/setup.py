"""``validate-config`` and ``tracking-init``: the checks and the store made once before the fan-out;
``publish``: the one command that writes a run's tables, figures and new cache entries into the
committed ``paper_figures/`` and ``output_cache/`` (a workflow run writes under ``paths.results``
only)."""

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


def _publish(args) -> int:
    import filecmp
    import os
    import shutil
    from pathlib import Path

    from madpinn.atomic import atomic_write
    from madpinn.output_cache import KINDS, add_entries, cache_layers

    cfg = config_of(args)
    paths = cfg["paths"]
    src, dest = Path(paths["figures"]), Path(args.figures_to)
    figures = {"copied": 0, "unchanged": 0}
    if src.resolve() == dest.resolve() or dest.resolve() in src.resolve().parents:
        print(f"madpinn: figures: {src} is inside {dest} already; nothing to copy")
    elif src.is_dir():
        for f in sorted(p for p in src.rglob("*") if p.is_file()):
            target = dest / f.relative_to(src)
            if target.is_file() and filecmp.cmp(f, target, shallow=False):
                figures["unchanged"] += 1
                continue
            figures["copied"] += 1
            if not args.dry_run:
                atomic_write(target, lambda tmp, f=f: shutil.copyfile(f, tmp))
    committed, own = cache_layers(paths.get("output_cache"), paths["results"], os.environ.get("SNAKEMAKE_OUTPUT_CACHE"))
    added = skipped = []
    if committed is not None and own.is_dir():
        if args.dry_run:
            from madpinn.output_cache import entry_hash, whole_entries

            have = {entry_hash(p.name) for p in committed.iterdir()} if committed.is_dir() else set()
            whole = whole_entries(own, KINDS)
            added = [h for h in whole if h not in have]
            skipped = [h for h in whole if h in have]
        else:
            added, skipped = add_entries(own, committed, KINDS)
    verb = "would copy" if args.dry_run else "copied"
    print(f"madpinn: {verb} {figures['copied']} files of {src} into {dest} ({figures['unchanged']} unchanged); "
          f"{verb} {len(added)} new cache entries of {own} into {committed} ({len(skipped)} there already)")
    if (added or figures["copied"]) and not args.dry_run:
        shown = os.path.relpath(committed) if committed is not None else "(no committed cache)"
        print(f"madpinn: to commit them: git add {dest} && git add -f {shown}   (entries are ignored files: -f)")
    return 0


def register(sub) -> None:
    p = sub.add_parser("validate-config", help="validate config file(s) against the schema")
    add_config_arg(p)
    p.set_defaults(func=_validate)

    p = sub.add_parser("tracking-init", help="create the MLflow store and experiment once")
    add_config_arg(p)
    p.add_argument("--out", required=True, help="marker JSON written on success")
    p.set_defaults(func=_tracking_init)

    p = sub.add_parser("publish", help="copy a finished run's tables and figures into paper_figures/ and its new "
                                       "cache entries into the committed output cache (never onto an existing entry)")
    add_config_arg(p)
    p.add_argument("--figures-to", default="paper_figures", help="the committed tables and figures (default paper_figures)")
    p.add_argument("-n", "--dry-run", action="store_true", help="say what would be copied; write nothing")
    p.set_defaults(func=_publish)
