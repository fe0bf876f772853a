"""Graph, Instance, Plan, Result, registry and the solve() front door."""

from __future__ import annotations

import math

import networkx as nx
import numpy as np
import pytest

import hierplan_opt as hp
from hierplan_opt import Graph, InputError, Instance, Kinematics, OptionError, Plan
from hierplan_opt.core.feasibility import quick_infeasibility
from hierplan_opt.core.graph import UNREACHABLE
from hierplan_opt.core.plan import path_cost
from hierplan_opt.core.result import Result, Status
from hierplan_opt.core.timer import Deadline


@pytest.fixture(autouse=True)
def _uncompiled_distance_tables(monkeypatch: pytest.MonkeyPatch) -> None:
    # These tests are about the tables made without the compiled BFS, which an earlier
    # test that loaded the kernels would otherwise have switched on for the process
    # (tests/test_jit_astar.py checks the compiled tables).
    from hierplan_opt.core import graph as graph_mod

    monkeypatch.setattr(graph_mod, "_compiled_bfs", None)


# ---------------------------------------------------------------- graphs
def test_grid_ids_coordinates_and_edges() -> None:
    g = Graph.grid(4, 3, obstacles=[(1, 1)])
    assert g.n == 12 and g.num_vertices == 11
    assert g.vertex((3, 2)) == 11 and g.location(11) == (3, 2)
    # 4-connected: horizontal 3*3 + vertical 4*2 = 17 edges, minus 4 touching (1, 1)
    assert g.num_edges == 13
    assert not g.has_edge(g.vertex((1, 0)), g.vertex((1, 1)))
    assert g.has_edge(g.vertex((0, 0)), g.vertex((1, 0)))
    assert g.adj[g.vertex((1, 1))] == []


def test_grid_3d_is_six_connected() -> None:
    g = Graph.grid(3, 3, 3)
    centre = g.vertex((1, 1, 1))
    assert sorted(g.location(u) for u in g.neighbors(centre)) == sorted(
        [(0, 1, 1), (2, 1, 1), (1, 0, 1), (1, 2, 1), (1, 1, 0), (1, 1, 2)]
    )
    assert g.dist(g.vertex((0, 0, 0)), g.vertex((2, 2, 2))) == 6


def test_grid_from_blocked_array_matches_obstacles() -> None:
    blocked = np.zeros((3, 4), dtype=bool)
    blocked[1, 2] = True  # [y, x]
    a = Graph.grid(4, 3, blocked=blocked)
    b = Graph.grid(4, 3, obstacles=[(2, 1)])
    assert np.array_equal(a.passable, b.passable)
    assert np.array_equal(a.indices, b.indices)


def test_distances_match_networkx_bfs() -> None:
    rng = np.random.default_rng(3)
    blocked = rng.random((9, 11)) < 0.25
    g = Graph.grid(11, 9, blocked=blocked)
    G = nx.Graph(list(g.edges()))
    target = next(v for v in range(g.n) if g.passable[v] and v in G)
    ref = nx.single_source_shortest_path_length(G, target)
    d = g.dist_to(target)
    for v in range(g.n):
        assert d[v] == ref.get(v, UNREACHABLE)
    assert g.dist_list(target) == d.tolist()


def test_directed_roadmap_distances_go_towards_target() -> None:
    g = Graph.roadmap({"A": (0, 0), "B": (1, 0), "C": (2, 0)}, [("A", "B"), ("B", "C")],
                      directed=True)  # fmt: skip
    a, c = g.vertex("A"), g.vertex("C")
    assert g.dist(a, c) == 2
    assert g.dist(c, a) == UNREACHABLE


def test_roadmap_lengths_and_networkx() -> None:
    G = nx.Graph()
    G.add_node("p", pos=(0.0, 0.0))
    G.add_node("q", pos=(3.0, 4.0))
    G.add_node("r", pos=(3.0, 0.0))
    G.add_edge("p", "q")
    G.add_edge("q", "r", length=7.5)
    g = Graph.from_networkx(G)
    assert g.edge_length(g.vertex("p"), g.vertex("q")) == 5.0
    assert g.edge_length(g.vertex("r"), g.vertex("q")) == 7.5
    assert g.edge_length(g.vertex("r"), g.vertex("r")) == 0.0
    with pytest.raises(InputError, match="not an edge"):
        g.edge_length(g.vertex("p"), g.vertex("r"))


