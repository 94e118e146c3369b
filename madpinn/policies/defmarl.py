"""DEF-MARL (SPEC §8): distributed epigraph-form MARL (``madpinn.marl.defmarl``).

Runs ``defmarl-n3`` / ``defmarl-n8`` load their variant's trained model (``--model policy=PATH``,
passed in by the workflow); every policy step each agent root-finds its smallest safe budget z on
its constraint critic, the agents agree on a budget (``consensus``: by default the max-consensus
over the sensing graph, so no agent reads one beyond the sensing radius, issue 47), and the actor
``π(a | o_i, z)`` acts.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping

from madpinn.marl.defmarl.deploy import DefMarlPolicy, load_defmarl
from madpinn.policies.base import PolicyContext, register_policy


@dataclass(frozen=True)
class DefMarlSettings:
    """``methods.defmarl`` at deployment (merged with a variant)."""

    root_iterations: int
    """bisection steps of each agent's smallest-safe-z search"""
    safe_level: float
    """agent i's z is safe when V_h(o_i, z) ≤ safe_level"""
    root_period_steps: int
    """policy steps between z searches (z held in between)"""
    consensus: str
    """how the agents agree on z (:data:`madpinn.marl.defmarl.root.CONSENSUS`): ``graph`` (max over
    the agents connected within the sensing radius), ``global`` (the team maximum of the authors'
    evaluation code), ``none``"""

    @classmethod
    def from_config(cls, m: Mapping) -> "DefMarlSettings":
        return cls(root_iterations=int(m["root_iterations"]), safe_level=float(m["safe_level"]),
                   root_period_steps=int(m["root_period_steps"]), consensus=str(m["consensus"]))


@register_policy("defmarl", DefMarlSettings)
def make_defmarl(ctx: PolicyContext) -> DefMarlPolicy:
    m = ctx.method
    return load_defmarl(
        ctx.model("policy", "defmarl"), ctx.obs_spec, ctx.dynamics.u_max, ctx.obs_spec.collision_radius, ctx.device, ctx.dtype,
        iterations=m.root_iterations, level=m.safe_level, root_period=m.root_period_steps, consensus=m.consensus,
    )
