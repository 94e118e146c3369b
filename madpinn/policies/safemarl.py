"""SafeMARL (SPEC §8): a trained MARL nominal policy filtered per agent by the control-barrier
value-function (CBVF) QP on the learned pairwise safety value V_s
(:mod:`madpinn.policies.safety_filter`, which documents the filter). The variant
``filter: false`` is the nominal MARL policy alone.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Mapping

from madpinn.marl.checkpoint import load_actor
from madpinn.marl.deploy import ActorPolicy
from madpinn.policies.base import PolicyContext, register_policy
from madpinn.policies.safety_filter import CBVFFilter, CBVFSettings, SafetyFilteredPolicy, make_cbvf_filter
from madpinn.value_functions import load_vs

__all__ = ["CBVFFilter", "SafeMarlSettings", "SafetyFilteredPolicy", "load_nominal", "make_safemarl"]


@dataclass(frozen=True)
class SafeMarlSettings:
    """``methods.safemarl`` at deployment (its ``nominal`` block trains the actor)."""

    filter: bool
    """filter the nominal actor through the CBVF QP (false: variant ``unfiltered``)"""
    cbvf: CBVFSettings
    """the CBVF filter (``cbvf_gamma``, ``critical_neighbours``, ``candidates``, ``threshold``)"""
    vs_band: bool
    """V_s clamped into its exact band [free-drift bound, ψ] (:meth:`madpinn.value_functions.PairValue.banded`)"""

    @classmethod
    def from_config(cls, m: Mapping) -> "SafeMarlSettings":
        return cls(filter=bool(m["filter"]), cbvf=CBVFSettings.from_config(m), vs_band=bool(m["vs_band"]))


def load_nominal(path, ctx: PolicyContext) -> ActorPolicy:
    """The trained nominal actor; refuses a model trained for other limits or collision radius."""
    actor, norm, meta = load_actor(path, ctx.device, ctx.dtype)
    spec = meta["obs_spec"]
    if abs(meta["u_max"] - ctx.dynamics.u_max) > 1e-9 or abs(spec["collision_radius"] - ctx.obs_spec.collision_radius) > 1e-9:
        raise ValueError(
            f"{path} was trained with u_max={meta['u_max']}, r={spec['collision_radius']}, but the config has "
            f"u_max={ctx.dynamics.u_max}, r={ctx.obs_spec.collision_radius}; retrain the nominal policy"
        )
    obs_spec = replace(ctx.obs_spec, **{k: spec[k] for k in ("goal_range", "offset_range", "sensing_radius")})
    return ActorPolicy(actor, norm, obs_spec, meta["neighbours"], ctx.dynamics.u_max)


@register_policy("safemarl", SafeMarlSettings)
def make_safemarl(ctx: PolicyContext) -> SafetyFilteredPolicy:
    m = ctx.method
    nominal = load_nominal(ctx.model("nominal", "safemarl"), ctx)
    if not m.filter:
        return SafetyFilteredPolicy(nominal, None)
    vs = load_vs(ctx.model("vs", "safemarl"), device=ctx.device, dtype=ctx.dtype, band=m.vs_band)
    return SafetyFilteredPolicy(nominal, make_cbvf_filter(vs, m.cbvf, ctx.dynamics.u_max, ctx.obs_spec.sensing_radius))
