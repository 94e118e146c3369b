"""Settings declared once (issue 32): ``config.yaml`` holds every value, the schema every bound,
and the settings dataclasses mirror them without a second copy.

Rules checked here, for every dataclass of the package that has a ``from_config`` (all are
registered in ``SETTINGS`` below, and all are named ``*Settings``):

- a field read from the config has no default of its own (fields that are no config key are
  listed in ``not_config``);
- a key the schema leaves optional is read, when absent, as the schema's ``default``, which the
  loader fills in (the one place the absent value is written; ``tests/test_settings_once.py``);
- a dataclass check never disagrees with a schema bound: a value just inside every schema bound
  (``minimum``, ``maximum``, exclusive ones, ``enum``) builds, and values just outside and far
  outside are either both accepted (the schema alone holds the bound) or both rejected (the
  dataclass re-checks the same bound, for objects built in code).
"""

from __future__ import annotations

import ast
import copy
import dataclasses
from dataclasses import dataclass, field
from typing import Any, Callable

import pytest

from conftest import REPO
from madpinn.config import ConfigError, method_config, validate_config
from madpinn.config.schema import _schema, node_at, object_branch, resolve
from madpinn.value_functions.epigraph import EpigraphSystem
from madpinn.dynamics.pair import PairSystem
from madpinn.evaluation.oracle import OracleSettings
from madpinn.marl.defmarl.epigraph import EpigraphSettings
from madpinn.marl.env import EnvSettings, RewardSettings
from madpinn.marl.ppo import PPOSettings
from madpinn.marl.validation import ValidationSettings
from madpinn.observation import ObservationSettings
from madpinn.policies import policy_settings
from madpinn.policies.defmarl import DefMarlSettings
from madpinn.policies.madpinn import MadPinnSettings
from madpinn.value_functions.calibration import CalibrationSettings
from madpinn.policies.mppi import MPPISettings
from madpinn.policies.nominal import NominalSettings
from madpinn.policies.safemarl import SafeMarlSettings
from madpinn.policies.safety_filter import CBVFSettings
from madpinn.scenarios import Arena
from madpinn.settings import AgentSettings
from madpinn.simulation.settings import SimSettings
from madpinn.simulation.mujoco.controller import ControllerSettings
from madpinn.simulation.mujoco.settings import MujocoSettings
from madpinn.evaluation.cell import CellSettings
from madpinn.evaluation.conformal_settings import ConformalSettings
from madpinn.evaluation.recipe_settings import RecipeSettings
from madpinn.evaluation.table_ii_settings import ReadingsSettings
from madpinn.tracking.settings import TrackingSettings
from madpinn.value_functions.grid_reference import GridSettings
from madpinn.value_functions.sampling import ConflictSamplingSettings, NearSamplingSettings
from madpinn.value_functions.train import TrainSettings
from madpinn.value_functions.verification import ScenarioSettings


def _at(cfg: dict, path: str) -> Any:
    node = cfg
    for part in path.split("."):
        node = node[part]
    return node


def _method(run: str):
    return lambda cfg: policy_settings(run.partition("-")[0], method_config(cfg, run)[1])


@dataclass
class Entry:
    """One settings class: the config section it mirrors, how the package builds it from a whole
    config, and its fields' keys (relative to the section; ``/a.b`` from the config root; fields
    not named here read the key of their own name)."""

    cls: type
    section: str
    build: Callable[[dict], Any]
    keys: dict = field(default_factory=dict)
    not_config: tuple = ()          # fields that are no config key (derived, or set in code)
    nested: tuple = ()              # fields holding another registered settings object
    overlay: tuple = ()             # config files over config.yaml that declare a section null there

    def config(self, paper_cfg: dict) -> dict:
        """The config this entry's rules read: config.yaml, with the entry's overlays merged over it."""
        from madpinn.config import load_config

        return load_config([REPO / "config.yaml", *self.overlay]) if self.overlay else paper_cfg


