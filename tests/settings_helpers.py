"""Settings objects of the paper config for tests that build library objects directly.

The settings classes carry no defaults (config.yaml holds every value, issue 32); tests take the
paper's values from here and change only what they test with ``dataclasses.replace`` or keywords.
"""

from __future__ import annotations

from dataclasses import replace

from madpinn.config import deep_merge, load_config
from madpinn.value_functions.epigraph import EpigraphSystem
from madpinn.dynamics.pair import PairSystem
from madpinn.marl.defmarl.epigraph import EpigraphSettings
from madpinn.marl.env import EnvSettings, RewardSettings
from madpinn.marl.ppo import PPOSettings
from madpinn.observation import ObservationSettings
from madpinn.policies.madpinn import MadPinnSettings
from madpinn.config import REPO_ROOT

PAPER = load_config([REPO_ROOT / "config.yaml"])


def observation_settings(**changes) -> ObservationSettings:
    """The paper's observation at the training mapping (carrot margin 0, ``neighbour_goal: ego``)."""
    return replace(ObservationSettings.from_config(PAPER).base_mapping(), **changes)


def madpinn_settings(**changes) -> MadPinnSettings:
    """``methods.madpinn`` of the paper config (the paper's deployment)."""
    return replace(MadPinnSettings.from_config(PAPER["methods"]["madpinn"]), **changes)


def mujoco_section(**changes) -> dict:
    """``sim.mujoco`` of the paper config with ``changes`` merged over it (``gains`` by key)."""
    return deep_merge(PAPER["sim"]["mujoco"], changes)


def ppo_settings(**changes) -> PPOSettings:
    return replace(PPOSettings.from_config(PAPER["methods"]["safemarl"]["nominal"]["ppo"]), **changes)


def env_settings(**changes) -> EnvSettings:
    return replace(EnvSettings.from_config(PAPER["methods"]["safemarl"]["nominal"]["env"]), **changes)


def reward_settings(**changes) -> RewardSettings:
    """The SafeMARL nominal policy's reward weights."""
    return replace(RewardSettings.from_config(PAPER["methods"]["safemarl"]["nominal"]["reward"]), **changes)


def epigraph_settings(**changes) -> EpigraphSettings:
    return replace(EpigraphSettings.from_config(PAPER["methods"]["defmarl"]["epigraph"]), **changes)


def epigraph_system(**changes) -> EpigraphSystem:
    """V̂'s system of the paper config (observation at the training mapping, z_max ``auto``)."""
    return replace(EpigraphSystem.from_config(PAPER), **changes)


def pair_system(**changes) -> PairSystem:
    """V_s's relative pair system of the paper config."""
    return replace(PairSystem.from_config(PAPER), **changes)
