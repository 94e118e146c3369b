"""Multi-agent policies. Each maps the global state to all agents' accelerations in one batch."""

from madpinn.policies.base import Policy, PolicyContext, make_policy, policy_settings, register_policy

__all__ = ["Policy", "PolicyContext", "make_policy", "policy_settings", "register_policy"]