SETTINGS = [
    Entry(AgentSettings, "agents", AgentSettings.from_config),
    Entry(SimSettings, "sim", SimSettings.from_config, nested=("mujoco",)),
    Entry(MujocoSettings, "sim.mujoco", lambda c: MujocoSettings.from_config(c["sim"]["mujoco"]), nested=("gains",)),
    Entry(ControllerSettings, "sim.mujoco.gains", lambda c: MujocoSettings.from_config(c["sim"]["mujoco"]).gains),
    Entry(ObservationSettings, "observation", ObservationSettings.from_config,
          keys={"collision_radius": "/agents.collision_radius", "model": "/agents.model"}),
    Entry(Arena, "arenas.small", lambda c: Arena.from_config(c, "small"), not_config=("name",)),
    Entry(NominalSettings, "methods.nominal", _method("nominal")),
    Entry(MadPinnSettings, "methods.madpinn", _method("madpinn"), keys={"strategy": "neighbours"},
          nested=("safety_filter",)),
    Entry(CBVFSettings, "methods.safemarl", lambda c: _method("safemarl")(c).cbvf, keys={"gamma": "cbvf_gamma"}),
    Entry(MPPISettings, "methods.mppi", _method("mppi"), keys={"dual_lr": "dual_ascent.lr", "penalty_max": "dual_ascent.max"}),
    Entry(SafeMarlSettings, "methods.safemarl", _method("safemarl"), not_config=("cbvf",)),   # cbvf: CBVFSettings of this section
    Entry(DefMarlSettings, "methods.defmarl", _method("defmarl-n3")),
    Entry(EnvSettings, "methods.safemarl.nominal.env", lambda c: EnvSettings.from_config(_at(c, "methods.safemarl.nominal.env"))),
    Entry(RewardSettings, "methods.safemarl.nominal.reward",
          lambda c: RewardSettings.from_config(_at(c, "methods.safemarl.nominal.reward"))),
    Entry(PPOSettings, "methods.safemarl.nominal.ppo", lambda c: PPOSettings.from_config(_at(c, "methods.safemarl.nominal.ppo"))),
    Entry(EpigraphSettings, "methods.defmarl.epigraph", lambda c: EpigraphSettings.from_config(_at(c, "methods.defmarl.epigraph"))),
    Entry(ValidationSettings, "methods.defmarl.validation",
          lambda c: ValidationSettings.from_config(_at(c, "methods.defmarl.validation")),
          keys={"window": "plateau.window", "min_gain": "plateau.min_gain", "stop": "plateau.stop"}),
    Entry(TrainSettings, "value_functions.vhat", lambda c: TrainSettings.from_config(c["value_functions"]["vhat"], c["value_functions"]["seed"]),
          keys={"seed": "/value_functions.seed"}),
    Entry(TrainSettings, "value_functions.vs", lambda c: TrainSettings.from_config(c["value_functions"]["vs"], c["value_functions"]["seed"]),
          keys={"seed": "/value_functions.seed"}),
    Entry(ConflictSamplingSettings, "value_functions.vhat.conflict_sampling",
          lambda c: ConflictSamplingSettings.from_config(c["value_functions"]["vhat"])),
    Entry(ConflictSamplingSettings, "value_functions.vs.conflict_sampling", lambda c: ConflictSamplingSettings.from_config(c["value_functions"]["vs"])),
    Entry(NearSamplingSettings, "value_functions.vs.near_sampling", lambda c: NearSamplingSettings.from_config(c["value_functions"]["vs"])),
    Entry(GridSettings, "value_functions.vs.validation.grid", lambda c: GridSettings.from_config(_at(c, "value_functions.vs.validation.grid"))),
    Entry(ScenarioSettings, "value_functions.vhat.validation.scenario",
          lambda c: ScenarioSettings.from_config(_at(c, "value_functions.vhat.validation.scenario")),
          not_config=("max_draws_factor",)),
    Entry(CalibrationSettings, "value_functions.vhat.validation.calibration",
          lambda c: CalibrationSettings.from_config(_at(c, "value_functions.vhat.validation.calibration")),
          keys={"level_max": "levels.max", "level_count": "levels.count"}),
    Entry(OracleSettings, "agents", lambda c: OracleSettings.from_config(c, "small"),
          not_config=("horizon_s", "dt")),        # the arena's episode length and episode / oracle.steps
    Entry(TrackingSettings, "tracking", TrackingSettings.from_config, keys={"experiment": "/experiment"},
          not_config=("uri", "pending_dir", "config_hash", "source", "results", "flush_every_s", "deferred")),
    Entry(EpigraphSystem, "value_functions.vhat", EpigraphSystem.from_config,
          keys={"u_max": "/agents.u_max", "v_max": "/agents.v_max"},
          not_config=("spec", "z_max")),   # spec: ObservationSettings at the training mapping; z_max: a number or `auto` (computed)
    Entry(PairSystem, "value_functions.vs", PairSystem.from_config,
          keys={"model": "/agents.model", "u_max": "/agents.u_max", "collision_radius": "/agents.collision_radius"}),
    Entry(ReadingsSettings, "table_ii_readings", ReadingsSettings.from_config,
          keys={"anchor": "anchor.study", "anchor_agents": "anchor.n_agents", "collision_radius": "/agents.collision_radius"},
          not_config=("patterns", "episodes", "labels", "protocol"),   # read from the studies and runs it names; protocol: two keys
          overlay=(REPO / "workflow" / "configs" / "scenario_laws.yaml",)),
    Entry(RecipeSettings, "vhat_recipe", RecipeSettings.from_config,
          not_config=("deciding", "reported", "seeds", "labels"),   # deciding / reported: study -> counts, held as (study, N) cells; the rest read from the studies and runs it names
          overlay=(REPO / "workflow" / "configs" / "vhat_recipe.yaml",)),
    Entry(ConformalSettings, "value_functions.vhat.validation.calibration", ConformalSettings.from_config,
          keys={"collision_radius": "/agents.collision_radius"},
          not_config=("studies", "arenas", "patterns", "levels", "others", "labels"),   # read from the studies and runs that deploy a level
          overlay=(REPO / "workflow" / "configs" / "conformal.yaml",)),
    Entry(CellSettings, "studies.main", lambda c: CellSettings.from_config(c, "main", "madpinn"),
          not_config=tuple(f.name for f in dataclasses.fields(CellSettings))),   # composite: study, run and parsed parts
]


