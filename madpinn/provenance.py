"""What a job depends on: the package code it runs and the part of the config it reads.

The workflow's rules carry both in their params (``source``, ``settings``), so that editing a
line a job runs, or changing a setting it reads, reruns that job (and what depends on it) and
nothing else.

**Code** (:func:`source_hash`): the definitions the job's entry reaches, read on the source
(``ast``; nothing is imported). From an entry ``"module:function"`` (a command's handler) it follows
what that function and the module's code run at import use: the module's own definitions by name,
every ``import`` (function-level (lazy) ones included, ``if TYPE_CHECKING:`` blocks left out) and
every package module named by a string constant (``importlib.import_module``, a package's PEP 562
``_HOMES``), and every module of a package whose ``__init__`` imports them all
(``import_submodules(__name__)``, :mod:`madpinn.submodules`: the agent models). ``from m import name``
reaches ``name`` and what it uses in turn; ``import m`` (or a module named by a string) reaches all of ``m``. The hash covers, per module reached, its code run
at import and the definitions reached, byte for byte, with the package data it names: a superset
of what runs, never less, and an edit to a definition no job reaches reruns nothing.

Plugin registries (a module-level dict ``_MODULES``: name -> module, one imported per job, e.g.
the policy of a run's method, or the command modules the parser loads) are not followed; a job names
the plugin it loads as an entry (:func:`plugin_module`).

:data:`GLUE` (tracking, checksums, atomic writes, hints, error reports and this module) writes no result: it is
neither hashed nor followed beyond an entry. The command layer and the config loading are hashed
like the rest (a job's seeds, the values it writes and the defaults it fills live there).

**Config** (:func:`madpinn.commands.job_settings`, :func:`madpinn.commands.settings_hash`):
per command, the one package function that says what its jobs read, declared beside the command's
parser (``reads``, :mod:`madpinn.commands.reads`): a trained model's own training hash
(:func:`madpinn.value_functions.build.training_hash`, :func:`madpinn.marl_hash.marl_training_hash`:
never validation or deployment-only settings), an evaluation cell's
:func:`madpinn.config.job_config`, and for the checks and outputs the config subtrees they read;
always as loaded, with every schema default filled in (a changed default reruns what reads it).
"""

from __future__ import annotations

import ast
import hashlib
import pkgutil
from functools import lru_cache
from pathlib import Path
from typing import Iterable, Mapping


PACKAGE = Path(__file__).resolve().parent
GLUE = ("madpinn.tracking", "madpinn.hints", "madpinn.checksum", "madpinn.atomic", "madpinn.provenance",
        "madpinn.commands.errors")
"""modules (and their sub-modules) that write no result: MLflow logging, file checksums, atomic
writes, error hints and the one-line error report (it names every expected exception class of the
package, which would tie every job to every module), this module"""
REGISTRY = "_MODULES"
"""name of a plugin registry: a module-level dict ``{name: module}``, one module imported per job"""
_DEFS = (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)
DATA_SUFFIXES = (".yaml", ".yml", ".json", ".csv", ".xml")
"""package data a module may read by file name (e.g. ``evaluation/paper_values.yaml``)"""


@lru_cache(maxsize=None)
def module_path(module: str) -> Path | None:
    """The file of package module ``module`` (dotted, ``madpinn.x.y``), or None when it is none
    (cached: a process sees the package's layout once)."""
    if not all(part.isidentifier() for part in module.split(".")) or module.split(".")[0] != "madpinn":
        return None
    p = PACKAGE.joinpath(*module.split(".")[1:])
    if (p / "__init__.py").is_file():
        return p / "__init__.py"
    return p.with_suffix(".py") if p.with_suffix(".py").is_file() else None


def is_glue(module: str) -> bool:
    return any(module == g or module.startswith(g + ".") for g in GLUE)


def _stat(path: Path) -> tuple[Path, int, int]:
    st = path.stat()
    return path, st.st_mtime_ns, st.st_size


@lru_cache(maxsize=None)
def _parse(path: Path, mtime_ns: int, size: int) -> ast.Module:
    """The parsed module (cached while the file keeps its size and mtime)."""
    return ast.parse(path.read_text(), filename=str(path))


@lru_cache(maxsize=None)
def _layout(path: Path, mtime_ns: int, size: int, module: str):
    """The parts of a module, each with what it imports (:func:`_scan`) and the names it uses: the
    code that runs at import (key None: its statements, the decorators, bases and defaults of its
    definitions) and each definition by name; with the whole module's imports and strings."""
    tree = _parse(path, mtime_ns, size)
    defs = {n.name: n for n in tree.body if isinstance(n, _DEFS)}
    base = [n for n in tree.body if not isinstance(n, _DEFS)]
    for d in defs.values():
        base += d.decorator_list + (d.bases + [k.value for k in d.keywords] if isinstance(d, ast.ClassDef)
                                    else d.args.defaults + [x for x in d.args.kw_defaults if x is not None])
    parts = {k: _scan([d], module) for k, d in defs.items()}
    parts[None] = _scan(base, module)
    return parts, set().union(*(e for e, _, _ in parts.values())), set().union(*(s for _, _, s in parts.values()))


