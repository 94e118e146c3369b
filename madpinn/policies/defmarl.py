"""DEF-MARL (SPEC §8): distributed epigraph-form MARL (``madpinn.marl.defmarl``).

Runs ``defmarl-n3`` / ``defmarl-n8`` load their variant's trained model (``--model policy=PATH``,
passed in by the workflow); every policy step each agent root-finds its smallest safe budget z on
its constraint critic, the team uses the maximum, and the actor ``π(a | o_i, z)`` acts.
"""

from __future__ import annotations

from madpinn.marl.defmarl.deploy import DefMarlPolicy, load_defmarl
from madpinn.policies.base import PolicyContext, register_policy


@register_policy("defmarl")
def make_defmarl(ctx: PolicyContext) -> DefMarlPolicy:
    m = ctx.method_cfg
    return load_defmarl(
        ctx.model("policy", "defmarl"), ctx.obs_spec, ctx.dynamics.u_max, ctx.obs_spec.collision_radius, ctx.device, ctx.dtype,
        iterations=int(m["root_iterations"]), level=float(m["safe_level"]), root_period=int(m["root_period_steps"]),
    )
