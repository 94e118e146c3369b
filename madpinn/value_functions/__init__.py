"""Learned value functions: V̂ (epigraph PINN, SPEC §4) and V_s (pairwise reachability, SPEC §5).

Public API::

    from madpinn.value_functions import load_vhat, load_vs
    vhat = load_vhat("results/models/vhat.pt")   # vhat.value(obs, z, t), vhat.value_and_grad(obs, z, t)
    vs = load_vs("results/models/vs.pt")         # vs.value(x_rel, t), vs.value_and_grad(x_rel, t)
    z_star, feasible = min_feasible_z(vhat, obs, z_tolerance)   # the deployed z* search (SPEC §6)

The names are resolved on first use (PEP 562), so that importing a light sub-module such as
``madpinn.value_functions.build`` (the command line's parser does) does not import torch.
"""

from importlib import import_module

_HOMES = {
    "CheckpointError": "madpinn.value_functions.model",
    "PairValue": "madpinn.value_functions.model",
    "VHat": "madpinn.value_functions.model",
    "load_vhat": "madpinn.value_functions.model",
    "load_vs": "madpinn.value_functions.model",
    "min_feasible_z": "madpinn.value_functions.z_search",
}

__all__ = sorted(_HOMES)


def __getattr__(name):
    if name not in _HOMES:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(import_module(_HOMES[name]), name)
    globals()[name] = value
    return value


def __dir__():
    return sorted(set(globals()) | set(_HOMES))