# --- the schema, walked ---------------------------------------------------------------------------------------------

SCHEMA = _schema()


def _resolve(node: dict) -> dict:
    """A schema node with its local ``$ref`` and ``allOf`` parts merged (the loader's own walk)."""
    return resolve(node, SCHEMA)


def _node(path: str) -> dict:
    """Resolved schema node of a dotted config path (``""``: the root; a section that may also be
    null, e.g. ``methods.defmarl.validation``: its mapping branch)."""
    node = node_at(path, SCHEMA)
    return object_branch(node, SCHEMA) or node if "oneOf" in node else node


def _key_path(entry: Entry, name: str) -> str:
    key = entry.keys.get(name, name)
    return key[1:] if key.startswith("/") else f"{entry.section}.{key}"


def _required(path: str) -> bool:
    parent, _, key = path.rpartition(".")
    return key in _node(parent)["required"]


def _scalar_branches(node: dict) -> list[dict]:
    """The branches of a key's schema that hold a scalar's bounds (``oneOf`` parts included)."""
    branches = [node, *(_resolve(b) for b in node.get("oneOf", []))]
    return [b for b in branches if b.get("type") in ("number", "integer") or "enum" in b
            or any(k in b for k in ("minimum", "maximum", "exclusiveMinimum", "exclusiveMaximum"))]


def _config_fields(entry: Entry) -> list[str]:
    return [f.name for f in dataclasses.fields(entry.cls) if f.name not in entry.not_config]


# --- the rules ------------------------------------------------------------------------------------------------------


