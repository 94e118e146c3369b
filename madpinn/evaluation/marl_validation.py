"""The validation curve of a DEF-MARL training run, on the package's own evaluation cells.

:class:`CellValidation` is the :class:`madpinn.marl.training_run.Validation` that ``train-defmarl``
passes to its training run: it evaluates the current policy on a validation seed (≥ 100, never a
protocol seed), decides the plateau and scores the rows the deployed checkpoint is chosen on
(:mod:`madpinn.marl.best_model`). It lives above ``marl/`` because it runs cells.
"""

from __future__ import annotations

import random
from dataclasses import replace
from pathlib import Path
from typing import Sequence

from madpinn.marl.best_model import BestOnValidation


class CellValidation(BestOnValidation):
    """Validation curve of run ``defmarl-<variant>``: the evaluation cells (``run_cell``, the
    study's cell settings with ``scenarios`` replaced) at the training and extra agent counts on
    the validation seed; adds ``val_safety_n<N>`` (%), ``val_safe_scenarios_n<N>`` (%),
    ``val_cost_n<N>`` and ``val_plateau`` to the iteration's curve row. The global RNG states are
    restored afterwards, so validating does not change the trained weights."""

    def __init__(self, cfg: dict, run: str, training_counts: Sequence[int], threads: int):
        from madpinn.config import method_config
        from madpinn.evaluation.cell import CellSettings
        from madpinn.marl.validation import ValidationSettings

        _, mcfg = method_config(cfg, run)
        self.settings = ValidationSettings.from_config(mcfg["validation"])
        s = self.settings
        self.every = s.every
        self.cell = replace(CellSettings.from_config(cfg, s.study, run), scenarios=s.scenarios)
        self.train_n = int(training_counts[0])
        self.counts = s.counts(training_counts)
        self.threads = threads
        self.stop_at_plateau = s.stop and s.every > 0

    def __call__(self, model: Path) -> dict:
        import numpy as np
        import torch

        from madpinn.evaluation.cell import run_cell

        states = (torch.get_rng_state(), np.random.get_state(), random.getstate())
        try:
            out = {}
            for n in self.counts:
                s = run_cell(self.cell, n, self.settings.seed, models={"policy": model}, backend=self.settings.backend,
                             threads=self.threads, progress=False).summary
                out.update({f"val_safety_n{n}": 100.0 * s["safety_rate"], f"val_safe_scenarios_n{n}": 100.0 * s["safe_scenarios"],
                            f"val_cost_n{n}": s["cost"]})
        finally:
            torch.set_rng_state(states[0])
            np.random.set_state(states[1])
            random.setstate(states[2])
        print(" ".join(f"{k}={v:.4g}" for k, v in out.items()), flush=True)
        return out

    def plateau(self, history: Sequence[dict]) -> bool:
        """The plateau rule (:func:`madpinn.marl.validation.plateau`) on the safety curve at the
        first training agent count."""
        from madpinn.marl.validation import plateau

        key = f"val_safety_n{self.train_n}"
        curve = [h[key] for h in history if key in h]
        return plateau(curve, self.settings.window, self.settings.min_gain)

    def score(self, stats) -> tuple[float, float] | None:
        """The best model's criterion: validation safety (%) at the first training agent count,
        rounded to 1e-6 so that equal outcome counts tie exactly (raw floats differ by rounding),
        then, on a tie, the mean validation safety at the other agent counts (generalisation)."""
        s = stats.get(f"val_safety_n{self.train_n}")
        if s is None or s != s:
            return None
        others = [stats[k] for k in (f"val_safety_n{n}" for n in self.counts if n != self.train_n) if k in stats]
        return round(float(s), 6), (round(sum(map(float, others)) / len(others), 6) if others else 0.0)

    def curves(self) -> tuple[str, ...]:
        return tuple(f"val_{m}_n{n}" for n in self.counts for m in ("safety", "safe_scenarios", "cost")) + (
            "val_plateau", "val_best")
