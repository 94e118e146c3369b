"""Record a V̂ trained through an overlay under its workflow variant's training hash (issue 33).

    python scripts/restamp_vhat_variant.py --config config.yaml --variant speed \
        --model training/vhat_speed/vhat.pt --out results/vhat_speed_restamped.pt
    python -m madpinn ship-models --model vhat_speed=results/vhat_speed_restamped.pt

The speed-aware fine-tune was trained with ``workflow/configs/vhat_speed_aware.yaml``, whose
``init_from`` names the shipped V̂ relative to that overlay's results directory
(``../../models/vhat.pt``); the workflow's variant ``value_functions.vhat_variants.speed`` names the
same starting model relative to its own results directory (``models/vhat.pt``: the workflow's V̂,
installed from ``models/vhat.pt`` or trained with the same training hash). The training hash hashes
that path text, so the two differ although the weights were trained with the same settings from the
same model. This script checks exactly that, and refuses otherwise:

- every training setting the checkpoint records equals the variant's merged setting, except the text
  of ``init_from`` (and the seed equals ``value_functions.seed``);
- the checkpoint started from ``models/vhat.pt`` (its ``meta.init_from``), and the manifest's V̂
  was trained for this configuration (the base V̂'s training hash);

then writes a copy whose ``meta.config_hash`` and ``meta.settings.init_from`` are the variant's,
keeping the original values under ``meta.restamped``. The weights are untouched. A checkpoint trained
by the workflow's own ``train_vhat_variant`` rule needs none of this.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import torch

from madpinn.config import load_config, validate_config, with_vf_variant
from madpinn.provenance import model_training_hash
from madpinn.value_functions.build import training_hash
from madpinn.value_functions.shipping import read_manifest, read_model_file

SHIPPED_VHAT = "models/vhat.pt"


def restamp(cfg: dict, variant: str, model: Path, out: Path, models_dir: Path) -> dict:
    """Check and write the restamped copy (see the module docstring); returns its new meta."""
    data = read_model_file(model, f"vhat_{variant}")
    meta = dict(data["meta"])
    merged = with_vf_variant(cfg, "vhat", variant)["value_functions"]["vhat"]
    want = {k: v for k, v in merged.items() if k != "validation"}
    have = dict(meta["settings"])
    if have.pop("seed", None) != cfg["value_functions"]["seed"]:
        sys.exit(f"{model}: trained with another value_functions.seed")
    differ = sorted(k for k in set(want) | set(have) if k != "init_from" and want.get(k) != have.get(k))
    if differ:
        sys.exit(f"{model}: settings differ from value_functions.vhat_variants.{variant} merged over vhat: {differ}")
    if "init_from" in want and meta.get("init_from") != SHIPPED_VHAT:
        sys.exit(f"{model}: started from {meta.get('init_from')!r}, not the shipped {SHIPPED_VHAT}")
    base = read_manifest(models_dir)["models"].get("vhat", {}).get("training_config_hash")
    if "init_from" in want and base != training_hash(cfg, "vhat"):
        sys.exit(f"{models_dir}/manifest.json: the shipped V̂ ({base}) is not this configuration's ({training_hash(cfg, 'vhat')})")
    new = model_training_hash(cfg, f"vhat_{variant}")
    meta["restamped"] = {"config_hash": meta["config_hash"], "settings_init_from": meta["settings"].get("init_from"),
                         "why": "same settings and starting model; init_from written relative to the workflow's "
                                "results directory (scripts/restamp_vhat_variant.py)"}
    meta["config_hash"] = new
    meta["settings"] = {**meta["settings"], "init_from": want.get("init_from")}
    out.parent.mkdir(parents=True, exist_ok=True)
    torch.save({**data, "meta": meta}, out)
    return meta


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--config", nargs="+", required=True)
    p.add_argument("--variant", required=True)
    p.add_argument("--model", required=True, type=Path)
    p.add_argument("--out", required=True, type=Path)
    p.add_argument("--models-dir", default=Path("models"), type=Path)
    args = p.parse_args()
    cfg = load_config(args.config)
    validate_config(cfg)
    meta = restamp(cfg, args.variant, args.model, args.out, args.models_dir)
    print(json.dumps({"config_hash": meta["config_hash"], "restamped": meta["restamped"]}, indent=2))


if __name__ == "__main__":
    main()
