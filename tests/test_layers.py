"""The layer contract of hierplan_opt (issue 31), checked over the import graph.

Layers, from the bottom up (a module may import its own part of the package and any
part of a lower layer; parts that share a layer do not import each other)::

    core <- io <- registry <- search, formulations <- api <- schedule
         <- trajectory, physics <- execution <- lifelong <- experiments, viz <- bench
         <- cli <- the package root (hierplan_opt/__init__.py) and __main__

``api`` (``hierplan_opt.solve``, the checked solve) sits just above the solvers: it
routes annotated roadmaps and task-free robots to ``search.libmrp``, and every layer
above (execution's re-planning, experiments, bench, cli) calls it. ``physics`` is the
MuJoCo plant that execution's closed loop drives (``simulate(mode="physics")``): it
needs only core, io and the schedule, so it sits below execution, beside trajectory,
and execution loads it inside a function (a heavy module: MuJoCo). The package root is
the front door for users: it re-exports (lazily) from every layer, so it is the top
and no module of the package imports it (they import the module that defines a name).

Every import counts: at the top, inside a function and under ``TYPE_CHECKING`` (see
tests/import_graph.py). ``search/`` is checked by its own tests so that its circles,
being untangled on another branch, are reported apart from the rest.
"""

from __future__ import annotations

import ast
import functools
from pathlib import Path

from import_graph import (
    Edge,
    circle_text,
    cycles,
    import_graph,
    layer_violations,
    modules,
    peer_imports,
    private_imports,
)

import hierplan_opt
from hierplan_opt import registry

PACKAGE = Path(hierplan_opt.__file__).resolve().parent

LAYERS = [
    {"core"},
    {"io"},
    {"registry"},
    {"search", "formulations"},
    {"api"},
    {"schedule"},
    {"trajectory", "physics"},
    {"execution"},
    {"lifelong"},
    {"experiments", "viz"},
    {"bench"},
    {"cli"},
    {"", "__main__"},
]


@functools.cache
def _edges() -> tuple[Edge, ...]:
    return tuple(import_graph(PACKAGE))


def _in_search(text: str) -> bool:
    return text.startswith("hierplan_opt.search.") or text.startswith("hierplan_opt.search ")


def test_every_part_of_the_package_is_in_a_layer() -> None:
    parts = {p.stem if p.is_file() else p.name for p in PACKAGE.iterdir()}
    parts = {p for p in parts if not p.startswith((".", "_")) or p == "__main__"}
    parts -= {"__init__", "data"}
    parts = {p for p in parts if (PACKAGE / p).is_dir() or (PACKAGE / f"{p}.py").is_file()}
    placed = set().union(*LAYERS)
    assert parts - placed == set()


def test_no_import_points_up_or_sideways_outside_search() -> None:
    edges = _edges()
    bad = [v for v in layer_violations(edges, LAYERS) if not _in_search(v)]
    assert bad == [], "\n".join(bad)


def test_no_import_points_up_or_sideways_from_search() -> None:
    # search -> formulations (the min-cut highway generator) was one (issue 31).
    edges = _edges()
    bad = [v for v in layer_violations(edges, LAYERS) if _in_search(v)]
    assert bad == [], "\n".join(bad)


def test_no_part_imports_another_parts_private_module() -> None:
    # e.g. io/_yaml was read from seven places outside io; it is the public io/yaml now
    assert private_imports(_edges()) == []


def test_no_import_circle_outside_search() -> None:
    edges = _edges()
    bad = [c for c in cycles(edges) if not all(_in_search(m + ".") for m in c)]
    assert bad == [], "\n".join(circle_text(c, edges) for c in bad)


def test_no_import_circle_in_search() -> None:
    # search/jit <-> reservations and cbs/ecbs/eecbs/highways were two (issue 31).
    edges = _edges()
    bad = [c for c in cycles(edges) if all(_in_search(m + ".") for m in c)]
    assert bad == [], "\n".join(circle_text(c, edges) for c in bad)


def _solver_modules() -> set[str]:
    return {registry.get(n).target.split(":")[0] for n in registry.names()}


def test_no_solver_module_imports_another() -> None:
    # ecbs imported cbs's engine, eecbs ecbs's, lacam pibt's, cbm and flow hungarian's
    # module (issue 31): the engines are library modules now (cbs_engine, ...).
    solvers = _solver_modules()
    assert {"hierplan_opt.search.cbs", "hierplan_opt.formulations.mip"} <= solvers
    assert peer_imports(_edges(), solvers) == []


# ------------------------------------------------------------- the checker itself
def _tree(root: Path, files: dict[str, str]) -> Path:
    pkg = root / "pkg"
    for rel, text in files.items():
        path = pkg / rel
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text)
    for d in [pkg, *(p for p in pkg.rglob("*") if p.is_dir())]:
        (d / "__init__.py").touch()
    return pkg


