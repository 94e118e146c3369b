# MAD-PINN policy (issue 4). Evaluation jobs of `madpinn[-variant]` run through rule `evaluate`
# (evaluate.smk) and depend on the trained value functions they load; the two ablation tables of
# the paper are built by tables.smk from the ablation studies when those are configured.
from pathlib import Path as _Path


def _madpinn_model(key):
    p = config["methods"]["madpinn"][key]
    return p if _Path(p).is_absolute() else f"{RESULTS}/{p}"


if "madpinn" in config["methods"]:
    # Default paths equal VHAT_MODEL / VS_MODEL of workflow/rules/train.smk, whose rules train them.
    METHOD_INPUTS["madpinn"] = [_madpinn_model("vhat_model"), _madpinn_model("vs_model")]

TABLES["table_neighbour_ablation"] = ("ablation_neighbours", "summary")
TABLES["table_update_ablation"] = ("ablation_update", "summary")
