"""No import circles in ``derivations/`` and ``codegen/`` (issue #29).

Every module is parsed with :mod:`ast` (nothing is imported), and every ``import`` and
``from ... import`` in it is read: module-level ones and those inside functions and
classes alike, since a late import inside a function only hides a circle until that
function runs.  Only explicit imports count: importing ``a.b.c`` is an edge to ``a.b.c``
(and ``from a.b import c`` to ``a.b.c`` where ``c`` is a module, else to ``a.b``), not
to the parent packages whose ``__init__`` Python runs on the way.  The test fails naming
each circle, as a path of module names.  A second test holds the code in these packages to the
modules' own names, not the old names ``derivations.MOVED`` keeps working for users (the first
test reads an old name as the module it names now), but for ``PINNED``: a module whose bytes
``generated/`` hashes into its headers.
"""
from __future__ import annotations

import ast
import importlib
from pathlib import Path

import derivations

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("derivations", "codegen")
OLD_NAMES = {f"derivations.{old}": f"derivations.{new}" for old, new in derivations.MOVED.items()}
# Modules whose bytes generated/ pins (the sha256 in its headers): they keep their old imports.
PINNED = {"derivations.robots.avr3000"}


def _modules() -> dict[str, Path]:
    modules = {}
    for package in PACKAGES:
        for path in sorted((ROOT / package).rglob("*.py")):
            parts = path.relative_to(ROOT).with_suffix("").parts
            modules[".".join(parts[:-1] if parts[-1] == "__init__" else parts)] = path
    return modules


def _targets(name: str, path: Path, modules) -> set[str]:
    """Every name ``name`` (at ``path``) imports anywhere in its body: ``a.b`` for ``import a.b``,
    ``a.b.c`` for ``from a.b import c`` where that is a module, else ``a.b``."""
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    found = set()
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            targets = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = package.split(".")[:len(package.split(".")) - node.level + 1]
                base = ".".join(anchor + ([base] if base else []))
            targets = [f"{base}.{alias.name}" if f"{base}.{alias.name}" in modules or f"{base}.{alias.name}" in OLD_NAMES
                       else base for alias in node.names]
        else:
            continue
        found.update(targets)
    return found


def import_graph() -> dict[str, set[str]]:
    modules = _modules()
    graph = {}
    for name, path in modules.items():  # an old name is an edge to the module it names now
        targets = {OLD_NAMES.get(t, t) for t in _targets(name, path, modules)}
        graph[name] = {t for t in targets if t in modules and t != name}
    return graph


def circles(graph: dict[str, set[str]]) -> list[list[str]]:
    """One circle through each strongly connected component of more than one module (Tarjan)."""
    index, low, stack, on_stack, components = {}, {}, [], set(), []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in sorted(graph[v]):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                components.append(set(component))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    found = []
    for component in components:  # a shortest way back to the first module, as a readable path
        start = min(component)
        paths = {start: [start]}
        frontier = [start]
        while frontier and start not in {w for v in frontier for w in graph[v]}:
            nxt = []
            for v in frontier:
                for w in sorted(graph[v] & component):
                    if w not in paths:
                        paths[w] = paths[v] + [w]
                        nxt.append(w)
            frontier = nxt
        last = next(v for v in frontier if start in graph[v])
        found.append(paths[last] + [start])
    return found


def test_the_circle_finder_finds_a_planted_circle():
    graph = {"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}
    assert circles(graph) == [["a", "b", "c", "a"]]
    assert circles({"a": {"b"}, "b": set()}) == []


def test_derivations_and_codegen_have_no_import_circles():
    graph = import_graph()
    assert "derivations.model" in graph and "codegen.cli" in graph  # the walk found the packages
    found = circles(graph)
    assert found == [], "import circles:\n" + "\n".join(" -> ".join(c) for c in found)


def test_the_packages_import_moved_modules_by_their_new_names():
    modules = _modules()
    old = sorted((name, t) for name, path in modules.items() if name not in PINNED
                 for t in _targets(name, path, modules) if t in OLD_NAMES)
    assert old == [], "imports through an old name (see derivations.MOVED): " + ", ".join(f"{a} imports {b}" for a, b in old)
    for name, new in derivations.MOVED.items():  # and the old names give the very modules the new ones do
        assert importlib.import_module(f"derivations.{name}") is importlib.import_module(f"derivations.{new}")