def _runtime_nodes(node: ast.AST):
    """``node`` and every node below it except those under ``if TYPE_CHECKING:`` (never run) and
    the values of a plugin registry (one is imported per job, named as an entry)."""
    todo = [node]
    while todo:
        node = todo.pop()
        if isinstance(node, ast.If) and getattr(node.test, "id", None) == "TYPE_CHECKING":
            todo += node.orelse
        elif not _is_registry(node):
            yield node
            todo += ast.iter_child_nodes(node)


def _is_registry(node: ast.AST) -> bool:
    """``_MODULES = {...}`` (or annotated)."""
    targets = node.targets if isinstance(node, ast.Assign) else [node.target] if isinstance(node, ast.AnnAssign) else []
    return isinstance(getattr(node, "value", None), ast.Dict) and any(getattr(t, "id", None) == REGISTRY for t in targets)


def _scan(nodes: Iterable[ast.AST], module: str) -> tuple[set[str], set[str], set[str]]:
    """What ``nodes`` of ``module`` import, the names they use and their string constants. Imports:
    ``m`` for a whole module (``import m``, ``from p import m``, ``from m import *``, a module named
    by a string), ``m:name`` for a name taken from module ``m`` (``from m import name``), and ``p:``
    for each package whose ``__init__`` the import runs."""
    out, used, strings = set(), set(), set()
    for top in nodes:
        for node in _runtime_nodes(top):
            if isinstance(node, ast.Name):
                used.add(node.id)
                continue
            if isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom):
                if node.level:
                    raise ValueError(f"{module}: relative import (line {node.lineno}); the package imports absolutely")
                names = [node.module if a.name == "*" else f"{node.module}.{a.name}"
                         if module_path(f"{node.module}.{a.name}") else f"{node.module}:{a.name}" for a in node.names]
            elif isinstance(node, ast.Call) and _is_discovery(node):
                names = package_modules(module)
            elif isinstance(node, ast.Constant) and isinstance(node.value, str):
                names = [node.value] if module_path(node.value) else []   # a module's whole name, not "madpinn: …" text
                strings.add(node.value)
            else:
                continue
            for name in names:
                m = name.partition(":")[0]
                if module_path(m):
                    parts = m.split(".")
                    out |= {name} | {".".join(parts[:i]) + ":" for i in range(1, len(parts))}
    return out, used, strings


DISCOVERY = "import_submodules"
"""the call (:func:`madpinn.submodules.import_submodules`) by which a package imports all its modules"""


def _is_discovery(node: ast.Call) -> bool:
    """``import_submodules(__name__)`` (or ``<module>.import_submodules(__name__)``)."""
    name = getattr(node.func, "id", None) or getattr(node.func, "attr", None)
    if name != DISCOVERY:
        return False
    if len(node.args) != 1 or getattr(node.args[0], "id", None) != "__name__":
        raise ValueError(f"{DISCOVERY} is followed only as {DISCOVERY}(__name__) in a package's __init__ (line {node.lineno})")
    return True


def package_modules(package: str) -> list[str]:
    """The modules and sub-packages of package ``package`` (dotted names)."""
    path = module_path(package)
    if path is None or path.name != "__init__.py":
        raise ValueError(f"{package}: {DISCOVERY}(__name__) outside a package's __init__")
    # found as import_submodules finds them (pkgutil, nothing imported), kept where this package reads source
    return sorted(m for m in (f"{package}.{info.name}" for info in pkgutil.iter_modules([str(path.parent)])) if module_path(m))


def imports(entry: str) -> set[str]:
    """What ``entry`` imports (see :func:`_scan`): ``module`` (all of it), ``module:name`` (the
    module-level code and the definition ``name``), ``module:`` (the module-level code only)."""
    return set(_reach_entry(entry)[0])


def _reach_entry(entry: str) -> tuple[frozenset[str], frozenset[str] | None]:
    """What ``entry`` imports and which of its module's definitions it runs (None: all of them)."""
    module, colon, name = entry.partition(":")
    path = module_path(module)
    if path is None:
        raise ValueError(f"'{module}' is not a module of the madpinn package")
    return _reach(*_stat(path), module, None if not colon else (name,) if name else ())


