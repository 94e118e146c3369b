"""The workflow's source triggers cover what each job family runs.

``SOURCES`` in ``workflow/rules/common.smk`` lists the parts of the package whose edit reruns a
job family (issue 17). A module a family's jobs import but the list misses would let an edit
change results silently; listing too much reruns hours of cells for nothing (evaluation cells do
not list the tables, the report or the oracle). Checked on the source: the static import closure of
each family's entry modules (every import, function-level ones included, so a superset of what
runs; ``TYPE_CHECKING`` imports left out), minus the glue that changes no result.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

from conftest import REPO

PACKAGE = REPO / "madpinn"
GLUE = ("madpinn.commands", "madpinn.config", "madpinn.tracking", "madpinn.hints", "madpinn.checksum",
        "madpinn.atomic")


def _literal(name: str):
    """The dict literal ``name = {...}`` of workflow/rules/common.smk; a name inside it (such as
    ``VF_INFERENCE``, unpacked in place) is that file's list literal of the same name."""
    text = (REPO / "workflow" / "rules" / "common.smk").read_text()
    start = text.index(f"\n{name} = {{") + len(f"\n{name} = ")
    expr = ast.parse(text[start:text.index("\n}\n", start) + 2], mode="eval")
    lists = {n.id: _list_literal(text, n.id) for n in ast.walk(expr) if isinstance(n, ast.Name)}
    return eval(compile(expr, "common.smk", "eval"), {"__builtins__": {}}, lists)   # literals and those lists only


def _list_literal(text: str, name: str) -> list:
    start = text.index(f"\n{name} = [") + len(f"\n{name} = ")
    return ast.literal_eval(text[start:text.index("]\n", start) + 1])


def _sources() -> dict[str, list[str]]:
    return _literal("SOURCES")


def _path(module: str) -> Path | None:
    p = PACKAGE.joinpath(*module.split(".")[1:])
    if (p / "__init__.py").is_file():
        return p / "__init__.py"
    return p.with_suffix(".py") if p.with_suffix(".py").is_file() else None


def _runtime_nodes(tree):
    """Every node except those under ``if TYPE_CHECKING:`` (annotations only, never run)."""
    todo = [tree]
    while todo:
        node = todo.pop()
        yield node
        for child in ast.iter_child_nodes(node):
            if isinstance(child, ast.If) and getattr(child.test, "id", None) == "TYPE_CHECKING":
                todo += child.orelse
            else:
                todo.append(child)


def _imports(module: str) -> set[str]:
    """Static imports of ``module``, plus the targets of a lazy package's ``_HOMES`` (PEP 562
    ``__getattr__``: ``madpinn.value_functions`` resolves ``load_vs`` from its ``model`` module)."""
    out = set()
    for node in _runtime_nodes(ast.parse(_path(module).read_text())):
        names = []
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            names = [node.module] + [f"{node.module}.{a.name}" for a in node.names]
        elif (isinstance(node, ast.Assign) and getattr(node.targets[0], "id", "") == "_HOMES"
              and isinstance(node.value, ast.Dict)):
            names = list(ast.literal_eval(node.value).values())
        for name in names:
            if name.startswith("madpinn") and _path(name):
                parts = name.split(".")
                out |= {".".join(parts[:i]) for i in range(2, len(parts) + 1)}
    return out


def _closure(entries) -> set[str]:
    """Modules reachable from ``entries``; glue reached on the way is not followed further (the
    config check's own imports, for instance, change no result)."""
    seen, todo = set(), list(entries)
    while todo:
        m = todo.pop()
        if m not in seen and _path(m):
            seen.add(m)
            if m in entries or not m.startswith(GLUE):
                todo += _imports(m)
    return seen


def _package_modules(sub: str) -> list[str]:
    root = PACKAGE / sub
    return [".".join(("madpinn",) + f.relative_to(PACKAGE).with_suffix("").parts).removesuffix(".__init__")
            for f in sorted(root.rglob("*.py"))]


