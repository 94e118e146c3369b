"""Settings once (issue 48 item 2): every key of the configuration is required or has its schema
``default``, filled at load (:func:`madpinn.config.validate_config`); the code reads every key and
never writes a second default (no ``.get("key", literal)`` on a config key); settings objects are
frozen; filling the defaults changes no hash a job or a shipped model is known by."""

from __future__ import annotations

import ast
import copy
import dataclasses
import json

import jsonschema
import pytest
import yaml

from conftest import REPO
from madpinn.config import FILLED, deep_merge, load_config, validate_config
from madpinn.config.schema import OVERLAY, _schema, node_at, object_branch, resolve
from madpinn.marl_hash import marl_training_hash
from madpinn.commands import settings_hash
from madpinn.provenance import model_training_hash

SCHEMA = _schema()
ENTRIES = "x-entries"   # schema keyword of a mapping of named entries (studies, methods): no defaults


def _keys(node, path=""):
    """``(dotted key, resolved node, required)`` of every key the schema declares, overlays and
    their insides left out (a partial section: an absent key is its base's value)."""
    branch = object_branch(node, SCHEMA)
    if branch is None or OVERLAY in branch:
        return
    for key, sub in branch["properties"].items():
        here = f"{path}.{key}" if path else key
        r = resolve(sub, SCHEMA)
        yield here, r, key in branch["required"] or bool(branch.get(ENTRIES)), sub
        if OVERLAY not in r:
            yield from _keys(sub, here)
    extra = branch.get("additionalProperties")
    if isinstance(extra, dict):
        yield from _keys(extra, f"{path}.*")


KEYS = list(_keys(SCHEMA))


def test_the_walk_sees_the_whole_schema():
    paths = {p for p, _, _, _ in KEYS}
    assert {"sim.mujoco.gains.pos_xy", "studies.main.in_all", "methods.madpinn.vhat",
            "value_functions.vhat.conflict_sampling.tau", "methods.defmarl.training.network.encoder"} <= paths
    assert not any(".variants." in p for p in paths)   # overlays: partial sections


def test_every_key_is_required_or_has_a_default():
    loose = [p for p, node, required, _ in KEYS if not required and "default" not in node and OVERLAY not in node]
    assert not loose, f"give each a schema `default` (its absent value) or make it required: {loose}"


@pytest.mark.parametrize("path", [p for p, node, _, _ in KEYS if "default" in node])
def test_every_default_is_a_valid_value_of_its_key(path):
    node, raw = next((n, raw) for p, n, _, raw in KEYS if p == path)
    jsonschema.Draft202012Validator({"$defs": SCHEMA["$defs"], **raw}).validate(node["default"])


def test_every_overlay_names_its_base():
    for path, node, _, _ in KEYS:
        if OVERLAY in node:
            node_at(node[OVERLAY])   # raises on a base the schema does not have


def test_load_fills_every_default_and_records_it(paper_cfg):
    cfg = copy.deepcopy(paper_cfg)
    assert cfg["studies"]["main"]["pattern"] == "uniform" and cfg["studies"]["main"]["in_all"] is True
    assert cfg["methods"]["madpinn"]["vhat"] is None and cfg["methods"]["safemarl"]["nominal"]["network"]["encoder"] == "deepsets"
    assert "studies.main.collision_events" in cfg[FILLED] and "studies.gap_mujoco.collision_events" not in cfg[FILLED]
    assert "variants" not in cfg["methods"]["madpinn"]["variants"]["k1"]   # nothing filled inside an overlay
    written = yaml.safe_load((REPO / "config.yaml").read_text())["studies"]["main"]
    assert {k: v for k, v in cfg["studies"]["main"].items() if k in written} == written


def test_an_invalid_config_is_left_as_it_was(paper_cfg):
    from madpinn.config import ConfigError

    cfg = copy.deepcopy(paper_cfg)
    cfg.pop(FILLED)
    del cfg["studies"]["main"]["pattern"]
    cfg["agents"]["u_max"] = -1.0
    with pytest.raises(ConfigError):
        validate_config(cfg)
    assert "pattern" not in cfg["studies"]["main"] and FILLED not in cfg


# --- no second default in code -------------------------------------------------------------------------------------

