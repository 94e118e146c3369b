"""DEF-MARL (SPEC §8): distributed epigraph-form MARL (``madpinn.marl.defmarl``).

Runs ``defmarl-n3`` / ``defmarl-n8`` load the model named by the variant's ``model`` key from
the models directory; every policy step each agent root-finds its smallest safe budget z on
its constraint critic, the team uses the maximum, and the actor ``π(a | o_i, z)`` acts.
"""

from __future__ import annotations

from madpinn.marl.defmarl.deploy import DefMarlPolicy, load_defmarl
from madpinn.policies.base import PolicyContext, register_policy


@register_policy("defmarl")
def make_defmarl(ctx: PolicyContext) -> DefMarlPolicy:
    m = ctx.method_cfg
    if "model" not in m:
        raise ValueError("DEF-MARL runs name a trained model: use a variant (defmarl-n3, defmarl-n8) whose config sets 'model'")
    return load_defmarl(
        ctx.models_dir / m["model"], ctx.obs_spec, ctx.dynamics.u_max, ctx.obs_spec.collision_radius, ctx.device, ctx.dtype,
        iterations=int(m["root_iterations"]), level=float(m["safe_level"]), root_period=int(m["root_period_steps"]),
    )
