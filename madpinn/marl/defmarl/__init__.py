"""DEF-MARL baseline (SPEC §8): distributed epigraph-form MARL on the shared PPO trainer.

Public anchor: MIT-REALM/def-marl (Zhang et al. 2025). See ``docs/reference/defmarl.md``.

- :mod:`epigraph` — z sampling, constraint h and cost l per period, the Dec-EFOCP λ-returns
  (discounted-max constraint targets, cost targets, combined ``max(max V_h, V_l − z)``).
- :mod:`critics` — the team cost critic ``V_l(x, z)`` (centralised, permutation invariant).
- :mod:`trainer` — :class:`DefMarlTrainer`, a :class:`madpinn.marl.trainer.PPOTrainer` subclass.
- :mod:`root` — the distributed deployment-time z root finder (bisection, with fallbacks).
- :mod:`deploy` — a trained model as a :class:`madpinn.policies.Policy`.
- :mod:`build` — the trainer of a variant (the ``train-defmarl`` job is in :mod:`madpinn.commands.defmarl`).
"""
