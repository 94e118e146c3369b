"""The PINN problem of ``value_functions.<kind>`` and the hash its trained weights depend on.

Light at import (no torch): the command line's parser and the workflow's parse-time checks read
``KINDS`` and ``training_hash``; the heavy modules are imported where they are used."""

from __future__ import annotations

from madpinn.config import config_hash, hashed_agents

KINDS = ("vhat", "vs")
"""value functions: V̂ (epigraph PINN) and V_s (pairwise safety)"""


def problem_from_config(cfg: dict, kind: str):
    """The PINN problem of V̂ (``kind="vhat"``, epigraph system) or V_s (``"vs"``, pair system)."""
    from madpinn.value_functions.epigraph import EpigraphSystem
    from madpinn.dynamics.pair import PairSystem
    from madpinn.value_functions.problems import EpigraphProblem, PairProblem
    from madpinn.value_functions.sampling import ConflictSamplingSettings, NearSamplingSettings

    if kind == "vhat":
        return EpigraphProblem(EpigraphSystem.from_config(cfg),
                               ConflictSamplingSettings.from_config(cfg["value_functions"]["vhat"]))
    vs = cfg["value_functions"]["vs"]
    return PairProblem(PairSystem.from_config(cfg), ConflictSamplingSettings.from_config(vs), NearSamplingSettings.from_config(vs))


def training_seed(cfg: dict, kind: str) -> int:
    """The seed of value function ``kind``'s training (initial weights and every batch): its own
    ``value_functions.<kind>.seed`` where set (a variant's training seed), else ``value_functions.seed``."""
    own = cfg["value_functions"][kind]["seed"]
    return int(cfg["value_functions"]["seed"] if own is None else own)


def training_hash(cfg: dict, kind: str, schedule_only: bool = False) -> str:
    """Hash of everything the trained weights depend on (not validation settings). ``schedule_only``:
    without ``stop_at``, i.e. the hash of the run's schedule, which its resume checkpoints carry: a
    run ending early resumes from a longer run's checkpoint (the states agree up to its end)."""
    from madpinn.config import DEPLOYMENT_ONLY_KEYS

    # as loaded, schema defaults filled in: a changed default retrains
    vcfg = {k: v for k, v in cfg["value_functions"][kind].items()
            if k != "validation" and not (schedule_only and k == "stop_at")}
    observation = {k: v for k, v in cfg["observation"].items() if k not in DEPLOYMENT_ONLY_KEYS}   # deployment-only keys do not retrain
    return config_hash({"kind": kind, "agents": hashed_agents(cfg["agents"]), "observation": observation, "vf": vcfg,
                        "seed": cfg["value_functions"]["seed"], "dtype": cfg["dtype"]})
