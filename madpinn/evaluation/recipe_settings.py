"""``vhat_recipe``: which runs and cells re-choose V̂'s recipe on validation seeds (issue 61 item 4),
parsed once from the validated config. Light (no pandas): the workflow hashes it while it plans
(:func:`madpinn.commands.reads.vhat_recipe`)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping


@dataclass(frozen=True)
class RecipeSettings:
    """``vhat_recipe``: the models of the rule (docs/findings/2026-11-29-vhat-recipe-preregistered.md) and its cells."""

    base: str
    """the run deploying the shipped recipe's V̂ (F + C, training seed 0)"""
    replicates: tuple[str, ...]
    """runs deploying the base recipe trained with other training seeds; with the base they span the band"""
    components: Mapping[str, str]
    """component (``F``: the fine-tuning stage, ``C``: conflict sampling) -> the run whose V̂ lacks it (−X)"""
    deciding: tuple[tuple[str, int], ...]
    """(study, N) cells that decide, in the config's order"""
    reported: tuple[tuple[str, int], ...]
    """(study, N) cells reported beside the deciding ones, deciding nothing"""
    margin_points: float
    """percentage points beyond the band's edge for −X to count as below or above it"""
    quorum: int
    """deciding cells on one side of the band (and none on the other) that make a component needed or harmful"""
    seeds: Mapping[str, tuple[int, ...]]
    """study -> its seeds (validation seeds, ≥ 100)"""
    labels: Mapping[str, str]
    """run -> display label"""

    @classmethod
    def from_config(cls, cfg: Mapping) -> "RecipeSettings":
        from madpinn.config import method_config

        sec, studies = cfg["vhat_recipe"], cfg["studies"]
        cells = lambda part: tuple((str(st), int(n)) for st, counts in sec[part].items() for n in counts)   # noqa: E731
        runs = (sec["base"], *sec["replicates"], *sec["components"].values())
        return cls(base=str(sec["base"]), replicates=tuple(sec["replicates"]), components=dict(sec["components"]),
                   deciding=cells("deciding"), reported=cells("reported"), margin_points=float(sec["margin_points"]),
                   quorum=int(sec["quorum"]),
                   seeds={st: tuple(int(s) for s in studies[st]["seeds"]) for st in (*sec["deciding"], *sec["reported"])},
                   labels={r: str(method_config(cfg, r)[1]["label"]) for r in runs})

    @property
    def band_runs(self) -> tuple[str, ...]:
        """The runs whose safety spans the training band: the base and its replicates."""
        return (self.base, *self.replicates)