def test_checker_reports_a_planted_upward_import_and_a_circle(tmp_path: Path) -> None:
    pkg = _tree(
        tmp_path,
        {
            "core/a.py": "def f():\n    from pkg.io import b  # planted: core -> io\n",
            "io/b.py": "from pkg.core.a import f\n",
            "io/c.py": (
                "from typing import TYPE_CHECKING\n"
                "from . import d\n"
                "if TYPE_CHECKING:\n    from pkg.io.e import E\n"
            ),
            "io/d.py": "import pkg.io.e\n",
            "io/e.py": "def g():\n    from .c import x\n",
            "cli/main.py": "import pkg.io.b\nfrom pkg import core\n",
        },
    )
    edges = import_graph(pkg)
    kinds = {(e.importer, e.imported): e.kind for e in edges}
    assert kinds[("pkg.core.a", "pkg.io.b")] == "function"
    assert kinds[("pkg.io.c", "pkg.io.e")] == "type"
    assert kinds[("pkg.io.c", "pkg.io.d")] == "top"  # relative `from . import d`
    assert kinds[("pkg.io.e", "pkg.io.c")] == "function"  # relative `from .c import x`
    assert kinds[("pkg.cli.main", "pkg.core")] == "top"

    layers = [{"core"}, {"io"}, {"cli"}]
    bad = layer_violations(edges, layers)
    assert bad == ["pkg.core.a -> pkg.io.b (line 2, function): upward (core is below io)"]
    assert layer_violations(edges, [{"core"}, {"io", "cli"}]) == [
        "pkg.cli.main -> pkg.io.b (line 1, top): sideways (cli and io share a layer)",
        "pkg.core.a -> pkg.io.b (line 2, function): upward (core is below io)",
    ]
    assert "is in no layer" in layer_violations(edges, [{"core"}, {"io"}])[0]
    assert private_imports(edges) == []
    (pkg / "io" / "_helpers.py").write_text("")
    (pkg / "cli" / "main.py").write_text("from pkg.io._helpers import x\nfrom pkg.io import b\n")
    (pkg / "io" / "f.py").write_text("from pkg.io import _helpers\n")  # its own part: fine
    assert private_imports(import_graph(pkg)) == [
        "pkg.cli.main -> pkg.io._helpers (line 1, top): private to io"
    ]

    assert peer_imports(edges, ["pkg.io.b", "pkg.io.c", "pkg.cli.main"]) == [
        "pkg.cli.main -> pkg.io.b (line 1, top): both are solver modules"
    ]

    found = cycles(edges)
    assert found == [
        ["pkg.core.a", "pkg.io.b"],  # the planted upward import closes a circle too
        ["pkg.io.c", "pkg.io.d", "pkg.io.e"],  # through a type-only and a function import
    ]
    assert circle_text(found[1], edges) == (
        "pkg.io.c -> pkg.io.e (line 4 of pkg.io.c, type) -> pkg.io.c (line 2 of pkg.io.e, function)"
    )


def test_checker_is_quiet_on_a_clean_tree(tmp_path: Path) -> None:
    pkg = _tree(
        tmp_path,
        {
            "core/a.py": "import os\nimport numpy\n",
            "io/b.py": "from pkg.core import a\nfrom pkg.core.a import x\n",
            "cli/main.py": "from pkg.io.b import y\n",
        },
    )
    edges = import_graph(pkg)
    assert len(edges) == 3  # other distributions are not edges
    assert layer_violations(edges, [{"core"}, {"io"}, {"cli"}]) == []
    assert cycles(edges) == []


def test_imports_inside_functions_say_why_outside_the_command_layers() -> None:
    """An import of the package inside a function hides a circle unless it saves start-up
    time (issue 31): outside ``cli`` and ``bench`` (where each command loads its own code
    when it runs) every such import carries a comment on its line or the two above that
    says why (a heavy module, a format's reader loaded on use, ...)."""
    files = modules(PACKAGE)
    bare = []
    for e in _edges():
        if e.kind != "function" or e.importer.split(".")[1:2] in (["cli"], ["bench"]):
            continue
        lines = files[e.importer].read_text().splitlines()
        if not any("#" in line for line in lines[max(0, e.line - 3) : e.line]):
            bare.append(str(e))
    assert not bare, bare


def _other_imports_in_functions() -> list[tuple[str, int, str]]:
    """Imports of other distributions (numpy, matplotlib, the standard library) inside
    a function, outside ``cli`` and ``bench``: ``(file, line, module)``."""
    out = []
    for name, path in modules(PACKAGE).items():
        if name.split(".")[1:2] in (["cli"], ["bench"]):
            continue
        tree = ast.parse(path.read_text())
        for fn in ast.walk(tree):
            if not isinstance(fn, (ast.FunctionDef, ast.AsyncFunctionDef)):
                continue
            for node in ast.walk(fn):
                if isinstance(node, ast.ImportFrom) and not node.level:
                    mod = node.module or ""
                elif isinstance(node, ast.Import):
                    mod = node.names[0].name
                else:
                    continue
                if not mod.startswith("hierplan_opt"):
                    out.append((str(path), node.lineno, mod))
    return sorted(set(out))


def test_imports_of_other_packages_inside_functions_say_why() -> None:
    """The same rule for numpy, matplotlib, the standard library, ...: inside a function
    only with a reason on the line or the two above (``# heavy module: matplotlib``;
    issue 31 found 97 without one, many of them light modules that save nothing)."""
    found = _other_imports_in_functions()
    assert any(mod.startswith("matplotlib") for _, _, mod in found)  # the scan sees them
    bare = []
    for file, line, mod in found:
        lines = Path(file).read_text().splitlines()
        if not any("#" in text for text in lines[max(0, line - 3) : line]):
            bare.append(f"{file}:{line}: {mod}")
    assert not bare, bare
