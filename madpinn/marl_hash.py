"""The hash a trained MARL policy depends on: SafeMARL's nominal policy and each DEF-MARL variant.

Light (no torch): the workflow's training rules carry it in their params (a change of these
settings retrains the policy) and the shipped overlay compares it with ``models/manifest.json``
before any job (a shipped policy trained for another configuration stops the run). Model names
are those of ``results/models/<name>.pt``: ``safemarl_nominal``, ``defmarl_<variant>``.
"""

from __future__ import annotations

from madpinn.config import method_config, subtree_hash

DEFMARL_PREFIX = "defmarl_"


def is_marl_model(name: str) -> bool:
    return name == "safemarl_nominal" or name.startswith(DEFMARL_PREFIX)


def marl_training_hash(cfg: dict, name: str) -> str:
    """Hash of the settings the weights of model ``name`` depend on (agents, observation, arena,
    dtype and the method's training settings; for DEF-MARL also its validation settings, which
    choose the deployed checkpoint), as loaded, schema defaults filled in."""
    if name == "safemarl_nominal":
        m = cfg["methods"]["safemarl"]
        return subtree_hash(cfg, ("agents", "observation", "dtype"),
                              {"nominal": m["nominal"],
                               "arena": cfg["arenas"][m["nominal"]["arena"]]})
    if name.startswith(DEFMARL_PREFIX):
        _, m = method_config(cfg, f"defmarl-{name[len(DEFMARL_PREFIX):]}")
        extra = {"training": m["training"], "epigraph": m["epigraph"]}
        if m["validation"] is not None:   # the deployed model is the best validation checkpoint
            extra["validation"] = m["validation"]
        return subtree_hash(cfg, ("agents", "observation", "arenas", "dtype"), extra)
    raise ValueError(f"'{name}' is not a MARL model (safemarl_nominal, defmarl_<variant>)")
