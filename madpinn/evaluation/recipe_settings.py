"""``vhat_recipe``: which runs and cells re-choose V̂'s recipe on validation seeds (issue 61 item 4),
parsed once from the validated config, with the cross-field rules its schema cannot state. Light (no
pandas): the workflow builds it while it plans (the rule ``vhat_recipe``'s settings hash), so a bad
section stops the workflow before any job.

The rules live here, not in :mod:`madpinn.config.rules`: that module is part of every job's source
hash (every job validates its config), so a rule of this section there would rerun every cell."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Mapping


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
    adopted_band: tuple[str, ...]
    """runs spanning the adopted recipe's training band (the deployed V̂ and its training-seed
    replicates, issue 60 item 3): reported per cell beside the base's band, deciding nothing"""

    @classmethod
    def from_config(cls, cfg: Mapping) -> "RecipeSettings":
        """From a validated config; :class:`madpinn.config.ConfigError` naming each broken rule of :func:`recipe_errors`."""
        from madpinn.config import ConfigError, method_config

        lines = recipe_errors(cfg)
        if lines:
            raise ConfigError("invalid configuration:\n" + "\n".join(lines))
        sec, studies = cfg["vhat_recipe"], cfg["studies"]
        cells = lambda part: tuple((str(st), int(n)) for st, counts in sec[part].items() for n in counts)   # noqa: E731
        runs = tuple(dict.fromkeys((sec["base"], *sec["replicates"], *sec["components"].values(), *sec["adopted_band"])))
        return cls(base=str(sec["base"]), replicates=tuple(sec["replicates"]), components=dict(sec["components"]),
                   deciding=cells("deciding"), reported=cells("reported"), margin_points=float(sec["margin_points"]),
                   quorum=int(sec["quorum"]),
                   seeds={st: tuple(int(s) for s in studies[st]["seeds"]) for st in (*sec["deciding"], *sec["reported"])},
                   labels={r: str(method_config(cfg, r)[1]["label"]) for r in runs}, adopted_band=tuple(sec["adopted_band"]))

    @property
    def band_runs(self) -> tuple[str, ...]:
        """The runs whose safety spans the training band: the base and its replicates."""
        return (self.base, *self.replicates)


def recipe_errors(cfg: Mapping[str, Any]) -> list[str]:
    """The section's rules (one line each): its runs exist and are distinct, its cells' studies exist
    on validation seeds (≥ 100) with those agent counts, each deciding study runs every model of the
    rule, and the quorum can be met by the deciding cells."""
    sec = cfg["vhat_recipe"]
    if not sec:
        return ["  - 'vhat_recipe': not configured (e.g. workflow/configs/vhat_recipe.yaml)"]
    lines, studies, methods = [], cfg["studies"], cfg["methods"]
    runs = {"base": [sec["base"]], "replicates": sec["replicates"],
            **{f"components.{x}": [r] for x, r in sec["components"].items()}}
    every = [r for rs in runs.values() for r in rs]   # the rule's runs, distinct; adopted_band may repeat one (the deployed −C)
    for key, names in {**runs, "adopted_band": sec["adopted_band"]}.items():
        for run in names:
            method, _, variant = run.partition("-")
            if method not in methods or (variant and variant not in methods[method]["variants"]):
                lines.append(f"  - 'vhat_recipe.{key}': unknown run '{run}'")
    if len(set(every)) < len(every):
        lines.append(f"  - 'vhat_recipe': the base, replicates and components must be distinct runs, got {every}")
    for part in ("deciding", "reported"):
        for name, counts in sec[part].items():
            st = studies.get(name)
            if st is None:
                lines.append(f"  - 'vhat_recipe.{part}': unknown study '{name}'")
                continue
            if min(st["seeds"]) < 100:
                lines.append(f"  - 'studies.{name}.seeds': the recipe is chosen on validation seeds ≥ 100 only, got {st['seeds']}")
            absent = [n for n in counts if n not in st["agent_counts"]]
            if absent:
                lines.append(f"  - 'vhat_recipe.{part}.{name}': study '{name}' has no agent counts {absent} (has {st['agent_counts']})")
            lacking = [r for r in every if r not in st["runs"]] if part == "deciding" else []
            if lacking:
                lines.append(f"  - 'vhat_recipe.deciding.{name}': study '{name}' does not run {lacking}")
    cells = sum(len(c) for c in sec["deciding"].values())
    if sec["quorum"] > cells:
        lines.append(f"  - 'vhat_recipe.quorum': {sec['quorum']} exceeds the {cells} deciding cells")
    return lines
