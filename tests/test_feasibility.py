"""The exact feasibility test (core/pebble_motion.py, core/feasibility.py) against brute force.

Brute force (tests/pebble_bruteforce.py) is a search over joint configurations with the
validator's move rules. For every graph checked, *every* placement of k labelled agents
is put into its reachability class by brute force, and the test's key
(:func:`arrangement_key`) must induce exactly the same partition; the answers of
:func:`arrangement_violation` (what ``quick_infeasibility`` uses) are checked on samples
of the same placements. The fast suite covers all connected graphs up to 4 vertices and
a few shapes; ``-m slow`` covers all connected graphs up to 6 vertices and the named
shapes (paths, cycles, stars, spiders, lollipops, thetas, figure eights, dumbbells,
small grids with obstacles) up to 9 vertices.
"""

from __future__ import annotations

import itertools
import random
import time
from collections.abc import Iterable

import networkx as nx
import pytest
from pebble_bruteforce import distances_from, reachability_classes, shortest_plan, successors

import hierplan_opt
from hierplan_opt import Agent, Graph, Instance
from hierplan_opt.core.feasibility import makespan_upper_bound, quick_infeasibility
from hierplan_opt.core.pebble_motion import arrangement_key, arrangement_violation, one_by_one
from hierplan_opt.core.plan import Plan
from hierplan_opt.core.result import Status
from hierplan_opt.core.validate import validate


def as_graph(G: nx.Graph) -> Graph:
    """A roadmap whose vertex ids are 0..n-1 in the order of ``G``'s nodes."""
    G = nx.convert_node_labels_to_integers(G)
    H = nx.Graph()
    H.add_nodes_from(range(G.number_of_nodes()))
    H.add_edges_from(G.edges())
    nx.set_node_attributes(H, {v: (v, 0) for v in H}, "pos")
    g = Graph.from_networkx(H)
    assert [g.vertex(str(v)) for v in range(g.n)] == list(range(g.n))
    return g


def theta(a: int, b: int, c: int) -> nx.Graph:
    """Two vertices joined by three internally disjoint paths of a, b, c edges."""
    G = nx.Graph()
    nxt = 2
    for length in (a, b, c):
        prev = 0
        for _ in range(length - 1):
            G.add_edge(prev, nxt)
            prev, nxt = nxt, nxt + 1
        G.add_edge(prev, 1)
    return G


def cycles_at(*lengths: int, bridge: int | None = None) -> nx.Graph:
    """Cycles sharing vertex 0 (figure eight), or joined by a path of ``bridge`` edges."""
    G = nx.Graph()
    nxt = 1
    anchors = []
    for length in lengths:
        anchor = 0 if bridge is None else nxt
        if bridge is not None:
            nxt += 1
        ring = [anchor, *range(nxt, nxt + length - 1)]
        nxt += length - 1
        nx.add_cycle(G, ring)
        anchors.append(anchor)
    if bridge is not None:
        path = [anchors[0], *range(nxt, nxt + bridge - 1), anchors[1]]
        nx.add_path(G, path)
    return G


def grid(w: int, h: int, obstacles: Iterable[tuple[int, int]] = ()) -> nx.Graph:
    G = nx.grid_2d_graph(w, h)
    G.remove_nodes_from(list(obstacles))
    return G


def shapes() -> list[tuple[str, nx.Graph]]:
    """Named small shapes, up to 9 vertices."""
    out: list[tuple[str, nx.Graph]] = []
    out += [(f"path{n}", nx.path_graph(n)) for n in range(2, 9)]
    out += [(f"cycle{n}", nx.cycle_graph(n)) for n in range(3, 9)]
    out += [(f"star{n}", nx.star_graph(n - 1)) for n in range(4, 9)]
    spider = nx.Graph()
    nx.add_path(spider, [1, 2, 0, 3, 4])
    nx.add_path(spider, [0, 5, 6])
    out.append(("spider222", spider))
    h_tree = nx.path_graph(6)
    h_tree.add_edges_from([(1, 6), (4, 7)])
    out.append(("h-tree", h_tree))
    out += [("lollipop3-3", nx.lollipop_graph(3, 3)), ("lollipop4-3", nx.lollipop_graph(4, 3))]
    out += [(f"theta{a}{b}{c}", theta(a, b, c)) for a, b, c in [(1, 2, 2), (2, 2, 2), (2, 2, 3)]]
    out += [(f"theta{a}{b}{c}", theta(a, b, c)) for a, b, c in [(1, 3, 3), (2, 3, 3)]]
    out += [("bowtie", cycles_at(3, 3)), ("eight34", cycles_at(3, 4)), ("eight44", cycles_at(4, 4))]
    out += [("dumbbell1", cycles_at(3, 3, bridge=1)), ("dumbbell2", cycles_at(3, 3, bridge=2))]
    out += [("barbell3-1", nx.barbell_graph(3, 1))]
    out += [
        ("grid2x2", grid(2, 2)),
        ("grid2x3", grid(2, 3)),
        ("grid2x4", grid(2, 4)),
        ("grid3x3-ring", grid(3, 3, [(1, 1)])),
        ("grid3x3-U", grid(3, 3, [(1, 0)])),
        ("grid3x3-H", grid(3, 3, [(0, 1), (2, 1)])),
        ("grid3x3-2obst", grid(3, 3, [(1, 1), (0, 2)])),
        ("grid3x3", grid(3, 3)),
    ]
    return out