# each family's entry modules (registries import policies and backends by name: whole packages).
# Not here: "marl" — its closure reaches the MuJoCo backend only through SimSettings' lazy import of
# MujocoSettings, which the trainers (double-integrator physics) never run; listing the simulation
# for them would retrain both baselines on every backend edit.
ENTRIES = {
    "evaluate": ["madpinn.commands.evaluate", "madpinn.evaluation.cell", "madpinn.policies", "madpinn.policies.base",
                 *_package_modules("simulation")],
    "gap": ["madpinn.commands.gap", "madpinn.evaluation.gap", *_package_modules("policies"),
            *_package_modules("simulation")],
    "oracle": ["madpinn.evaluation.oracle"],
    "tables": ["madpinn.evaluation.tables", *_package_modules("figures")],
    "report": ["madpinn.evaluation.reproduction"],
    "value": _package_modules("value_functions"),
    "render": ["madpinn.commands.mujoco", *_package_modules("simulation")],
}


def _covered(path: Path, listed) -> bool:
    """``path`` is one of the listed files or lies under one of the listed directories."""
    return any(path == p or p in path.parents for p in listed)


@pytest.mark.parametrize("family", sorted(ENTRIES))
def test_every_module_a_family_runs_is_listed(family):
    listed = [PACKAGE / part for part in _sources()[family]]
    missing = []
    for module in sorted(_closure(ENTRIES[family])):
        if module == "madpinn" or module.startswith(GLUE):
            continue
        path = _path(module)
        if not _covered(path, listed):
            missing.append(str(path.relative_to(PACKAGE)))
    assert not missing, f"SOURCES['{family}'] misses {missing}"


def test_evaluation_cells_do_not_rerun_for_tables_report_or_oracle_edits():
    listed = {PACKAGE / part for part in _sources()["evaluate"]}
    for module in ("evaluation/tables.py", "evaluation/reproduction.py", "evaluation/oracle.py"):
        assert not _covered(PACKAGE / module, listed), module


def _policy_modules() -> dict[str, str]:
    """``_MODULES`` of madpinn/policies/base.py: method -> its module (imported by name at run time)."""
    tree = ast.parse((PACKAGE / "policies" / "base.py").read_text())
    node = next(n for n in tree.body if isinstance(n, ast.Assign) and getattr(n.targets[0], "id", "") == "_MODULES")
    return ast.literal_eval(node.value)


@pytest.mark.parametrize("method", sorted(_policy_modules()))
def test_every_module_a_method_runs_is_listed_for_its_cells(method):
    """An evaluation cell of ``method`` hashes SOURCES['evaluate'] + METHOD_SOURCES[method]; every
    module its policy imports must be among them."""
    methods = _literal("METHOD_SOURCES")
    assert method in methods, f"METHOD_SOURCES has no entry for '{method}' (its cells would hash every policy)"
    listed = [PACKAGE / part for part in _sources()["evaluate"] + methods[method]]
    missing = [str(_path(m).relative_to(PACKAGE)) for m in sorted(_closure([_policy_modules()[method]]))
               if m != "madpinn" and not m.startswith(GLUE) and not _covered(_path(m), listed)]
    assert not missing, f"METHOD_SOURCES['{method}'] misses {missing}"


def test_value_function_training_edits_do_not_rerun_evaluation_cells():
    """MAD-PINN and SafeMARL cells hash the value-function modules they run (loading and
    evaluating a trained network), not its training, grid reference or verification: those reach
    a cell through the trained model file, its input."""
    methods = _literal("METHOD_SOURCES")
    for method in ("madpinn", "safemarl"):
        listed = [PACKAGE / p for p in _sources()["evaluate"] + methods[method]]
        for module in ("train.py", "grid_reference.py", "verification.py", "figures.py", "shipping.py"):
            assert not _covered(PACKAGE / "value_functions" / module, listed), (method, module)
        assert _covered(PACKAGE / "value_functions" / "model.py", listed), method


def test_editing_one_method_does_not_rerun_another_methods_cells():
    """The MAD-PINN policy's modules are not hashed into the baselines' cells, and vice versa."""
    methods = _literal("METHOD_SOURCES")
    common = [PACKAGE / part for part in _sources()["evaluate"]]
    for module in ("policies/madpinn.py", "policies/look_ahead.py", "policies/z_search.py"):
        for other in ("mppi", "nominal", "safemarl", "defmarl"):
            assert not _covered(PACKAGE / module, common + [PACKAGE / p for p in methods[other]]), (module, other)
    for other in ("madpinn", "nominal", "safemarl", "defmarl"):
        assert not _covered(PACKAGE / "policies/mppi.py", common + [PACKAGE / p for p in methods[other]]), other
