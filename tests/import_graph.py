"""The import graph of a package, read with ``ast`` (nothing is imported), and the checks
of its layer contract: no arrow points up or sideways between layers, no module circle.

Every ``import`` / ``from ... import`` statement counts, wherever it stands: at the top,
inside a function (an import there still ties the two modules together; it only
delays the load) and inside ``if TYPE_CHECKING:`` (a type is a dependency too: an
upward type import says the lower layer knows about the upper one, and a circle
through types is still a circle a reader has to untangle). An edge is kept with its
kind (``top``, ``function``, ``type``) so a report says where it stands.

``from pkg.sub import name`` is an edge to ``pkg.sub.name`` when that is a module,
else to ``pkg.sub``; relative imports are resolved; imports of other distributions
are ignored. Importing a submodule also runs its parents' ``__init__``; that implicit
step is not an edge (as in import-linter/grimp).
"""

from __future__ import annotations

import ast
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path


@dataclass(frozen=True)
class Edge:
    """``importer`` imports ``imported`` at ``line``; ``kind``: top, function or type."""

    importer: str
    imported: str
    line: int
    kind: str

    def __str__(self) -> str:
        return f"{self.importer} -> {self.imported} (line {self.line}, {self.kind})"


def modules(package_dir: Path) -> dict[str, Path]:
    """Dotted module name -> file, for every ``.py`` file under ``package_dir``."""
    out: dict[str, Path] = {}
    for path in sorted(package_dir.rglob("*.py")):
        parts = list(path.relative_to(package_dir.parent).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts.pop()
        out[".".join(parts)] = path
    return out


def _is_type_checking(test: ast.expr) -> bool:
    return (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING") or (
        isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING"
    )


def import_graph(package_dir: Path) -> list[Edge]:
    """Every import between the package's own modules (see the module doc)."""
    mods = modules(package_dir)
    root = package_dir.name

    def known(name: str) -> str:
        while name not in mods:
            name = name.rpartition(".")[0]
        return name

    edges: list[Edge] = []
    for name, path in mods.items():
        is_package = path.name == "__init__.py"

        def targets(node: ast.Import | ast.ImportFrom, name: str = name, pkg: bool = is_package):
            if isinstance(node, ast.Import):
                return [a.name for a in node.names]
            if node.level:
                base = name.split(".") if pkg else name.split(".")[:-1]
                base = base[: len(base) - (node.level - 1)]
                module = ".".join([*base, *([node.module] if node.module else [])])
            else:
                module = node.module or ""
            return [
                f"{module}.{a.name}" if f"{module}.{a.name}" in mods else module for a in node.names
            ]

        def visit(node: ast.AST, kind: str, name: str = name) -> None:
            for child in ast.iter_child_nodes(node):
                child_kind = kind
                if isinstance(child, ast.FunctionDef | ast.AsyncFunctionDef | ast.Lambda):
                    child_kind = "function" if kind == "top" else kind
                if isinstance(child, ast.Import | ast.ImportFrom):
                    for target in targets(child):
                        if target.split(".")[0] == root:
                            edges.append(Edge(name, known(target), child.lineno, kind))
                if isinstance(child, ast.If) and _is_type_checking(child.test):
                    for stmt in child.body:
                        visit(ast.Module(body=[stmt], type_ignores=[]), "type")
                    for stmt in child.orelse:
                        visit(ast.Module(body=[stmt], type_ignores=[]), kind)
                    continue
                visit(child, child_kind)

        visit(ast.parse(path.read_text(encoding="utf-8"), str(path)), "top")
    return edges


def component(module: str) -> str:
    """The part of the package a module belongs to: ``pkg.io.files`` -> ``io``,
    ``pkg.api`` -> ``api``, ``pkg`` itself -> ``""``."""
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else ""


def layer_violations(edges: Iterable[Edge], layers: Sequence[Iterable[str]]) -> list[str]:
    """Edges that point to a higher layer, or between two parts of one layer.

    ``layers`` lists the components from the bottom up; parts that share a layer are
    independent of each other. A component in no layer is itself a violation.
    """
    rank = {c: i for i, layer in enumerate(layers) for c in layer}
    out: list[str] = []
    for e in edges:
        a, b = component(e.importer), component(e.imported)
        if a == b:
            continue
        for c in (a, b):
            if c not in rank:
                out.append(f"{e}: {c or '(package root)'!r} is in no layer")
                break
        else:
            if rank[b] > rank[a]:
                out.append(f"{e}: upward ({a or 'root'} is below {b or 'root'})")
            elif rank[b] == rank[a]:
                out.append(f"{e}: sideways ({a} and {b} share a layer)")
    return sorted(set(out))


def private_imports(edges: Iterable[Edge]) -> list[str]:
    """Imports of another part's private module (``pkg.io._yaml`` from ``pkg.cli``): a
    module whose name starts with ``_`` serves its own part only."""
    out = []
    for e in edges:
        last = e.imported.rsplit(".", 1)[-1]
        private = last.startswith("_") and not last.startswith("__")
        if private and component(e.importer) != component(e.imported):
            out.append(f"{e}: private to {component(e.imported)}")
    return sorted(set(out))


def peer_imports(edges: Iterable[Edge], peers: Iterable[str]) -> list[str]:
    """Imports of one of ``peers`` (e.g. the modules that define a registered solver)
    by another: peers reach each other through something else (the registry)."""
    group = set(peers)
    out = [
        f"{e}: both are solver modules"
        for e in edges
        if e.importer in group and e.imported in group and e.importer != e.imported
    ]
    return sorted(set(out))


def cycles(edges: Iterable[Edge]) -> list[list[str]]:
    """The module circles: each strongly connected set of two or more modules (or a
    module that imports itself), sorted, with one concrete circle through it."""
    graph: dict[str, set[str]] = {}
    for e in edges:
        graph.setdefault(e.importer, set()).add(e.imported)
        graph.setdefault(e.imported, set())
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[list[str]] = []

    def strongconnect(v: str) -> None:  # Tarjan; the graph has a few hundred nodes
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in sorted(graph[v]):
            if w not in index:
                strongconnect(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp: list[str] = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1 or v in graph[v]:
                found.append(sorted(comp))

    for v in sorted(graph):
        if v not in index:
            strongconnect(v)
    return sorted(found)


def circle_text(comp: list[str], edges: Iterable[Edge]) -> str:
    """A circle through ``comp`` written as ``a -> b (line, kind) -> ... -> a``."""
    members = set(comp)
    out: dict[str, list[Edge]] = {}
    for e in edges:
        if e.importer in members and e.imported in members:
            out.setdefault(e.importer, []).append(e)
    start = comp[0]
    # breadth-first back to start
    prev: dict[str, Edge] = {}
    frontier = [start]
    while frontier and start not in prev:
        nxt: list[str] = []
        for v in frontier:
            for e in sorted(out.get(v, []), key=lambda e: (e.imported, e.line)):
                if e.imported not in prev:
                    prev[e.imported] = e
                    nxt.append(e.imported)
        frontier = nxt
    steps: list[Edge] = []
    v = start
    while True:
        e = prev[v]
        steps.append(e)
        v = e.importer
        if v == start:
            break
    steps.reverse()
    return " -> ".join(
        [start, *(f"{e.imported} (line {e.line} of {e.importer}, {e.kind})" for e in steps)]
    )