def test_grid_positions_scale_with_cell_size() -> None:
    g = Graph.grid(3, 2, cell_size=0.5)
    assert list(g.position(g.vertex((2, 1)))) == [1.0, 0.5]
    assert g.edge_length(0, 1) == 0.5


@pytest.mark.parametrize(
    ("call", "message"),
    [
        (lambda: Graph.grid(0, 3), "positive integers"),
        (lambda: Graph.grid(3, 3, obstacles=[(3, 0)]), "outside"),
        (lambda: Graph.grid(3, 3, cell_size=-1.0), "cell_size"),
        (lambda: Graph.grid(3, 3, cell_size=math.nan), "cell_size"),
        (lambda: Graph.roadmap({"A": (0, 0)}, [("A", "B")]), "unknown vertex 'B'"),
        (lambda: Graph.roadmap({"A": (0, 0), "B": (1, 0)}, [("A", "B", -2)]), "bad length"),
        (lambda: Graph.roadmap({"A": (0, 0), "B": (1, 0)}, [("A", "A")]), "self-loop"),
        (lambda: Graph.roadmap({"A": (0, math.nan)}, []), "not finite"),
        (
            lambda: Graph.roadmap({"A": (0, 0), "B": (1, 0)}, [("A", "B"), ("B", "A")]),
            "listed twice",
        ),
        (lambda: Graph.grid(3, 3).vertex((1, 5)), "outside the 3x3 map"),
        (lambda: Graph.grid(3, 3).vertex((1.5, 1)), "non-integer"),
    ],
)
def test_graph_bad_input(call, message: str) -> None:  # type: ignore[no-untyped-def]
    with pytest.raises(InputError, match=message):
        call()


# ---------------------------------------------------------------- instances
def test_instance_lower_bounds() -> None:
    g = Graph.grid(5, 2, obstacles=[(0, 1), (1, 1), (3, 1), (4, 1)])
    inst = Instance.mapf(g, [(0, 0), (1, 0)], [(4, 0), (3, 0)])
    assert inst.soc_lower_bound() == 6 and inst.makespan_lower_bound() == 4
    assert inst.goals == [4, 3] and not inst.is_tapf


def test_tapf_lower_bounds_use_nearest_target() -> None:
    g = Graph.grid(5, 1)
    inst = Instance.tapf(g, [([(0, 0), (1, 0)], [(3, 0), (4, 0)])])
    # each robot's nearest target is (3, 0): 3 + 2; target (4, 0) needs >= 3 steps
    assert inst.soc_lower_bound() == 5 and inst.makespan_lower_bound() == 3
    assert inst.goal_set(0) == (3, 4)


@pytest.mark.parametrize(
    ("build", "message"),
    [
        (
            lambda g: Instance.mapf(g, [(1, 1)], [(0, 0)]),
            r"start of agent 'agent0' \[1, 1\] "
            "is on an obstacle",
        ),
        (lambda g: Instance.mapf(g, [(0, 0)], [(1, 1)]), "goal of agent 'agent0'.*obstacle"),
        (lambda g: Instance.mapf(g, [(0, 0), (0, 0)], [(2, 0), (0, 2)]), "share the start"),
        (lambda g: Instance.mapf(g, [(5, 0)], [(0, 0)]), "outside the 3x3 map"),
        (lambda g: Instance.mapf(g, [(0, 0)], [(2, 0), (0, 2)]), "1 starts but 2 goals"),
        (lambda g: Instance.mapf(g, [], []), "no agents"),
        (lambda g: Instance.tapf(g, [([(0, 0), (2, 0)], [(0, 2)])]), "2 robots but 1 targets"),
        (
            lambda g: Instance.tapf(g, [([(0, 0)], [(0, 2)]), ([(2, 0)], [(0, 2)])]),
            "given to both team",
        ),
        (
            lambda g: Instance.mapf(
                g, [(0, 0)], [(2, 0)], names=["a"], highways=[((0, 0), (2, 0))]
            ),
            "not an edge",
        ),
    ],
)
def test_instance_bad_input(build, message: str) -> None:  # type: ignore[no-untyped-def]
    g = Graph.grid(3, 3, obstacles=[(1, 1)])
    with pytest.raises(InputError, match=message):
        build(g)


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"v_max": 0.0}, "v_max must be a positive"),
        ({"v_max": -1.0}, "v_max must be a positive"),
        ({"v_max": math.nan}, "v_max must be a positive"),
        ({"v_max": math.inf}, "v_max must be a positive"),
        ({"drive": "differential"}, "needs omega_max"),
        ({"drive": "differential", "omega_max": -2.0}, "omega_max must be a positive"),
        ({"a_max": 0.0}, "a_max must be a positive"),
        ({"radius": -0.1}, "radius"),
        ({"drive": "tracked"}, "drive must be one of"),
    ],
)
def test_kinematics_bad_input(kwargs: dict, message: str) -> None:
    with pytest.raises(InputError, match=message):
        Kinematics(**kwargs)


