"""``vhat-recipe``: V̂'s recipe re-chosen on validation seeds by the pre-registered rule (issue 61 item
4), one of the outputs family's pages (registered by :func:`madpinn.commands.outputs.register`). Its
own module, with the ``reads`` its jobs declare: the other output jobs' source hashes stay as they were."""

from __future__ import annotations

from typing import Mapping

from madpinn.commands.args import add_config_arg, config_of
from madpinn.commands.finish import JobRecord, finish, job


def reads(cfg: Mapping, **_) -> dict:
    """What the recipe page reads besides its cells (:class:`madpinn.evaluation.recipe_settings.RecipeSettings`)."""
    import dataclasses

    from madpinn.evaluation.recipe_settings import RecipeSettings

    return {"experiment": cfg["experiment"], **dataclasses.asdict(RecipeSettings.from_config(cfg))}


def _vhat_recipe(args) -> int:
    from madpinn.evaluation.recipe_page import write_recipe_page
    from madpinn.evaluation.recipe_settings import RecipeSettings

    cfg = config_of(args)
    settings = RecipeSettings.from_config(cfg)   # the section's rules, before any file is read
    record = JobRecord(job_key="table/vhat_recipe", rule="vhat_recipe", params={"inputs": len(args.inputs)})
    with job(cfg, record, not args.no_track) as run:
        record.artifacts = write_recipe_page(args.inputs, settings, args.out_dir)
        return finish(run, record, echo=list(record.artifacts))


def register(sub) -> None:
    p = sub.add_parser("vhat-recipe", help="V̂'s recipe re-chosen on validation seeds by the pre-registered rule (issue 61)")
    add_config_arg(p)
    p.add_argument("--inputs", nargs="+", required=True, help="result .parquet files of vhat_recipe's studies")
    p.add_argument("--out-dir", required=True)
    p.add_argument("--no-track", action="store_true")
    p.set_defaults(func=_vhat_recipe, reads=reads)
