"""The library as a new user meets it (issue 34, "The library"): ``help(solve)`` names
every solver and option, ``dir(hierplan_opt)`` lists the lazy exports, networkx graphs
whose nodes are coordinates load, and result objects print in a few lines."""

from __future__ import annotations

import pydoc
import re
import subprocess
import sys
import textwrap

import networkx as nx
import pytest

import hierplan_opt as hp
from hierplan_opt import registry
from hierplan_opt.core.graph import Graph
from hierplan_opt.core.instance import Instance
from hierplan_opt.core.plan import Plan


def _words(text: str) -> str:
    return " ".join(text.split())


def solver_reference() -> str:
    """What the Solvers part of ``solve``'s docstring must say (paste it there)."""
    out: list[str] = []
    for n in registry.names():
        info = registry.get(n)
        kind = "optimal" if info.optimal else "bounded" if info.bounded else "heuristic"
        problems = "/".join(sorted(p.upper() for p in info.problems))
        out.append(f"``{n}`` ({problems}, {kind}): {info.description}.")
        out += [f"- {o.describe()}" for o in info.load().options]
    return "\n".join(out)


def test_help_of_solve_names_every_solver_and_option() -> None:
    doc = _words(pydoc.render_doc(hp.solve, renderer=pydoc.plaintext))
    missing = [line for line in solver_reference().splitlines() if _words(line) not in doc]
    assert not missing, "solve's docstring is out of date; it should list:\n" + "\n".join(
        textwrap.fill(m, 84, break_on_hyphens=False) for m in missing
    )
    assert "lacam" in doc and "anytime" in doc and "max_horizon" in doc


@pytest.mark.parametrize("name", ["load_instance", "verify", "simulate", "refine", "postprocess"])
def test_dir_lists_the_lazy_exports(name: str) -> None:
    assert name in dir(hp)
    assert name in hp.__all__
    assert callable(getattr(hp, name))


def test_lazy_exports_keep_the_import_light() -> None:
    code = (
        "import sys, hierplan_opt\n"
        "names = dir(hierplan_opt)\n"
        "print(sorted(m for m in ('hierplan_opt.execution', 'hierplan_opt.trajectory', "
        "'hierplan_opt.formulations.verify', 'casadi') if m in sys.modules))"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True, timeout=120
    )
    assert out.stdout.strip() == "[]"


def test_from_networkx_takes_coordinate_nodes() -> None:
    g = Graph.from_networkx(nx.grid_2d_graph(6, 6))
    assert (g.num_vertices, g.num_edges, g.directed) == (36, 60, False)
    assert g.coords[g.vertex((2, 3))].tolist() == [2.0, 3.0]
    inst = Instance.mapf(g, [(0, 0), (5, 5)], [(5, 5), (0, 0)])
    r = hp.solve(inst, "cbs", time_limit=10)
    assert r.status is hp.Status.OPTIMAL and r.cost == 20 and hp.validate(inst, r.plan) == []


def test_from_networkx_refuses_nodes_without_coordinates() -> None:
    with pytest.raises(hp.InputError, match="node 'a' has no 'pos' attribute and is not a tuple"):
        Graph.from_networkx(nx.Graph([("a", "b")]))


@pytest.fixture(scope="module")
def warehouse() -> tuple[Instance, hp.Result]:
    inst = hp.load_instance("instances/paper/warehouse-part1.yaml")
    res = hp.solve(inst, "cbm", time_limit=60)
    assert res.plan is not None
    return inst, res


def test_result_objects_print_short(warehouse: tuple[Instance, hp.Result]) -> None:
    inst, res = warehouse
    schedule = hp.postprocess(inst, res.plan)
    assert schedule.stn is not None
    objects = {
        "result": res,
        "plan": res.plan,
        "schedule": schedule,
        "waypoints": schedule.waypoints[0],
        "stn": schedule.stn,
        "tpg": schedule.stn.tpg,
    }
    for what, obj in objects.items():
        text = repr(obj)
        assert len(text) < 800, (what, len(text))
        assert "\n" not in text and text.startswith(type(obj).__name__ + "("), what
    text = repr(schedule)
    assert f"makespan={schedule.makespan!r}" in text
    assert re.search(r"times=<array \(\d+,\) float64>", text)
    assert "plan=Plan(<12 paths>, horizon=" in repr(res)


def test_refined_trajectories_print_short(warehouse: tuple[Instance, hp.Result]) -> None:
    inst, res = warehouse
    traj = hp.refine(inst, hp.postprocess(inst, res.plan), solver="profile+qp", stretch="auto")
    for obj in (traj, traj.robots[0], traj.windows):
        assert len(repr(obj)) < 800, type(obj).__name__
    assert f"stretch={traj.stretch!r}" in repr(traj)


def test_small_plans_still_print_in_full() -> None:
    assert repr(Plan.from_paths([[0, 1], [2]])) == "Plan(paths=((0, 1), (2,)))"
