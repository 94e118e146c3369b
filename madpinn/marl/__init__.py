"""Shared-parameter multi-agent PPO on the batched double integrator (SafeMARL nominal policy,
and the base DEF-MARL builds on). See ``docs/reference/marl.md``.

Modules, one concept each:

- :mod:`features` — local, permutation-invariant observation: ego features + a masked set of
  neighbours within the sensing radius (built with :mod:`madpinn.observation`).
- :mod:`env` — vectorised goal-reaching environment, ``[envs, agents]`` batched.
- :mod:`normalize` — running observation / return normalisation.
- :mod:`networks` — deep-sets encoder, Gaussian actor, value critic (extra inputs, several heads).
- :mod:`buffer` — rollout storage ``[T, envs, agents, …]``.
- :mod:`gae` — generalised advantage estimation.
- :mod:`ppo` — clipped PPO update (entropy bonus, gradient clipping, several critics).
- :mod:`trainer` — the loop: collect → advantages → update, with hooks for extensions.
- :mod:`checkpoint` — save/load (``weights_only=True``) with clear errors.
- :mod:`deploy` — a trained actor as a :class:`madpinn.policies.Policy`.
"""