def test_with_goals_and_subset() -> None:
    g = Graph.grid(4, 4)
    tapf = Instance.tapf(g, [([(0, 0), (3, 3)], [(0, 3), (3, 0)])])
    fixed = tapf.with_goals([g.vertex((3, 0)), g.vertex((0, 3))])
    assert not fixed.is_tapf and fixed.goals == [3, 12]
    assert fixed.subset(1).num_agents == 1
    with pytest.raises(InputError, match="1..2"):
        fixed.subset(3)


def test_quick_infeasibility() -> None:
    g = Graph.grid(3, 3, obstacles=[(1, 0), (1, 1), (1, 2)])  # a wall splits the grid
    assert "cannot reach" in (quick_infeasibility(Instance.mapf(g, [(0, 0)], [(2, 2)])) or "")
    two = Instance.mapf(g, [(0, 0), (0, 2)], [(0, 1), (0, 1)])
    assert "share the goal" in (quick_infeasibility(two) or "")
    team = Instance.tapf(g, [([(0, 0), (0, 1)], [(0, 2), (2, 2)])])
    assert "no assignment" in (quick_infeasibility(team) or "")
    ok = Instance.tapf(g, [([(0, 0), (2, 1)], [(0, 2), (2, 2)])])
    assert quick_infeasibility(ok) is None


# ---------------------------------------------------------------- plans, results
def test_plan_costs_ignore_trailing_waits_only() -> None:
    assert path_cost([4]) == 0
    assert path_cost([1, 1, 1]) == 0
    assert path_cost([1, 2, 2, 3, 3]) == 3
    assert path_cost([1, 2, 1, 1]) == 2  # leaves and comes back: counts
    p = Plan.from_paths([[0, 1, 1], [5, 6, 7, 7, 7]])
    assert p.costs == (1, 2) and p.sum_of_costs == 3 and p.makespan == 2
    assert p.cost("soc") == 3 and p.cost("makespan") == 2
    assert p.trimmed().paths == ((0, 1), (5, 6, 7))
    with pytest.raises(ValueError, match="unknown objective"):
        p.cost("energy")


def test_result_gap() -> None:
    r = Result(Status.FEASIBLE, Plan.from_paths([[0, 1]]), cost=12, lower_bound=10)
    assert r.solved and r.gap == pytest.approx((12 - 10) / 12)  # (cost - bound) / cost
    assert Result(Status.TIME_LIMIT, None, lower_bound=10).gap is None


def test_deadline() -> None:
    assert not Deadline(None).expired()
    assert Deadline(0.0).expired()
    with pytest.raises(OptionError):
        Deadline(-1.0)


# ---------------------------------------------------------------- registry, front door
def test_unknown_solver_names_the_known_ones() -> None:
    g = Graph.grid(2, 1)
    inst = Instance.mapf(g, [(0, 0)], [(1, 0)])
    with pytest.raises(hp.UnknownSolverError, match="unknown solver 'astar2'.*cbs"):
        hp.solve(inst, "astar2")