def check_partition(G: nx.Graph, ks: Iterable[int], rng: random.Random) -> int:
    """Brute-force classes == key classes for every placement; sampled direct answers."""
    g = as_graph(G)
    count = 0
    for k in ks:
        comp = reachability_classes(g.adj, k)
        key_to_comp: dict[tuple, int] = {}
        comp_to_key: dict[int, tuple] = {}
        for conf, cid in comp.items():
            key = arrangement_key(g, list(conf))
            assert key_to_comp.setdefault(key, cid) == cid, (sorted(G.edges()), k, conf, "merged")
            assert comp_to_key.setdefault(cid, key) == key, (sorted(G.edges()), k, conf, "split")
        confs = list(comp)
        ids = list(range(k))
        for a, b in (rng.sample(confs, 2) for _ in range(min(40, len(confs) // 2))):
            why = arrangement_violation(g, list(a), ids, list(b), ids)
            assert (why is None) == (comp[a] == comp[b]), (sorted(G.edges()), a, b, why)
        count += len(comp)
    return count


# ------------------------------------------------------------------ brute force itself
def test_bruteforce_follows_the_validator() -> None:
    g = as_graph(nx.cycle_graph(3))
    steps = set(successors(g.adj, (0, 1, 2)))
    assert (1, 2, 0) in steps  # rotation of a full triangle
    assert (1, 0, 2) not in steps  # swap along an edge
    path = as_graph(nx.path_graph(3))
    assert (1, 2) in set(successors(path.adj, (0, 1)))  # following
    rng = random.Random(3)
    for name, G in shapes()[:20]:
        h = as_graph(G)
        k = min(3, h.n - 1)
        start, goal = (tuple(rng.sample(range(h.n), k)) for _ in range(2))
        plan = shortest_plan(h.adj, start, goal)
        if plan is None:
            continue
        inst = Instance.mapf(h, [str(v) for v in start], [str(v) for v in goal])
        paths = [[conf[i] for conf in plan] for i in range(k)]
        assert validate(inst, Plan.from_paths(paths)) == [], name


# ------------------------------------------------------------------ the reproducer
def test_reproducer_3x3_grid_three_agents() -> None:
    # The 3x3 grid around one obstacle is a ring of 8 cells: three agents keep their
    # cyclic order whatever the empty cells, so reversing it is impossible.
    g = Graph.grid(3, 3, obstacles=[(1, 1)])
    inst = Instance.mapf(g, [(0, 0), (2, 0), (2, 2)], [(2, 0), (0, 0), (2, 2)])
    assert shortest_plan(g.adj, tuple(inst.starts), tuple(inst.goals)) is None
    t0 = time.perf_counter()
    why = quick_infeasibility(inst)
    assert time.perf_counter() - t0 < 1.0  # milliseconds in practice; generous for CI
    assert why is not None and "cyclic order" in why
    for solver in ("cbs", "ecbs", "eecbs", "cbm", "cpsat", "mip"):
        r = hierplan_opt.solve(inst, solver, time_limit=5.0)
        assert r.status == Status.INFEASIBLE, solver
    # The same cells with the cyclic order kept are solvable, and the test says so.
    ok = Instance.mapf(g, [(0, 0), (2, 0), (2, 2)], [(2, 0), (2, 2), (0, 0)])
    assert quick_infeasibility(ok) is None
    assert shortest_plan(g.adj, tuple(ok.starts), tuple(ok.goals)) is not None


def test_reproducer_t_junction_without_room() -> None:
    # 3x3 grid with two obstacles: a T of 7 cells; three agents cannot rotate on it.
    g = Graph.grid(3, 3, obstacles=[(0, 1), (2, 1), (0, 2), (2, 2)])
    inst = Instance.mapf(g, [(0, 0), (2, 0), (1, 2)], [(2, 0), (1, 2), (0, 0)])
    assert shortest_plan(g.adj, tuple(inst.starts), tuple(inst.goals)) is None
    assert "cannot pass" in (quick_infeasibility(inst) or "")


def test_messages_name_the_case() -> None:
    tri = as_graph(nx.cycle_graph(3))
    full = Instance.mapf(tri, ["0", "1", "2"], ["1", "0", "2"])
    assert "cyclic order" in (quick_infeasibility(full) or "")
    tail = as_graph(nx.lollipop_graph(3, 1))  # triangle 0-1-2 and vertex 3 on 2
    stuck = Instance.mapf(tail, ["0", "1", "2", "3"], ["0", "1", "3", "2"])
    assert "can never move" in (quick_infeasibility(stuck) or "")
    bowtie = as_graph(cycles_at(3, 3))
    odd = Instance.mapf(bowtie, ["0", "1", "2", "3", "4"], ["1", "0", "2", "3", "4"])
    assert "permuted evenly" in (quick_infeasibility(odd) or "")
    even = Instance.mapf(bowtie, ["0", "1", "2", "3", "4"], ["1", "2", "0", "3", "4"])
    assert quick_infeasibility(even) is None
    # Two full triangles joined by a bridge: robots never cross it, so team counts per
    # triangle must already be right.
    dumbbell = as_graph(cycles_at(3, 3, bridge=1))  # triangles {0,1,2}, {3,4,5}; bridge 0-3
    teams = [(["0", "2", "4"], ["0", "4", "5"]), (["3", "1", "5"], ["2", "3", "1"])]
    assert "cannot reach any target" in (quick_infeasibility(Instance.tapf(dumbbell, teams)) or "")


def test_directed_graphs_keep_the_necessary_checks_only() -> None:
    # Small directed roadmaps are decided by the exhaustive joint search; large ones
    # keep the necessary checks only (a full one-way ring of 12: 12! configurations).
    g = Graph.roadmap(
        {"A": (0, 0), "B": (1, 0), "C": (0, 1)}, [("A", "B"), ("B", "C"), ("C", "A")], directed=True
    )
    why = quick_infeasibility(Instance.mapf(g, ["A", "B", "C"], ["B", "A", "C"]))
    assert why is not None and "exhaustive search" in why
    assert quick_infeasibility(Instance.mapf(g, ["A", "B", "C"], ["B", "C", "A"])) is None
    assert makespan_upper_bound(Instance.mapf(g, ["A", "B"], ["B", "A"])) == 5
    names = [f"v{i}" for i in range(12)]
    ring = Graph.roadmap(
        {v: (i, 0) for i, v in enumerate(names)},
        [(names[i], names[(i + 1) % 12]) for i in range(12)],
        directed=True,
    )
    assert quick_infeasibility(Instance.mapf(ring, names, [names[1], names[0], *names[2:]])) is None


# ------------------------------------------------------------------ exactness (fast sample)
def test_exact_on_every_graph_up_to_4_vertices_and_some_shapes() -> None:
    rng = random.Random(0)
    count = 0
    for G in nx.graph_atlas_g()[1:]:
        if G.number_of_nodes() <= 4 and nx.is_connected(G):
            count += check_partition(G, range(1, G.number_of_nodes() + 1), rng)
    for name in ("bowtie", "dumbbell1", "lollipop3-3", "spider222", "theta122"):
        G = dict(shapes())[name]
        n = G.number_of_nodes()
        count += check_partition(G, range(max(1, n - 2), n + 1), rng)
    assert count > 10_000


def test_one_by_one_only_says_yes_when_brute_force_agrees() -> None:
    # The shortcut the exact test is skipped for must never accept an unsolvable
    # placement; it should accept a fair share of the solvable ones.
    rng = random.Random(3)
    graphs = [G for G in nx.graph_atlas_g()[1:] if nx.is_connected(G) and G.number_of_nodes() <= 5]
    graphs += [G for name, G in shapes() if G.number_of_nodes() <= 7]
    said_yes = solvable = 0
    for G in graphs:
        g = as_graph(G)
        for k in range(1, min(4, g.n) + 1):
            comp = reachability_classes(g.adj, k)
            confs = list(comp)
            for a, b in (rng.sample(confs, 2) for _ in range(min(30, len(confs) // 2))):
                yes = one_by_one(g.adj, list(a), list(b))
                solvable += comp[a] == comp[b]
                if yes:
                    said_yes += 1
                    assert comp[a] == comp[b], (sorted(G.edges()), a, b)
                    inst = Instance.mapf(g, [str(v) for v in a], [str(v) for v in b])
                    assert quick_infeasibility(inst) is None
    assert said_yes > 200 and solvable > said_yes


@pytest.mark.slow
def test_exact_on_every_connected_graph_up_to_6_vertices() -> None:
    rng = random.Random(1)
    graphs = [G for G in nx.graph_atlas_g()[1:] if nx.is_connected(G) and G.number_of_nodes() <= 6]
    count = sum(check_partition(G, range(1, G.number_of_nodes() + 1), rng) for G in graphs)
    assert len(graphs) == 143 and count > 220_000


@pytest.mark.slow
@pytest.mark.parametrize("name", [name for name, _ in shapes()])
def test_exact_on_named_shapes(name: str) -> None:
    G = dict(shapes())[name]
    n = G.number_of_nodes()
    # Above 7 vertices the few-holes regime only (where classes are least trivial); above
    # 8, two and three holes (the full 3x3 grid with every agent count was checked once,
    # 967,680 placements, 13 minutes).
    ks = range(1, n + 1) if n <= 7 else range(n - 3, n + 1) if n == 8 else range(n - 3, n - 1)
    assert check_partition(G, ks, random.Random(2)) > 0


# ------------------------------------------------------------------ teams (coloured agents)
def coloured_feasible(
    comp: dict[tuple[int, ...], int],
    start: tuple[int, ...],
    colours: list[int],
    targets: dict[int, int],
) -> bool:
    """Brute force: some assignment of robots to targets of their colour is reachable."""
    k = len(start)
    free = list(targets)
    for perm in itertools.permutations(free, k):
        if all(targets[perm[i]] == colours[i] for i in range(k)) and comp[perm] == comp[start]:
            return True
    return False


@pytest.mark.parametrize("slow", [False, pytest.param(True, marks=pytest.mark.slow)])
def test_teams_exact_against_brute_force(slow: bool) -> None:
    rng = random.Random(5)
    names = [name for name, G in shapes() if G.number_of_nodes() <= (7 if slow else 5)]
    for name in names:
        g = as_graph(dict(shapes())[name])
        for k in range(2, g.n + 1):
            comp = reachability_classes(g.adj, k)
            for _ in range(40 if slow else 8):
                start = tuple(rng.sample(range(g.n), k))
                colours = [rng.randrange(2 if k > 2 else 1) for _ in range(k)]
                goal = rng.sample(range(g.n), k)
                targets = dict(zip(goal, colours, strict=True))
                rng.shuffle(goal)
                why = arrangement_violation(
                    g, list(start), colours, goal, [targets[v] for v in goal]
                )
                assert (why is None) == coloured_feasible(comp, start, colours, targets), (
                    name,
                    start,
                    colours,
                    targets,
                )


def test_one_team_is_decided_by_counts_per_component() -> None:
    g = Graph.grid(5, 1)
    inst = Instance.tapf(g, [([(0, 0), (1, 0)], [(4, 0), (3, 0)])])
    assert quick_infeasibility(inst) is None  # anonymous agents need not pass each other
    two = Instance.tapf(g, [([(0, 0)], [(4, 0)]), ([(1, 0)], [(3, 0)])])
    assert "cannot reach any target" in (quick_infeasibility(two) or "")


# ------------------------------------------------------------------ makespan upper bound
def optimal_makespan(
    g: Graph, start: tuple[int, ...], goal_set: frozenset[int] | None, goal
) -> int | None:
    dist = distances_from(g.adj, start)
    if goal_set is None:
        return dist.get(goal)
    best = [d for conf, d in dist.items() if frozenset(conf) == goal_set]
    return min(best) if best else None


@pytest.mark.parametrize("slow", [False, pytest.param(True, marks=pytest.mark.slow)])
def test_makespan_bound_covers_the_optimum(slow: bool) -> None:
    rng = random.Random(7)
    checked = 0
    for name, G in shapes():
        g = as_graph(G)
        if g.n > (7 if slow else 5):
            continue
        for k in range(1, g.n + 1):
            for _ in range(6 if slow else 2):
                start = tuple(rng.sample(range(g.n), k))
                goal = tuple(rng.sample(range(g.n), k))
                mapf = Instance.mapf(g, [str(v) for v in start], [str(v) for v in goal])
                opt = optimal_makespan(g, start, None, goal)
                assert (opt is None) == (quick_infeasibility(mapf) is not None), (name, start, goal)
                if opt is not None:
                    assert opt <= makespan_upper_bound(mapf), (name, start, goal)
                anon = Instance.tapf(g, [([str(v) for v in start], [str(v) for v in goal])])
                opt = optimal_makespan(g, start, frozenset(goal), None)
                assert opt is not None and quick_infeasibility(anon) is None
                assert opt <= makespan_upper_bound(anon), (name, start, goal)
                checked += 1
    assert checked > 50


def test_large_maps_are_decided() -> None:
    from pathlib import Path

    from hierplan_opt.io.movingai import load_movingai

    root = Path(__file__).resolve().parent.parent / "instances" / "movingai"
    inst = load_movingai(root / "random-32-32-20.map", root / "random-32-32-20-random-1.scen", 409)
    assert quick_infeasibility(inst) is None
    # Fill the map: all but 3 free cells hold an agent; a few random goal swaps are
    # then decided without search (either answer is fine: it must be consistent).
    g = inst.graph
    free = [v for v in range(g.n) if g.passable[v]]
    rng = random.Random(11)
    starts = rng.sample(free, len(free) - 3)
    goals = list(starts)
    i, j = 0, 1
    goals[i], goals[j] = goals[j], goals[i]
    agents = tuple(Agent(f"a{m}", s, t) for m, (s, t) in enumerate(zip(starts, goals, strict=True)))
    crowded = Instance(graph=g, agents=agents)
    why = quick_infeasibility(crowded)
    assert why is None or "cannot" in why or "order" in why


def test_one_by_one_with_stuck_agents_first_or_last_agrees_with_brute_force(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    # The agents without a route clear of every endpoint may move first or last
    # (one_by_one's STUCK_MAX): every placement that only this accepts is solvable by
    # brute force, and there are such placements (the extension is exercised).
    import hierplan_opt.core.pebble_motion as pm

    rng = random.Random(35)
    graphs = [G for G in nx.graph_atlas_g()[1:] if nx.is_connected(G) and G.number_of_nodes() <= 6]
    graphs += [G for name, G in shapes() if G.number_of_nodes() <= 7]
    only_extended = 0
    for G in graphs:
        g = as_graph(G)
        for k in range(2, min(4, g.n - 1) + 1):
            comp = reachability_classes(g.adj, k)
            confs = list(comp)
            for a, b in (rng.sample(confs, 2) for _ in range(min(40, len(confs) // 2))):
                monkeypatch.setattr(pm, "STUCK_MAX", -1)
                plain = one_by_one(g.adj, list(a), list(b))
                monkeypatch.setattr(pm, "STUCK_MAX", 4)
                if one_by_one(g.adj, list(a), list(b)) and not plain:
                    only_extended += 1
                    assert comp[a] == comp[b], (sorted(G.edges()), a, b)
    assert only_extended > 300, only_extended


def test_structure_made_once_per_map():
    # Graphs of one map (read again per solve) share the structure; a graph with the
    # same edges but another free cell (an isolated free cell against a blocked one)
    # does not.
    from hierplan_opt.core.pebble_motion import PebbleStructure

    a = Graph.grid(5, 1, obstacles=[(1, 0), (3, 0)])
    b = Graph.grid(5, 1, obstacles=[(1, 0), (2, 0), (3, 0)])
    assert a.adj is b.adj
    sa, sb = PebbleStructure.of(a), PebbleStructure.of(b)
    assert sa is not sb and (len(sa.comps), len(sb.comps)) == (3, 2)
    assert PebbleStructure.of(Graph.grid(5, 1, obstacles=[(1, 0), (3, 0)])) is sa