def _settings_classes_in_package() -> set[str]:
    """Names of the dataclasses under madpinn/ that define ``from_config`` (read from the AST)."""
    names = set()
    for path in (REPO / "madpinn").rglob("*.py"):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ClassDef) and any("dataclass" in ast.unparse(d) for d in node.decorator_list):
                if any(isinstance(b, ast.FunctionDef) and b.name == "from_config" for b in node.body):
                    names.add(node.name)
    return names


# Built from the config like settings, but no settings block: a named arena and the dynamics
# systems of the value functions (held to the same rules, named for what they are).
NOT_NAMED_SETTINGS = {"Arena", "EpigraphSystem", "PairSystem"}


def test_every_settings_class_is_registered_and_named_settings():
    found = _settings_classes_in_package()
    registered = {e.cls.__name__ for e in SETTINGS}
    assert not found - registered, f"register every settings class in SETTINGS: {sorted(found - registered)}"
    other = sorted(name for name in found | registered if not name.endswith("Settings") and name not in NOT_NAMED_SETTINGS)
    assert not other, f"one suffix for settings classes (*Settings): {other}"


def test_objects_built_from_settings_have_no_defaults_either():
    """Every agent model is built from ``agents`` in one place (``AgentSettings.dynamics``); the
    Crazyflie's thrust-to-weight ratio comes from ``sim.mujoco`` (``MujocoSettings.spec``), its
    other fields are the airframe's constants, no config keys."""
    from madpinn.dynamics import MODELS
    from madpinn.simulation.mujoco.model import CrazyflieSpec

    for model in MODELS.values():
        assert all(f.default is dataclasses.MISSING for f in dataclasses.fields(model)), model.name
        assert {f.name for f in dataclasses.fields(model)} <= set(_node("agents")["properties"]), model.name
    spec = {f.name: f for f in dataclasses.fields(CrazyflieSpec)}
    assert spec["thrust_to_weight"].default is dataclasses.MISSING
    assert not (set(spec) - {"thrust_to_weight"}) & set(_node("sim.mujoco")["properties"])


@pytest.mark.parametrize("entry", SETTINGS, ids=lambda e: f"{e.cls.__name__}:{e.section}")
def test_config_fields_have_no_default_of_their_own(entry):
    with_default = [f.name for f in dataclasses.fields(entry.cls) if f.name not in entry.not_config
                    and (f.default is not dataclasses.MISSING or f.default_factory is not dataclasses.MISSING)]
    assert not with_default, (f"{entry.cls.__name__}: {with_default} are read from the config and must not carry a "
                              "second default (config.yaml holds the value; an optional key's absent value is the schema's `default`)")


@pytest.mark.parametrize("entry", SETTINGS, ids=lambda e: f"{e.cls.__name__}:{e.section}")
def test_fields_read_their_keys(entry, paper_cfg):
    """Each mapped key exists in the schema and in config.yaml, and the built field holds its value."""
    paper_cfg = entry.config(paper_cfg)
    built = entry.build(copy.deepcopy(paper_cfg))
    for name in _config_fields(entry):
        path = _key_path(entry, name)
        _node(path)   # the schema declares it
        if name in entry.nested or entry.cls is CellSettings:
            continue
        try:
            value = _at(paper_cfg, path)
        except KeyError:
            assert not _required(path), f"{path} is required but absent from config.yaml"
            continue
        got = getattr(built, name)
        want = tuple(value) if isinstance(got, tuple) else value
        assert got == want, f"{entry.cls.__name__}.{name} = {got!r}, config {path} = {value!r}"


@pytest.mark.parametrize("entry", SETTINGS, ids=lambda e: f"{e.cls.__name__}:{e.section}")
def test_optional_keys_read_as_the_schema_default(entry, paper_cfg):
    paper_cfg = entry.config(paper_cfg)
    for name in _config_fields(entry):
        path = _key_path(entry, name)
        if name in entry.nested or entry.cls is CellSettings or _required(path):
            continue
        node = _node(path)
        assert "default" in node, f"{path} is optional: the schema must say what its absence means (`default:`)"
        cfg = copy.deepcopy(paper_cfg)
        parent, _, key = path.rpartition(".")
        _at(cfg, parent).pop(key, None)
        validate_config(cfg)   # the loader fills the absent key (the only place it is filled)
        value = getattr(entry.build(cfg), name)
        value = list(value) if isinstance(value, tuple) else value   # a YAML list held as a frozen tuple
        assert value == node["default"], f"absent {path} must read as the schema default"