def test_front_door_refuses_bad_objective_and_time_limit() -> None:
    g = Graph.grid(2, 1)
    inst = Instance.mapf(g, [(0, 0)], [(1, 0)])
    with pytest.raises(OptionError, match="unknown objective 'energy'"):
        hp.solve(inst, "cbs", cost="energy")
    with pytest.raises(OptionError, match="time_limit"):
        hp.solve(inst, "cbs", time_limit=-3)
    with pytest.raises(OptionError, match="time_limit"):
        hp.solve(inst, "cbs", time_limit=math.nan)


def test_front_door_refuses_unknown_option() -> None:
    g = Graph.grid(2, 1)
    inst = Instance.mapf(g, [(0, 0)], [(1, 0)])
    with pytest.raises(OptionError, match="solver 'cbs' has no option 'frobnicate'"):
        hp.solve(inst, "cbs", frobnicate=True)


def test_front_door_turns_an_invalid_plan_into_error(monkeypatch: pytest.MonkeyPatch) -> None:
    from hierplan_opt import registry

    def broken(instance, *, time_limit=None, seed=0, objective="soc"):  # type: ignore[no-untyped-def]
        return Result(Status.OPTIMAL, Plan.from_paths([[a.start] for a in instance.agents]), 0)

    registry.register("broken", "x:y", objectives={"soc"}, optimal=True)
    registry.get("broken")._fn.append(broken)
    try:
        g = Graph.grid(3, 1)
        inst = Instance.mapf(g, [(0, 0)], [(2, 0)])
        r = hp.solve(inst, "broken")
        assert r.status is Status.ERROR and r.plan is None
        assert "wrong_goal" in r.stats["violations"][0]
    finally:
        registry._REGISTRY.pop("broken")


def test_registry_lists_every_issue_solver() -> None:
    from hierplan_opt import registry

    for name in ["cbs", "ecbs", "cbm", "flow", "mip", "cpsat"]:
        assert name in registry.names()
    assert registry.get("cbm").problems == {"mapf", "tapf"}


def test_one_team_solver_refuses_several_teams() -> None:
    g = Graph.grid(3, 3)
    inst = Instance.tapf(g, [([(0, 0)], [(2, 2)]), ([(2, 0)], [(0, 2)])])
    with pytest.raises(OptionError, match="solver 'flow' solves anonymous MAPF.*2 teams"):
        hp.solve(inst, "flow")
    with pytest.raises(OptionError, match="does not solve MAPF"):
        hp.solve(Instance.mapf(g, [(0, 0)], [(2, 2)]), "flow")


def grids_and_digraphs(
    rng: np.random.Generator, wh: tuple[int, int], p: float, k: int, va: tuple[int, int]
) -> list[Graph]:
    """``k`` grids ``wh`` with cells blocked at rate ``p`` (walled-off parts happen),
    then ``k`` directed roadmaps of ``va[0]`` vertices and up to ``va[1]`` random arcs."""
    w, h = wh
    graphs = [Graph.grid(w, h, blocked=rng.random((h, w)) < p) for _ in range(k)]
    nv, na = va
    for _ in range(k):
        pts = {f"v{i}": (float(i), 0.0) for i in range(nv)}
        arcs = {(f"v{a}", f"v{b}") for a, b in rng.integers(0, nv, (na, 2)) if a != b}
        graphs.append(Graph.roadmap(pts, sorted(arcs), directed=True))
    return graphs


def test_bfs_levels_equal_scipy_shortest_paths() -> None:
    # The distance tables come from a breadth-first order and its predecessors; they must
    # equal scipy's unweighted shortest paths, on grids with walled-off parts and on
    # directed roadmaps (towards the target: the reversed graph).
    from scipy.sparse.csgraph import shortest_path

    from hierplan_opt.core.graph import _bfs_levels

    rng = np.random.default_rng(5)
    for g in grids_and_digraphs(rng, (13, 8), 0.35, 4, (30, 45)):
        ref = shortest_path(g._csgraph, directed=True, unweighted=True)
        ref = np.where(np.isfinite(ref), ref, UNREACHABLE).astype(np.int64)
        for s in range(g.n):
            assert _bfs_levels(g._csgraph, s).tolist() == ref[s].tolist()
        if g.directed:  # the tables towards each target: BFS on the reversed graph
            g.fill_distances(range(g.n))
            for t in range(g.n):
                assert g.dist_to(t).tolist() == ref[:, t].tolist()


