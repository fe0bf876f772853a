"""Start-up cost: ``import hierplan_opt`` and a small MAPF solve stay light (issue 22).

Each check runs in a fresh interpreter and lists the heavy modules it ended up importing.
"""

from __future__ import annotations

import json
import subprocess
import sys

HEAVY = (
    "ortools",
    "pyomo",
    "highspy",
    "casadi",
    "matplotlib",
    "networkx",
    "scipy.optimize",
    "scipy.sparse",
)


def _heavy_after(code: str) -> list[str]:
    probe = (
        f"{code}\nimport json, sys\nprint(json.dumps([m for m in {HEAVY!r} if m in sys.modules]))"
    )
    proc = subprocess.run(
        [sys.executable, "-c", probe], capture_output=True, text=True, check=True, timeout=120
    )
    return json.loads(proc.stdout.strip().splitlines()[-1])


def test_import_loads_no_heavy_dependency() -> None:
    assert _heavy_after("import hierplan_opt") == []


def test_cli_help_loads_no_heavy_dependency() -> None:
    code = (
        "import contextlib, io\n"
        "from hierplan_opt.cli import main\n"
        "with contextlib.redirect_stdout(io.StringIO()), contextlib.suppress(SystemExit):\n"
        "    main(['--help'])"
    )
    assert _heavy_after(code) == []


def test_small_cbs_solve_loads_no_solver_backend() -> None:
    code = (
        "import hierplan_opt\n"
        "from hierplan_opt.core.graph import Graph\n"
        "from hierplan_opt.core.instance import Instance\n"
        "g = Graph.grid(6, 6, obstacles=[(2, 2), (3, 3)])\n"
        "inst = Instance.mapf(g, [(0, 0), (5, 5), (0, 5), (5, 0)], "
        "[(5, 5), (0, 0), (5, 0), (0, 5)])\n"
        "assert hierplan_opt.solve(inst, 'cbs').cost is not None"
    )
    assert _heavy_after(code) == []


def test_cli_solve_builds_only_its_own_arguments(tmp_path) -> None:
    # `hierplan solve` fills in only solve's arguments: simulate's policy choices would
    # import the execution layer (~0.1 s) for nothing.
    from pathlib import Path

    root = Path(__file__).resolve().parent.parent / "instances" / "movingai"
    code = (
        "import contextlib, io, sys\n"
        "from hierplan_opt.cli import main\n"
        "with contextlib.redirect_stdout(io.StringIO()):\n"
        f"    rc = main(['-q', 'solve', {str(root / 'random-32-32-20.map')!r}, '--scen', "
        f"{str(root / 'random-32-32-20-random-1.scen')!r}, '--agents', '4', "
        f"'--out', {str(tmp_path / 'plan.yaml')!r}])\n"
        "assert rc == 0, rc\n"
        "assert not any(m.startswith('hierplan_opt.execution') for m in sys.modules)"
    )
    assert _heavy_after(code) == []
    assert (tmp_path / "plan.yaml").is_file()


def test_python_bfs_matches_scipy_distances(monkeypatch) -> None:
    # Small batches use a Python BFS while scipy is not loaded; it must agree with scipy
    # (the reference made by scipy, also after a test that loaded the compiled BFS).
    import random

    from hierplan_opt.core import graph as graph_mod
    from hierplan_opt.core.graph import Graph

    monkeypatch.setattr(graph_mod, "_compiled_bfs", None)

    rng = random.Random(3)
    for _ in range(5):
        obstacles = {(rng.randrange(9), rng.randrange(7)) for _ in range(20)}
        g = Graph.grid(9, 7, obstacles=sorted(obstacles))
        free = [v for v in range(g.n) if g.adj[v] or g.is_vertex(v)]
        for t in rng.sample(free, 4):
            ref = Graph.grid(9, 7, obstacles=sorted(obstacles))
            ref._small_bfs = lambda count: False  # type: ignore[method-assign]
            assert graph_mod._bfs(g.adj, t) == ref.precompute_distances([t])[0].tolist()


def test_pebble_structure_without_scipy_is_the_same(monkeypatch) -> None:
    # A process without scipy loaded builds the exact feasibility test's structure with
    # Python graph routines; it must equal the scipy-built one field by field.
    import random

    import scipy.sparse.csgraph  # noqa: F401  (loaded for the reference build)

    from hierplan_opt.core.graph import Graph
    from hierplan_opt.core.pebble_motion import PebbleStructure

    fields = ("comp", "comp_size", "comps", "ecc", "ecc_members", "big", "ecc_is_cycle")
    fields += ("is_cycle_component", "_bridge_nbrs", "tparent", "order", "sub_size")
    rng = random.Random(5)
    graphs = [Graph.grid(5, 1), Graph.grid(3, 3, obstacles=[(1, 1)])]
    for _ in range(12):
        w, h = rng.randint(2, 9), rng.randint(1, 7)
        cells = [(x, y) for x in range(w) for y in range(h)]
        graphs.append(
            Graph.grid(w, h, obstacles=rng.sample(cells, rng.randint(0, len(cells) // 2)))
        )
    for g in graphs:
        ref = PebbleStructure(g)
        with monkeypatch.context() as m:
            m.delitem(sys.modules, "scipy.sparse.csgraph")
            mine = PebbleStructure(g)
        for f in fields:
            assert getattr(mine, f) == getattr(ref, f), f


def test_warehouse_ten_agent_solve_imports_no_scipy() -> None:
    # Issue 35: the 10 goal tables of a 10k-cell map (5,699 free cells) are a Python BFS
    # (about 20 ms) rather than an import of scipy.sparse.csgraph (0.15-0.5 s).
    code = (
        "import hierplan_opt\n"
        "from hierplan_opt.bench import scenario\n"
        "_, inst = scenario('warehouse-10-20-10-2-1-even-1:10')\n"
        "assert hierplan_opt.solve(inst, 'cbs').cost == 869\n"
    )
    assert _heavy_after(code) == []


def test_the_command_runs_one_openblas_thread_and_the_library_keeps_its_own() -> None:
    # numpy's OpenBLAS worker spins after start-up; the `hierplan` command (its console
    # script's argv[0]) starts with one thread, a program importing the library decides.
    probe = (
        "import sys, os; sys.argv[0] = {argv!r}; os.environ.pop('OPENBLAS_NUM_THREADS', None)"
        "{extra}; import hierplan_opt, numpy, threading;"
        "print(os.environ.get('OPENBLAS_NUM_THREADS'), len(os.listdir('/proc/self/task')))"
    )

    def run(argv: str, extra: str = "") -> list[str]:
        code = probe.format(argv=argv, extra=extra)
        out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
        assert out.returncode == 0, out.stderr
        return out.stdout.split()

    command = run("/venv/bin/hierplan")
    assert command == ["1", "1"]  # one thread in the process: no BLAS worker
    library = run("notebook.py")
    assert library[0] == "None"
    assert run("/venv/bin/hierplan", "; os.environ['OPENBLAS_NUM_THREADS'] = '2'")[0] == "2"