CONFIG_KEYS = {p.rpartition(".")[2] for p, _, _, _ in KEYS}
NOT_CONFIG = {
    "meta": "a checkpoint's or a model file's metadata (files written before a key existed lack it)",
    "ck['meta']": "a checkpoint's metadata",
    "data['meta']": "a model file's metadata",
    "load_checkpoint(best_path)['meta']": "a checkpoint's metadata",
    "m": "a MARL checkpoint's metadata (marl/checkpoint.py)",
    "train_state": "a resumable checkpoint's state",
    "d": "a saved problem description (checkpoints written before a key existed)",
    "stats": "a policy's episode counters",
    "s": "a cell's JSON summary",
    "r": "a row of a result table",
    "values": "the paper's values (madpinn/evaluation/paper_values.yaml), not the config",
    "values.get(k[0], {})": "the paper's values of one table (paper_values.yaml)",
    "values.get(table, {})": "the paper's values of one table (paper_values.yaml)",
    "prov": "a report's provenance record",
    "next(iter(cells.values()), {})": "a cell's JSON summary",
    "next(iter(table.get(ref, {}).values()), {})": "a row of a result table",
    "paper_values().get(table, {})": "the paper's values (evaluation/paper_values.yaml)",
    "paper.get(table, {})": "the paper's values (evaluation/paper_values.yaml)",
}
"""receivers of ``.get("<a config key name>", default)`` that hold no config (the reason each)"""


def _config_gets(root=REPO):
    """``file:line receiver.get("key", default)`` of every two-argument ``get`` of a config key name."""
    out = []
    for path in sorted((root / "madpinn").rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text())):
            if (isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute) and node.func.attr == "get"
                    and len(node.args) == 2 and isinstance(node.args[0], ast.Constant)
                    and node.args[0].value in CONFIG_KEYS):
                receiver = ast.unparse(node.func.value)
                if receiver not in NOT_CONFIG:
                    out.append(f"{path.relative_to(root)}:{node.lineno} {receiver}.get({node.args[0].value!r}, ...)")
    return out


def test_no_second_default_for_a_config_key_in_the_package():
    found = _config_gets()
    assert not found, ("read the key (`cfg[...]`: the loader filled its schema default), or name the receiver in "
                       "NOT_CONFIG with the reason it holds no config:\n" + "\n".join(found))


def test_the_scan_sees_a_second_default(tmp_path):
    (tmp_path / "madpinn").mkdir()
    (tmp_path / "madpinn" / "m.py").write_text("def f(vcfg, meta):\n    return vcfg.get('obstacle_weight', 0.0), meta.get('iterations', 0)\n")
    assert _config_gets(tmp_path) == ["madpinn/m.py:2 vcfg.get('obstacle_weight', ...)"]


# --- frozen settings -----------------------------------------------------------------------------------------------


def _settings_classes():
    """``(file, class)`` of every dataclass of the package with a ``from_config`` (a settings object)."""
    for path in sorted((REPO / "madpinn").rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ClassDef) and any(isinstance(b, ast.FunctionDef) and b.name == "from_config"
                                                      for b in node.body):
                decos = [ast.unparse(d) for d in node.decorator_list if "dataclass" in ast.unparse(d)]
                if decos:
                    yield path.relative_to(REPO), node.name, decos[0]


def test_every_settings_object_is_frozen():
    loose = [f"{f}:{name} @{deco}" for f, name, deco in _settings_classes() if "frozen=True" not in deco]
    assert not loose, f"settings objects are frozen (build a new one with dataclasses.replace): {loose}"


def test_train_settings_are_frozen(paper_cfg):
    from madpinn.value_functions.train import TrainSettings

    s = TrainSettings.from_config(paper_cfg["value_functions"]["vs"], 0)
    with pytest.raises(dataclasses.FrozenInstanceError):
        s.init_from = "x.pt"
    assert dataclasses.replace(s, init_from="x.pt").init_from == "x.pt" and s.init_from is None


# --- hashes read the filled config: a changed default reruns what reads it (issue 63) -----------------------------


OVERLAY_MODELS = {"workflow/configs/agent_models.yaml": ("vhat_3d", "vs_3d")}
"""models of models/manifest.json trained for an overlay's variants (the 3-D model's, issue 63): each
is checked under that overlay, the others under config.yaml alone"""


@pytest.mark.parametrize("overlay, manifest", [(None, "models/manifest.json"),
                                               ("workflow/configs/reading_2r.yaml", "models/reading_2r/manifest.json"),
                                               ("workflow/configs/agent_models.yaml", "models/manifest.json")])