def _probes(node: dict) -> tuple[list, list[tuple]]:
    """(values just inside the bounds, [(just outside, far outside), ...]) of one scalar key."""
    inside, outside = [], []
    for b in _scalar_branches(node):
        if "enum" in b:
            inside += list(b["enum"])
            continue
        integer = b.get("type") == "integer"
        step = 1 if integer else 1e-6
        far = 1000
        if "minimum" in b:
            m = b["minimum"]
            inside.append(m)
            outside.append((m - step, m - far))
        if "exclusiveMinimum" in b:
            m = b["exclusiveMinimum"]
            inside.append(m + step)
            outside.append((m, m - far))
        if "maximum" in b:
            m = b["maximum"]
            inside.append(m)
            outside.append((m + step, m + far))
        if "exclusiveMaximum" in b:
            m = b["exclusiveMaximum"]
            inside.append(m - step)
            outside.append((m, m + far))
    return inside, outside


def _builds(entry: Entry, cfg: dict) -> bool:
    try:
        entry.build(cfg)
    except Exception:   # noqa: BLE001 - any rejection counts
        return False
    return True


def _with(paper_cfg: dict, path: str, value) -> dict:
    cfg = copy.deepcopy(paper_cfg)
    parent, _, key = path.rpartition(".")
    _at(cfg, parent)[key] = value
    return cfg


# Inside values a dataclass may reject for a rule between two keys that the schema cannot state
# (the value is inside its own bound, the pair is not): (class, key) -> the rule.
CROSS_FIELD = {
    ("ObservationSettings", "observation.goal_range"): "carrot_margin < goal_range",
    ("GridSettings", "value_functions.vs.validation.grid.p_range"): "interior_p <= p_range",
    ("GridSettings", "value_functions.vs.validation.grid.v_range"): "interior_v <= v_range",
    ("GridSettings", "value_functions.vs.validation.grid.nodes"): "nodes odd (5 is, the probe 5 builds; kept for 8192-like maxima)",
    ("CBVFSettings", "methods.safemarl.candidates"): "critical_neighbours <= candidates",
    ("CBVFSettings", "methods.safemarl.critical_neighbours"): "critical_neighbours <= candidates",
    ("EpigraphSettings", "methods.defmarl.epigraph.z_min"): "z_min < z_max",
}


@pytest.mark.parametrize("entry", SETTINGS, ids=lambda e: f"{e.cls.__name__}:{e.section}")
def test_dataclass_bounds_agree_with_the_schema(entry, paper_cfg):
    paper_cfg = entry.config(paper_cfg)
    for name in _config_fields(entry):
        path = _key_path(entry, name)
        if name in entry.nested or entry.cls is CellSettings:
            continue
        inside, outside = _probes(_node(path))
        for value in inside:
            cfg = _with(paper_cfg, path, value)
            try:
                validate_config(cfg)
            except ConfigError:
                continue    # a cross-field rule of the config itself
            if (entry.cls.__name__, path) not in CROSS_FIELD:
                assert _builds(entry, cfg), f"{entry.cls.__name__} rejects {path} = {value!r}, inside the schema's bounds"
        for near, far in outside:
            with pytest.raises(ConfigError):
                validate_config(_with(paper_cfg, path, near))
            a, b = _builds(entry, _with(paper_cfg, path, near)), _builds(entry, _with(paper_cfg, path, far))
            assert a == b, (f"{entry.cls.__name__} checks {path} against another bound than the schema "
                            f"({near!r} {'builds' if a else 'fails'}, {far!r} {'builds' if b else 'fails'})")
