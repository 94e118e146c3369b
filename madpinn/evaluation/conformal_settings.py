"""The calibrated level's page (issue 62): which cells it reads and how their runs relate, parsed once
from the validated config. Light (no pandas): the workflow hashes it while it plans
(:func:`madpinn.commands.conformal.reads`)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping

from madpinn.marl.validation import MIN_VALIDATION_SEED   # the page reads validation-seed studies only: a protocol
# study may carry a level run as a labelled row (main's madpinn-cpeps01, issue 62), never this page's

REFERENCE_RUN = "madpinn"
"""V̂ alone (δ = 0, the paper's deployment): every run of the page is paired against it"""


def level_run(cfg: Mapping, run: str) -> Mapping | None:
    """The ``conformal`` settings a MAD-PINN run deploys (None: V̂ alone, δ = 0, or another method)."""
    from madpinn.config import method_config

    return method_config(cfg, run)[1].get("conformal") if run.partition("-")[0] == REFERENCE_RUN else None


def conformal_studies(cfg: Mapping) -> list[str]:
    """The page's studies: each on validation seeds only, outside ``all`` (a protocol study on a
    validation seed, the large arena's frontier, shows level runs beside its governors: its figure's,
    not this page's), with at least one level run (the workflow's ``conformal_cells`` /
    ``conformal_page`` inputs and :meth:`ConformalSettings.from_config` alike)."""
    return [s for s, st in cfg["studies"].items()
            if min(st["seeds"]) >= MIN_VALIDATION_SEED and not st["in_all"] and any(level_run(cfg, r) for r in st["runs"])]


@dataclass(frozen=True)
class LevelRun:
    """A run that deploys a calibrated level (``methods.madpinn.variants.<v>.conformal``)."""

    run: str
    epsilon: float
    """the violation rate the level is calibrated to, per accepted state of V̂'s own model"""
    beta: float
    """the calibration's confidence parameter (the bound holds with probability 1 − β)"""
    binned: bool
    """one δ per closing-speed bin (a Mondrian split) instead of one pooled δ"""
    distribution: str
    """the state distribution the level was calibrated on (``uniform`` | ``conflict``)"""


@dataclass(frozen=True)
class ConformalSettings:
    """The studies whose runs deploy a calibrated level, and what the page needs of them."""

    studies: tuple[str, ...]
    """studies with at least one level run (overlay ``workflow/configs/conformal.yaml``)"""
    arenas: Mapping[str, str]
    """study -> its arena (``small`` | ``large``): where the paper's row comes from"""
    patterns: Mapping[str, str]
    """study -> its start/goal law or conflict pattern"""
    levels: tuple[LevelRun, ...]
    """the level runs, in the studies' order"""
    others: tuple[str, ...]
    """the studies' other runs besides V̂ alone (e.g. a hand-tuned speed governor)"""
    labels: Mapping[str, str]
    """run -> display label"""
    speed_edges: tuple[float, ...]
    """interior closing-speed bin edges (m/s) of the calibration (its Mondrian split)"""
    collision_radius: float
    """r (m): an agent whose minimum separation is ≤ r collided"""

    @classmethod
    def from_config(cls, cfg: Mapping) -> "ConformalSettings":
        from madpinn.config import ConfigError, method_config, study_pattern

        studies = {s: cfg["studies"][s] for s in conformal_studies(cfg)}
        if not studies:
            raise ConfigError("no validation-seed study runs a calibrated level (methods.madpinn.variants.<v>.conformal; "
                              "overlay workflow/configs/conformal.yaml)")
        missing = sorted(s for s, st in studies.items() if REFERENCE_RUN not in st["runs"])
        if missing:
            raise ConfigError(f"studies {missing} run a calibrated level without '{REFERENCE_RUN}' (V̂ alone), "
                              "which every level run is paired against: add it to their runs")
        runs = list(dict.fromkeys(r for st in studies.values() for r in st["runs"]))
        levels = tuple(LevelRun(r, float(c["epsilon"]), float(c["beta"]), bool(c["binned"]), str(c["distribution"]))
                       for r in runs if (c := level_run(cfg, r)))
        level_names = {lv.run for lv in levels}
        return cls(studies=tuple(studies), arenas={s: str(st["arena"]) for s, st in studies.items()},
                   patterns={s: study_pattern(st) for s, st in studies.items()}, levels=levels,
                   others=tuple(r for r in runs if r != REFERENCE_RUN and r not in level_names),
                   labels={r: str(method_config(cfg, r)[1]["label"]) for r in runs},
                   speed_edges=tuple(float(x) for x in cfg["value_functions"]["vhat"]["validation"]["calibration"]["speed_edges"]),
                   collision_radius=float(cfg["agents"]["collision_radius"]))