@pytest.mark.parametrize("way", ["python", "batch", "levels"])
def test_distance_table_ways_agree(way: str, monkeypatch: pytest.MonkeyPatch) -> None:
    # fill_distances makes a table by a Python BFS (small graphs), one scipy call per
    # batch (mid-sized) or a breadth-first order per target (large): each way, forced
    # here on small graphs, must give the same tables, as arrays and as lists.
    import scipy.sparse.csgraph  # noqa: F401  (the choice depends on it being loaded)

    from hierplan_opt.core import graph as graph_mod

    monkeypatch.setattr(graph_mod, "SMALL_BFS_CELLS", 10**9 if way == "python" else 0)
    monkeypatch.setattr(graph_mod, "DIST_BATCH_CELLS", 10**9 if way == "batch" else 0)
    rng = np.random.default_rng(11)
    for g in grids_and_digraphs(rng, (11, 7), 0.3, 3, (25, 40)):
        radj = g.reverse_adj  # distances *to* t: a BFS from t over the reversed arcs
        targets = [int(t) for t in rng.choice(g.n, 6, replace=False)]
        g.fill_distances(targets)
        for t in targets:
            ref = graph_mod._bfs(radj, t)
            assert g.dist_list(t) == ref
            assert g.dist_to(t).tolist() == ref
            assert not g.dist_to(t).flags.writeable


def test_grid_xy_only_for_four_connected_grids() -> None:
    g = Graph.grid(4, 3, obstacles=[(1, 1)])
    w, xs, ys = g.grid_xy
    assert w == 4 and all(g.location(v) == (xs[v], ys[v]) for v in range(g.n))
    assert Graph.grid(3, 3, 1).grid_xy is not None and Graph.grid(3, 3, 2).grid_xy is None
    assert Graph.roadmap({"A": (0, 0), "B": (1, 0)}, [("A", "B")]).grid_xy is None

    def by_hand(extra: list[tuple[int, int]]) -> Graph:
        # The same cells and edges as g (plus ``extra``), built without Graph.grid: checked.
        arcs = [(u, v) for u in range(g.n) for v in g.adj[u]] + extra
        arcs.sort()
        indptr = np.searchsorted([u for u, _ in arcs], np.arange(g.n + 1))
        return Graph(
            kind="grid", coords=g.coords, passable=g.passable, indptr=indptr,
            indices=np.array([v for _, v in arcs]), lengths=np.ones(len(arcs)), shape=g.shape,
        )  # fmt: skip

    assert by_hand([]).grid_xy == g.grid_xy
    assert by_hand([(0, 5), (5, 0)]).grid_xy is None  # a diagonal edge


def test_open_grid_distances_are_manhattan_and_equal_bfs() -> None:
    # A grid without blocked cells gets its tables from the cells' Manhattan distance;
    # they must equal a BFS (2D, 3D, one-cell-wide) and not be used with obstacles.
    from hierplan_opt.core import graph as graph_mod

    for dims in [(1, 1), (6, 1), (1, 5), (7, 4), (3, 4, 2), (5, 5, 1)]:
        g = Graph.grid(*dims)
        assert g._open_grid
        g.fill_distances(range(g.n))
        for t in range(g.n):
            ref = graph_mod._bfs(g.adj, t)
            assert g.dist_list(t) == ref and g.dist_to(t).tolist() == ref
    assert not Graph.grid(4, 4, obstacles=[(1, 2)])._open_grid