def test_every_shipped_model_keeps_its_training_hash(overlay, manifest):
    """Every shipped model's recorded training hash is this configuration's (the shipped path installs
    them, nothing retrains). The stamps were rewritten once when hashes began to read filled defaults
    (issue 63), each only where its old stamp equalled the old hash of this configuration."""
    cfg = load_config([REPO / "config.yaml", *([REPO / overlay] if overlay else [])])
    models = json.loads((REPO / manifest).read_text())["models"]
    own = OVERLAY_MODELS.get(overlay)
    elsewhere = {n for names in OVERLAY_MODELS.values() for n in names}
    models = {n: e for n, e in models.items() if (n in own if own else n not in elsewhere)}
    assert models   # every parametrisation checks some model
    for name, entry in models.items():
        marl = name.startswith(("safemarl", "defmarl"))
        assert (marl_training_hash(cfg, name) if marl else model_training_hash(cfg, name)) == entry["training_config_hash"], name


def test_a_resolved_config_written_out_hashes_as_the_original(paper_cfg, tmp_path):
    """The workflow writes the resolved config (``config.resolved.yaml``) that every job loads: its
    filled keys are recorded with it, so each job's settings hash is the planner's."""
    out = tmp_path / "resolved.yaml"
    out.write_text(yaml.safe_dump(paper_cfg, sort_keys=False))
    again = load_config([out])
    for kind in ("vhat", "vs"):
        assert settings_hash(again, "train-value", kind=kind) == settings_hash(paper_cfg, "train-value", kind=kind)
    for variant in paper_cfg["value_functions"]["vhat_variants"]:
        assert settings_hash(again, "train-value", kind="vhat", variant=variant) == \
            settings_hash(paper_cfg, "train-value", kind="vhat", variant=variant)
    for study, st in paper_cfg["studies"].items():
        for run in st["runs"]:
            assert settings_hash(again, "evaluate", study=study, run=run) == settings_hash(paper_cfg, "evaluate", study=study, run=run)


def test_a_cell_hash_reads_no_workflow_key(paper_cfg):
    """``in_all`` says which targets build a study's cells, not what a cell computes."""
    cfg = deep_merge(copy.deepcopy(paper_cfg), {"studies": {"main": {"in_all": False}}})
    validate_config(cfg)
    assert settings_hash(cfg, "evaluate", study="main", run="madpinn") == settings_hash(paper_cfg, "evaluate", study="main", run="madpinn")
    cfg = deep_merge(copy.deepcopy(paper_cfg), {"studies": {"main": {"collision_events": True}}})
    validate_config(cfg)
    assert settings_hash(cfg, "evaluate", study="main", run="madpinn") != settings_hash(paper_cfg, "evaluate", study="main", run="madpinn")


@pytest.mark.parametrize("key, value, command, job", [
    ("value_functions.vs.obstacle_weight", 3.0, "train-value", {"kind": "vs"}),
    ("studies.main.collision_events", True, "evaluate", {"study": "main", "run": "madpinn"}),
])
def test_a_changed_schema_default_reruns_what_reads_it(key, value, command, job):
    """config.yaml without ``key``, filled under the schema and under a copy of the schema's text with
    another default for it: the jobs that read the key get another settings hash (they used to keep
    theirs, when hashes read the config as written)."""
    from madpinn.config.schema import SCHEMA_PATH, fill_defaults

    written = yaml.safe_load((REPO / "config.yaml").read_text())
    parent, leaf = key.rsplit(".", 1)
    section = written
    for part in parent.split("."):
        section = section[part]
    section.pop(leaf, None)   # the default decides
    altered_schema = yaml.safe_load(SCHEMA_PATH.read_text())
    nodes, todo = [], [altered_schema]
    while todo:   # every schema node declaring `leaf` with a default
        node = todo.pop()
        if isinstance(node, dict):
            props = node.get("properties")
            if isinstance(props, dict) and isinstance(props.get(leaf), dict) and "default" in props[leaf]:
                nodes.append(props[leaf])
            todo += list(node.values())
        elif isinstance(node, list):
            todo += node
    assert len(nodes) == 1 and nodes[0]["default"] != value, (leaf, nodes)
    nodes[0]["default"] = value
    base = fill_defaults(copy.deepcopy(written))
    altered = fill_defaults(copy.deepcopy(written), altered_schema)
    assert lookup(base, key) != lookup(altered, key) == value
    assert settings_hash(base, command, **job) != settings_hash(altered, command, **job)


def lookup(cfg, key):
    from madpinn.config.hashing import lookup_key

    return lookup_key(cfg, key)
