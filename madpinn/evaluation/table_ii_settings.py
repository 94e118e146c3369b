"""``table_ii_readings``: which cells are Table II's readings (issue 60), parsed once from the
validated config. Light (no pandas): the workflow hashes it while it plans
(:func:`madpinn.commands.reads.table_ii_readings`)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping


@dataclass(frozen=True)
class ReadingsSettings:
    """``table_ii_readings``: which cells are Table II's readings and which one is the protocol's."""

    studies: tuple[str, ...]
    """large-arena studies; every (study, run, horizon) of theirs is one reading"""
    patterns: Mapping[str, str]
    """study -> its start/goal law (``uniform`` | ``goals_within_<R>m``)"""
    episodes: Mapping[str, float]
    """study -> its episode length T (s): the horizon its unsuffixed figures are read at"""
    baselines: tuple[str, ...]
    """large-arena studies of other methods under the protocol's reading (item 4)"""
    anchor: str
    """Table I's setting (small arena, uniform law): the per-encounter hazard reference of §1"""
    anchor_agents: int
    """the anchor's agent count the large-arena cells are compared with (16: Table I's largest)"""
    protocol: tuple[str, str]
    """(study, run) of the protocol's own reading (read at that study's episode length)"""
    labels: Mapping[str, str]
    """run -> display label"""
    collision_radius: float
    """r (m): an agent whose minimum separation is ≤ r collided (the speed bins of the page)"""

    @classmethod
    def from_config(cls, cfg: Mapping) -> "ReadingsSettings":
        from madpinn.config import method_config, study_pattern

        sec, studies = cfg["table_ii_readings"], cfg["studies"]
        names = tuple(sec["studies"])
        every = (*names, *sec["baselines"], sec["anchor"]["study"])
        runs = {r for s in every for r in studies[s]["runs"]}
        return cls(studies=names, baselines=tuple(sec["baselines"]), patterns={s: study_pattern(studies[s]) for s in every},
                   episodes={s: float(cfg["arenas"][studies[s]["arena"]]["episode_s"]) for s in every},
                   anchor=str(sec["anchor"]["study"]), anchor_agents=int(sec["anchor"]["n_agents"]),
                   protocol=(str(sec["protocol"]["study"]), str(sec["protocol"]["run"])),
                   labels={r: str(method_config(cfg, r)[1]["label"]) for r in sorted(runs)},
                   collision_radius=float(cfg["agents"]["collision_radius"]))

    @property
    def protocol_reading(self) -> tuple[str, str, float]:
        """(study, run, horizon_s) of the protocol's reading."""
        study, run = self.protocol
        return study, run, self.episodes[study]