@pytest.mark.parametrize("many", [True, False])
def test_many_target_bfs_equals_the_python_bfs(many: bool, monkeypatch: pytest.MonkeyPatch):
    # Without scipy, fill_distances makes the first table by the Python BFS and, when
    # its levels say so (MANY_BFS_RATIO), the others at once by numpy (_bfs_many), in
    # batches between deadline checks. Both ways, forced here, give the Python BFS's
    # tables: grids with walled-off parts, a 3D grid, a roadmap with an isolated vertex.
    from hierplan_opt.core import graph as graph_mod

    monkeypatch.setattr(graph_mod, "MANY_BFS_RATIO", 0 if many else 10**9)
    monkeypatch.setattr(graph_mod, "DIST_BATCH_WORK", 64)  # batches of a few targets
    monkeypatch.setattr(Graph, "_small_bfs", lambda self, count: True)  # as without scipy
    calls: list[int] = []
    real = graph_mod._bfs_many

    def spy(nbr: np.ndarray, targets: list[int]) -> np.ndarray:
        calls.append(len(targets))
        return real(nbr, targets)

    monkeypatch.setattr(graph_mod, "_bfs_many", spy)
    rng = np.random.default_rng(35)
    graphs = [g for g in grids_and_digraphs(rng, (12, 9), 0.35, 4, (30, 45)) if not g.directed]
    graphs.append(Graph.grid(4, 3, 3, obstacles=[(1, 1, 1), (2, 0, 2)]))
    pts = {f"v{i}": (float(i), float(i % 3)) for i in range(7)}
    graphs.append(Graph.roadmap(pts, [("v0", "v1"), ("v1", "v2"), ("v2", "v0"), ("v3", "v4")]))
    for g in graphs:
        free = [v for v in range(g.n) if g.passable[v]]
        targets = [int(t) for t in rng.choice(free, min(7, len(free)), replace=False)]
        assert g.fill_distances(targets)
        for t in targets:
            ref = graph_mod._bfs(g.adj, t)
            assert g.dist_list(t) == ref
            assert g.dist_to(t).tolist() == ref
            assert not g.dist_to(t).flags.writeable
    assert (sum(calls) > 0) == many
    assert not many or max(calls) < 7  # batches


def test_many_target_bfs_only_on_small_degrees_and_stops_at_the_deadline(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    from hierplan_opt.core import graph as graph_mod
    from hierplan_opt.core.timer import Deadline

    star = Graph.roadmap(
        {f"v{i}": (float(i), 1.0 if i else 0.0) for i in range(12)},
        [("v0", f"v{i}") for i in range(1, 12)],
    )
    assert star._neighbour_table is None  # a hub of 11 neighbours: a Python BFS each
    digraph = Graph.roadmap({"A": (0, 0), "B": (1, 0)}, [("A", "B")], directed=True)
    assert digraph._neighbour_table is None
    monkeypatch.setattr(graph_mod, "MANY_BFS_RATIO", 0)
    monkeypatch.setattr(graph_mod, "DIST_BATCH_WORK", 1)  # one target a batch
    monkeypatch.setattr(Graph, "_small_bfs", lambda self, count: True)
    star.fill_distances(range(12))
    assert all(star.dist_list(t) == graph_mod._bfs(star.adj, t) for t in range(12))
    g = Graph.grid(6, 5, obstacles=[(2, y) for y in range(4)])
    assert g._neighbour_table is not None
    assert g._neighbour_table.shape == (g.n + 1, 4)

    # The deadline passes after the first batch: the first table (the Python BFS's) and
    # that batch are made, and kept.
    class Late(Deadline):
        __slots__ = ("checks",)

        def expired(self) -> bool:
            self.checks += 1
            return self.checks > 1

    late = Late(60)
    late.checks = 0
    assert not g.fill_distances([0, 7, 12, 29], late)
    made = [t for t in (0, 7, 12, 29) if t in g._dist_list_cache]
    assert made == [0, 7]
    assert g.fill_distances([0, 7, 12, 29])
    assert all(g.dist_list(t) == graph_mod._bfs(g.adj, t) for t in (0, 7, 12, 29))
    # The Python BFS of many tables (a maze's long corridors) checks it every 16 tables.
    monkeypatch.setattr(graph_mod, "MANY_BFS_RATIO", 10**9)
    g = Graph.grid(8, 5)
    g._open_grid = False  # type: ignore[misc]  # (its tables would be Manhattan's)
    late = Late(60)
    late.checks = 0
    assert not g.fill_distances(range(40), late)
    assert sorted(g._dist_list_cache) == list(range(16))