@lru_cache(maxsize=None)
def _reach(path: Path, mtime_ns: int, size: int, module: str,
           names: tuple[str, ...] | None) -> tuple[frozenset[str], frozenset[str] | None]:
    """The imports of the code that runs when ``names`` of the module are used (None: all of it),
    and the definitions that code reaches: the code run at import and, transitively, the
    definitions it and ``names`` name."""
    parts, whole, _ = _layout(path, mtime_ns, size, module)
    if names is None:
        return frozenset(whole), None
    out, used = set(parts[None][0]), parts[None][1]
    seen, todo = set(), [*used, *names]
    while todo:
        name = todo.pop()
        if name in parts and name is not None and name not in seen:
            seen.add(name)
            out |= parts[name][0]
            todo += parts[name][1]
    return frozenset(out), frozenset(seen)


def reached(entries: Iterable[str]) -> dict[str, frozenset[str] | None]:
    """Module -> the top-level definitions of it that the entries (``module`` or
    ``module:function``) reach (None: the whole module), the entries' own modules and their
    packages included; glue reached on the way is not followed further (nor listed)."""
    entries = list(entries)
    out: dict[str, frozenset[str] | None] = {}
    seen, todo = set(), list(entries)
    while todo:
        e = todo.pop()
        if e in seen:
            continue
        seen.add(e)
        module = e.partition(":")[0]
        if e not in entries and is_glue(module):
            out.setdefault(module, frozenset())
            continue
        deps, defs = _reach_entry(e)
        todo += deps
        known = out.get(module, frozenset())
        out[module] = None if defs is None or known is None else known | defs
    return out


def closure(entries: Iterable[str]) -> set[str]:
    """Modules that the entries (``module`` or ``module:function``) reach, the entries' own
    modules and their packages included; glue reached on the way is not followed further."""
    return set(reached(entries))


def data_files(module: str) -> list[Path]:
    """Package data beside ``module`` that it names by file name (a string constant)."""
    path = module_path(module)
    names = _layout(*_stat(path), module)[2]
    return sorted(f for f in path.parent.iterdir() if f.suffix in DATA_SUFFIXES and f.name in names)


def source_files(entries: Iterable[str]) -> list[Path]:
    """Every file a job with these entries runs or reads (in part): the closure less glue, with
    its data."""
    modules = sorted(m for m in closure(entries) if not is_glue(m))
    files = {module_path(m) for m in modules} | {f for m in modules for f in data_files(m)}
    return sorted(files)


def reached_source(module: str, defs: frozenset[str] | None) -> bytes:
    """The bytes of ``module`` that a job reaching ``defs`` of it runs: the whole file (``defs``
    None), else the file less the lines of every top-level definition not in ``defs`` (decorators
    included); in both, less a plugin registry's lines (``_MODULES = {...}``: a job runs the one
    entry it is named by, hashed as its own entry, so adding or editing another entry re-keys nothing)."""
    path = module_path(module)
    data = path.read_bytes()
    body = _parse(*_stat(path)).body
    drop = [node for node in body if _is_registry(node) or (defs is not None and isinstance(node, _DEFS) and node.name not in defs)]
    if not drop:
        return data
    lines = data.splitlines(keepends=True)
    for node in reversed(drop):
        first = min([node.lineno, *(d.lineno for d in getattr(node, "decorator_list", ()))])
        del lines[first - 1:node.end_lineno]
    return b"".join(lines)


def source_hash(*entries: str) -> str:
    """sha256 (12 hex) over the package-relative path and reached bytes (:func:`reached_source`)
    of every module the entries reach (glue left out), and the package data those modules name."""
    h = hashlib.sha256()
    reach = reached(entries)
    for module in sorted(m for m in reach if not is_glue(m)):
        path = module_path(module)
        h.update(b"%s\0%s\0" % (str(path.relative_to(PACKAGE)).encode(), reached_source(module, reach[module])))
        for f in data_files(module):
            h.update(b"%s\0%s\0" % (str(f.relative_to(PACKAGE)).encode(), f.read_bytes()))
    return h.hexdigest()[:12]


def registry(module: str) -> dict[str, str]:
    """The plugin registry (``_MODULES``) of ``module``: name -> module, read from the source."""
    for node in _parse(*_stat(module_path(module))).body:
        if _is_registry(node):
            return ast.literal_eval(node.value)
    raise ValueError(f"{module} has no {REGISTRY}")


def plugin_module(module: str, name: str) -> str | None:
    """The module registered under ``name`` in ``module``'s registry (None: not a plugin there)."""
    return registry(module).get(name)


# --- the config a job reads: declared by each command beside its parser, hashed by
# madpinn.commands.settings_hash (the command layer; this module stays below it) ---

def model_training_hash(cfg: Mapping, name: str) -> str | None:
    """The training hash of value-function model ``name`` (``vhat``, ``vs``, ``vhat_<variant>``:
    its variant's merged settings), None for any other name (the shipped overlay's check)."""
    from madpinn.config import split_vf_model, with_vf_variant
    from madpinn.value_functions.build import training_hash

    split = split_vf_model(name)
    return training_hash(with_vf_variant(cfg, split[0], split[1]), split[0]) if split else None
