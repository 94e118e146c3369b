"""Settings parsed once (issue 13): every method's settings come from the validated config with
one factory name; the double integrator is built from settings in one place; backends and
policies take settings, never the config dict."""

from __future__ import annotations

import ast
import inspect

from conftest import REPO
from madpinn.config import load_config, method_config
from madpinn.policies import PolicyContext, policy_settings
from madpinn.settings import AgentSettings
from madpinn.simulation.settings import SimSettings

PACKAGE = REPO / "madpinn"


def test_settings_read_the_config(paper_cfg):
    limits = AgentSettings.from_config(paper_cfg)
    assert (limits.collision_radius, limits.u_max, limits.v_max) == tuple(
        paper_cfg["agents"][k] for k in ("collision_radius", "u_max", "v_max"))
    dyn = limits.dynamics()
    assert (dyn.u_max, dyn.v_max) == (limits.u_max, limits.v_max)
    sim = SimSettings.from_config(paper_cfg)
    assert sim.dt == paper_cfg["sim"]["dt"] and sim.backend == paper_cfg["sim"]["backend"]
    assert sim.mujoco is not None and sim.mujoco.altitude == paper_cfg["sim"]["mujoco"]["altitude"]


def test_every_configured_run_has_frozen_settings(paper_cfg):
    """Each run of each method builds its settings from the config alone (schema-required keys,
    no code defaults), and the settings are frozen."""
    import dataclasses

    import pytest

    for method, section in paper_cfg["methods"].items():
        for run in [method] + [f"{method}-{v}" for v in section.get("variants", {})]:
            name, mcfg = method_config(paper_cfg, run)
            s = policy_settings(name, mcfg)
            assert dataclasses.is_dataclass(s)
            with pytest.raises(dataclasses.FrozenInstanceError):
                setattr(s, dataclasses.fields(s)[0].name, None)
    assert "cfg" not in {f.name for f in dataclasses.fields(PolicyContext)}


def _calls(name: str) -> list[str]:
    where = []
    for path in PACKAGE.rglob("*.py"):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Call) and getattr(node.func, "id", getattr(node.func, "attr", None)) == name:
                where.append(str(path.relative_to(REPO)))
    return where


def test_one_place_builds_the_agent_model_and_one_factory_name():
    """No module constructs an agent model by its class: the one place is ``AgentSettings.dynamics``,
    which builds the configured ``agents.model`` from its class in the registry (issue 63)."""
    from madpinn.dynamics import MODELS

    for cls in MODELS.values():
        assert _calls(cls.__name__) == [], cls.__name__
    assert "model_class(self.model)" in inspect.getsource(AgentSettings.dynamics)
    for bad in ("from_dict", "from_method_config"):
        assert _calls(bad) == [], bad


def test_backends_take_settings():
    from madpinn.simulation.backend import make_backend

    assert list(inspect.signature(make_backend).parameters) == ["name", "sim", "limits", "device", "dtype"]
    cfg = load_config([REPO / "config.yaml"])
    b = make_backend("double_integrator", SimSettings.from_config(cfg), AgentSettings.from_config(cfg), "cpu", None)
    assert b.dt == cfg["sim"]["dt"] and b.dynamics.u_max == cfg["agents"]["u_max"]
