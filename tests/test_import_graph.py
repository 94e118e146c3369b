"""The package's import graph has no circle and no upward arrow (issue 48 point 3): every import,
module-level or inside a function, as :mod:`madpinn.provenance` reads it.

Circles: none (the last, the MuJoCo backend registering itself with the registry that imported it
by name, went with issue 48: ``simulation/backend.py`` names the backend's module, which no longer
imports the registry).

Arrows: each top-level module and sub-package (an *area*) has a rank in :data:`LAYERS`, and a
module may import only areas of a lower rank (the house order of ``madpinn/__init__.py``:
dynamics → value functions → policies → simulation → evaluation → commands, with the shared
leaves below). Two areas of one rank are siblings and import neither each other.
"""

from __future__ import annotations

from madpinn.provenance import PACKAGE, imports

KNOWN: list[set[str]] = []
"""circles not yet removed (issue 48); a new one fails, and so does a removed one left listed"""


LAYERS = [
    {"madpinn", "atomic", "checksum", "device", "machine", "hints", "output_cache", "run_log", "separation", "scenario_errors",
     "submodules"},   # leaves
    {"conflicts", "encounters"},     # a scenario layout's conflicts: its pattern, its straight-line encounters
    {"scenarios"},
    {"config"},                      # reads scenarios to check agent counts
    {"dynamics"},                    # the agent models and the pair system
    {"observation"},                 # its layout follows the agent model
    {"settings"},                    # the agents' settings build the dynamics
    {"value_functions", "marl", "marl_hash"},
    {"policies"},
    {"simulation"},
    {"evaluation"},
    {"figures", "tracking"},
    {"commands"},
    {"provenance"},                  # names the command layer's packages (GLUE) and the training hashes
    {"source_cache"},                # keeps provenance's source hashes between snakemake starts
    {"__main__"},
]
"""areas (``madpinn.<area>``; ``madpinn``: the package's ``__init__``) from the bottom up"""
RANK = {area: i for i, layer in enumerate(LAYERS) for area in layer}


def _area(module: str) -> str:
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else parts[0]


def _graph() -> dict[str, set[str]]:
    modules = _modules()
    return {m: {e.partition(":")[0] for e in imports(m) if not e.endswith(":")} & set(modules) - {m} for m in modules}


def _upward(graph: dict[str, set[str]]) -> list[str]:
    """``importer -> imported`` for every import of an area of the same or a higher rank."""
    return sorted(f"{m} -> {t}" for m, targets in graph.items() for t in targets
                  if _area(m) != _area(t) and RANK[_area(m)] <= RANK[_area(t)])


def _modules() -> list[str]:
    out = []
    for f in sorted(PACKAGE.rglob("*.py")):
        parts = list(f.relative_to(PACKAGE.parent).with_suffix("").parts)
        out.append(".".join(parts[:-1] if parts[-1] == "__init__" else parts))
    return out


def _circles(graph: dict[str, set[str]]) -> list[set[str]]:
    """The strongly connected components of more than one module (Tarjan, iterative)."""
    index, low, stack, on, out, counter = {}, {}, [], set(), [], 0
    for root in graph:
        if root in index:
            continue
        work = [(root, iter(sorted(graph[root])))]
        index[root] = low[root] = counter
        counter += 1
        stack.append(root)
        on.add(root)
        while work:
            v, it = work[-1]
            w = next(it, None)
            if w is not None:
                if w not in index:
                    index[w] = low[w] = counter
                    counter += 1
                    stack.append(w)
                    on.add(w)
                    work.append((w, iter(sorted(graph[w]))))
                elif w in on:
                    low[v] = min(low[v], index[w])
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[v])
            if low[v] == index[v]:
                comp = set()
                while True:
                    w = stack.pop()
                    on.discard(w)
                    comp.add(w)
                    if w == v:
                        break
                if len(comp) > 1:
                    out.append(comp)
    return out


def test_the_import_graph_has_no_circle_but_the_known_one():
    circles = _circles(_graph())
    assert sorted(map(sorted, circles)) == sorted(map(sorted, KNOWN)), circles


def test_the_finder_sees_a_circle():
    assert _circles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [{"a", "b", "c"}]
    assert _circles({"a": {"b"}, "b": set()}) == []


def test_every_area_has_a_rank():
    areas = {_area(m) for m in _modules()}
    assert not areas - set(RANK), f"place these in LAYERS: {sorted(areas - set(RANK))}"
    assert not set(RANK) - areas, f"gone from the package, drop from LAYERS: {sorted(set(RANK) - areas)}"


def test_no_import_points_up_or_sideways():
    upward = _upward(_graph())
    assert not upward, "imports against the layer order (tests/test_import_graph.py LAYERS):\n" + "\n".join(upward)


def test_the_checker_sees_an_upward_and_a_sideways_arrow():
    graph = {"madpinn.settings": {"madpinn.simulation.mujoco.settings", "madpinn.dynamics"},
             "madpinn.marl.build": {"madpinn.value_functions.model"}, "madpinn.dynamics": set()}
    assert _upward(graph) == ["madpinn.marl.build -> madpinn.value_functions.model",
                              "madpinn.settings -> madpinn.simulation.mujoco.settings"]
