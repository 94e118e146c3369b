"""Learned value functions: V̂ (epigraph PINN, SPEC §4) and V_s (pairwise reachability, SPEC §5).

Public API::

    from madpinn.value_functions import load_vhat, load_vs
    vhat = load_vhat("results/models/vhat.pt")   # vhat.value(obs, z, t), vhat.value_and_grad(obs, z, t)
    vs = load_vs("results/models/vs.pt")         # vs.value(x_rel, t), vs.value_and_grad(x_rel, t)
    z_star, feasible = min_feasible_z(vhat, obs) # epigraph budget search of SPEC §6
"""

from madpinn.value_functions.model import CheckpointError, PairValue, VHat, load_vhat, load_vs
from madpinn.value_functions.validation import min_feasible_z

__all__ = ["CheckpointError", "PairValue", "VHat", "load_vhat", "load_vs", "min_feasible_z"]
