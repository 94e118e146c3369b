"""The package's import graph has no circle (issue 48 point 3): every import, module-level or
inside a function, as :mod:`madpinn.provenance` reads it. The one circle left is listed here and
must go, not grow: the MuJoCo backend registers itself with the backend registry that imports it
by name (``simulation/backend.py::_load_optional_backends``)."""

from __future__ import annotations

from madpinn.provenance import PACKAGE, imports

KNOWN = [{"madpinn.simulation.backend", "madpinn.simulation.mujoco"}]
"""circles not yet removed (issue 48); a new one fails, and so does a removed one left listed"""


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
    modules = _modules()
    graph = {m: {e.partition(":")[0] for e in imports(m) if not e.endswith(":")} & set(modules) - {m} for m in modules}
    circles = _circles(graph)
    assert sorted(map(sorted, circles)) == sorted(map(sorted, KNOWN)), circles


def test_the_finder_sees_a_circle():
    assert _circles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [{"a", "b", "c"}]
    assert _circles({"a": {"b"}, "b": set()}) == []
