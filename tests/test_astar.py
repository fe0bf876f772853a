"""Space-time A*, constraints and MDDs: the low level of CBS."""

from __future__ import annotations

import itertools

import pytest

from hierplan_opt.core.graph import Graph
from hierplan_opt.core.plan import path_cost
from hierplan_opt.search.astar import space_time_astar
from hierplan_opt.search.constraints import (
    LEN_GT,
    LEN_LE,
    NEG_E,
    NEG_RANGE,
    NEG_V,
    POS_E,
    POS_V,
    AgentConstraints,
    add_derived,
    violates_derived,
)
from hierplan_opt.search.heuristics import dependent, min_vertex_cover
from hierplan_opt.search.mdd import build_mdd
from hierplan_opt.search.reservations import Reservations
from hierplan_opt.search.symmetry import Corridors


def plan(g: Graph, s, t, cons: list | None = None, res=None):
    sv, tv = g.vertex(s), g.vertex(t)
    c = AgentConstraints.root(g.n, tv).add_many(cons or [], n=g.n, goal=tv)
    path, _ = space_time_astar(g.adj, sv, tv, g.dist_list(tv), c, res=res, dist_of=g.dist_list)
    return path, c


def brute_paths(g: Graph, s: int, horizon: int):
    """Every walk of ``horizon`` steps from ``s`` (waits included)."""
    walks = [(s,)]
    for _ in range(horizon):
        walks = [w + (u,) for w in walks for u in (*g.adj[w[-1]], w[-1])]
    return walks


def test_goal_constraint_later_than_arrival():
    # The agent could arrive at t=2 but its goal is forbidden at t=3: it must arrive at 4.
    g = Graph.grid(3, 1)
    path, c = plan(g, (0, 0), (2, 0), [(NEG_V, 0, g.vertex((2, 0)), -1, 3)])
    assert path_cost(path) == 4 == len(path) - 1
    assert path[3] != g.vertex((2, 0))
    assert c.allows_path(path, g.n)


def test_vertex_and_edge_constraints():
    g = Graph.grid(3, 1)
    path, _ = plan(g, (0, 0), (2, 0), [(NEG_V, 0, 1, -1, 1)])
    assert path == (0, 0, 1, 2)
    path, _ = plan(g, (0, 0), (2, 0), [(NEG_E, 0, 0, 1, 1)])
    assert path == (0, 0, 1, 2)


def test_length_constraints():
    g = Graph.grid(4, 1)
    path, c = plan(g, (0, 0), (3, 0), [(LEN_GT, 0, -1, -1, 5)])
    assert path_cost(path) == 6 and c.allows_path(path, g.n)
    path, c = plan(g, (0, 0), (3, 0), [(LEN_LE, 0, -1, -1, 2)])
    assert path is None
    path, c = plan(g, (0, 0), (3, 0), [(LEN_LE, 0, -1, -1, 3)])
    assert path == (0, 1, 2, 3)


def test_positive_constraints_are_landmarks():
    g = Graph.grid(3, 3)
    path, c = plan(g, (0, 0), (2, 2), [(POS_V, 0, g.vertex((0, 2)), -1, 2)])
    assert path[2] == g.vertex((0, 2)) and path_cost(path) == 4
    path, c = plan(g, (0, 0), (2, 0), [(POS_E, 0, g.vertex((1, 1)), g.vertex((1, 0)), 3)])
    assert path[2] == g.vertex((1, 1)) and path[3] == g.vertex((1, 0))
    assert path_cost(path) == 4 and c.allows_path(path, g.n)
    # A landmark on the goal after arrival is met by parking there.
    path, c = plan(g, (0, 0), (1, 0), [(POS_V, 0, g.vertex((1, 0)), -1, 6)])
    assert path == (0, 1)


def test_derived_constraints_of_positive_ones():
    g = Graph.grid(3, 1)
    pos = (POS_E, 0, 0, 1, 2)
    assert violates_derived(pos, (2, 1), g.n, [0, 0])  # at 1 at time 2 (parked)
    assert violates_derived(pos, (2, 2, 1, 0), g.n, [0, 0])  # swap at 2
    assert not violates_derived(pos, (2, 2, 2), g.n, [0, 0])
    other = add_derived(AgentConstraints(), [pos], n=g.n, goals=[1, 0], goal=2)
    assert (2 * g.n + 1) in other.vertex and (1 * g.n + 0) in other.vertex
    le = add_derived(AgentConstraints(), [(LEN_LE, 0, -1, -1, 4)], n=3, goals=[1, 0], goal=2)
    assert le.forbid_from == {1: 4}


def test_length_constraint_violated_by_any_visit_of_the_goal_from_its_time_on():
    # LEN_LE (agent 0 at its goal 1 from time t on): another path breaks it by being at
    # vertex 1 at any time >= t, parked there included. All paths over 3 vertices.
    goals = [1, 0]
    for length in range(1, 6):
        for path in itertools.product(range(3), repeat=length):
            for t in range(7):
                at = [path[min(tt, length - 1)] for tt in range(t, t + 8)]
                assert violates_derived((LEN_LE, 0, -1, -1, t), path, 3, goals) == (1 in at)


def test_time_collapse_terminates_without_path():
    # Goal forbidden from t=2 on (another agent parks there): no path; must terminate.
    g = Graph.grid(4, 1)
    c = add_derived(AgentConstraints(), [(LEN_LE, 1, -1, -1, 2)], n=g.n, goals=[3, 3 - 0], goal=3)
    path, _ = space_time_astar(g.adj, 0, 3, g.dist_list(3), c)
    assert path is None
    # Middle vertex forbidden forever from t=0: the goal is cut off.
    c = add_derived(AgentConstraints(), [(LEN_LE, 1, -1, -1, 0)], n=g.n, goals=[3, 1], goal=3)
    path, _ = space_time_astar(g.adj, 0, 3, g.dist_list(3), c)
    assert path is None


def test_range_constraint():
    g = Graph.grid(3, 1)
    path, _ = plan(g, (0, 0), (2, 0), [(NEG_RANGE, 0, 1, 0, 4)])
    assert path == (0, 0, 0, 0, 0, 1, 2)


@pytest.mark.parametrize("seed", range(6))
def test_astar_optimal_against_enumeration(seed):
    import random

    rng = random.Random(seed)
    g = Graph.grid(3, 3, obstacles=[(1, 1)] if seed % 2 else [])
    free = [v for v in range(g.n) if g.passable[v]]
    s, t = rng.sample(free, 2)
    cons = []
    for _ in range(4):
        cons.append((NEG_V, 0, rng.choice(free), -1, rng.randint(1, 5)))
    c = AgentConstraints.root(g.n, t).add_many(cons, n=g.n, goal=t)
    path, _ = space_time_astar(g.adj, s, t, g.dist_list(t), c)
    horizon = 9
    best = None
    for w in brute_paths(g, s, horizon):
        if w[-1] != t:
            continue
        trimmed = w[: path_cost(w) + 1]
        if c.allows_path(trimmed, g.n):
            cost = path_cost(w)
            best = cost if best is None else min(best, cost)
    assert path is not None and best is not None
    assert path_cost(path) == best
    assert c.allows_path(path, g.n)


def test_conflict_table_breaks_ties():
    g = Graph.grid(3, 2)
    # Another agent sits on (1, 0) at t=1; prefer the equal-cost route through row 1.
    other = (g.vertex((1, 0)),) * 3
    res = Reservations(g.n)
    res.add(1, other)
    path, _ = plan(g, (0, 0), (2, 1), res=res)
    assert len(path) - 1 == 3 and g.vertex((1, 0)) not in path


def test_conflict_table_add_remove_roundtrip():
    res = Reservations(10)
    p = (1, 2, 3, 3)
    res.add(0, p)
    res.add(1, (5, 4))
    res.remove(0)
    only = Reservations(10)
    only.add(1, (5, 4))
    assert res.vt == only.vt and res.et == only.et
    assert res.parked == {4: (1, 1)}


def test_mdd_levels_and_cardinality():
    g = Graph.grid(3, 3)
    s, t = g.vertex((0, 0)), g.vertex((2, 2))
    m = build_mdd(g.adj, s, t, g.dist_list(t), AgentConstraints(), 4)
    assert [len(lv) for lv in m.levels] == [1, 2, 3, 2, 1]
    assert m.single(4, t) and m.single(9, t) and not m.single(2, g.vertex((1, 1)))
    # Every cost-4 path lies in the MDD and every MDD edge lies on one.
    walks = [w for w in brute_paths(g, s, 4) if w[-1] == t and path_cost(w) == 4]
    for w in walks:
        assert all(w[i + 1] in m.levels[i][w[i]] for i in range(4))
    assert sum(len(kids) for lv in m.levels for kids in lv.values()) == len(
        {(i, w[i], w[i + 1]) for w in walks for i in range(4)}
    )


def test_dependency_of_two_mdds():
    g = Graph.grid(3, 3)
    ma = build_mdd(g.adj, 0, 2, g.dist_list(2), AgentConstraints(), 2)
    mb = build_mdd(g.adj, 6, 8, g.dist_list(8), AgentConstraints(), 2)
    assert not dependent(ma, mb)
    mc = build_mdd(g.adj, 2, 0, g.dist_list(0), AgentConstraints(), 2)
    assert dependent(ma, mc)


def test_min_vertex_cover_exact_small_graphs():
    for n in range(2, 6):
        edges = list(itertools.combinations(range(n), 2))
        weights = {e: 1 + (e[0] + e[1]) % 3 for e in edges}
        got = min_vertex_cover(weights)
        best = min(
            sum(x)
            for x in itertools.product(range(4), repeat=n)
            if all(x[i] + x[j] >= w for (i, j), w in weights.items())
        )
        assert got == best


def test_corridor_detection():
    g = Graph.grid(5, 3, obstacles=[(1, 0), (2, 0), (3, 0), (1, 2), (2, 2), (3, 2)])
    cor = Corridors(g).corridor(g.vertex((1, 1)))
    assert cor is not None and len(cor[0]) == 3
    assert Corridors(g).corridor(g.vertex((0, 1))) is None


def test_path_order_infeasibility():
    # Agents on a path-shaped component keep their order: the front door's exact test
    # (which replaced CBS's own path-order check) refuses a swapped order.
    from hierplan_opt.core.feasibility import quick_infeasibility
    from hierplan_opt.core.instance import Instance

    g = Graph.grid(5, 1)
    assert quick_infeasibility(Instance.mapf(g, [(0, 0), (4, 0)], [(4, 0), (0, 0)]))
    assert quick_infeasibility(Instance.mapf(g, [(0, 0), (4, 0)], [(1, 0), (3, 0)])) is None
    g2 = Graph.grid(3, 3)
    assert quick_infeasibility(Instance.mapf(g2, [(0, 0), (2, 2)], [(2, 2), (0, 0)])) is None


@pytest.mark.parametrize("seed", range(40))
def test_restricted_mdd_equals_rebuilt(seed):
    import random

    from hierplan_opt.search.mdd import restrict

    rng = random.Random(seed)
    g = Graph.grid(4, 3, obstacles=[(1, 1)] if seed % 3 == 0 else [])
    free = [v for v in range(g.n) if g.passable[v]]
    s, t = rng.sample(free, 2)
    goals = [t, rng.choice([v for v in free if v != t])]
    dist = g.dist_list(t)
    base = AgentConstraints.root(g.n, t).add_many(
        [(NEG_V, 0, rng.choice(free), -1, rng.randint(1, 4))], n=g.n, goal=t
    )
    p0, _ = space_time_astar(g.adj, s, t, dist, base, dist_of=g.dist_list)
    m0 = build_mdd(g.adj, s, t, dist, base, len(p0) - 1, g.dist_list)
    cost = m0.cost
    for _ in range(6):
        kind = rng.choice(["own_v", "own_e", "own_pos", "der_pos", "der_len", "range"])
        v, u = rng.choice(free), rng.choice(free)
        tt = rng.randint(1, cost + 1)
        if kind == "own_v":
            new = base.add((NEG_V, 0, v, -1, tt), n=g.n, goal=t)
        elif kind == "own_e":
            nb = rng.choice([*g.adj[v]] or [v])
            new = base.add((NEG_E, 0, v, nb, tt), n=g.n, goal=t)
        elif kind == "own_pos":
            new = base.add((POS_V, 0, v, -1, tt), n=g.n, goal=t)
        elif kind == "range":
            new = base.add((NEG_RANGE, 0, v, 0, tt), n=g.n, goal=t)
        elif kind == "der_pos":
            new = add_derived(base, [(POS_V, 1, u, -1, tt)], n=g.n, goals=goals, goal=t)
        else:
            new = add_derived(base, [(LEN_LE, 1, -1, -1, tt)], n=g.n, goals=goals, goal=t)
        p, _ = space_time_astar(g.adj, s, t, dist, new, dist_of=g.dist_list)
        r = restrict(m0, new.delta, new.derived)
        if p is None or len(p) - 1 != cost:
            assert r is None
            continue
        rebuilt = build_mdd(g.adj, s, t, dist, new, cost, g.dist_list)
        assert r is not None
        assert [{k: sorted(x) for k, x in lv.items()} for lv in r.levels] == [
            {k: sorted(x) for k, x in lv.items()} for lv in rebuilt.levels
        ]


def test_cut_off_and_failure_memo_change_no_result():
    # Random narrow grids, other agents' goals forbidden from random times on (their
    # length constraints) plus vertex constraints: with the cut-off check and the memo
    # of failed constraint sets the search returns exactly what it returns without
    # (path or None), also when the same constraints come again; a goal that cut_off
    # declares out of reach has no path, and the check does fire.
    import random

    from hierplan_opt.search.astar import cut_off

    cuts = fails = memo = 0
    for seed in range(60):
        rng = random.Random(seed)
        w, h = rng.choice([(6, 3), (7, 2), (5, 5), (9, 3)])
        obst = [(rng.randrange(w), rng.randrange(h)) for _ in range(rng.randint(0, w * h // 4))]
        g = Graph.grid(w, h, obstacles=obst)
        free = [v for v in range(g.n) if g.passable[v]]
        if len(free) < 4:
            continue
        cache: dict = {}
        for _ in range(12):
            s, t = rng.sample(free, 2)
            others = [v for v in free if v != t]
            c = AgentConstraints.root(g.n, t)
            for _ in range(rng.randint(1, 5)):
                goals = [t, rng.choice(others)]
                le = (LEN_LE, 1, -1, -1, rng.randint(0, 8))
                c = add_derived(c, [le], n=g.n, goals=goals, goal=t)
            for _ in range(rng.randint(0, 12)):
                c = c.add((NEG_V, 0, rng.choice(free), -1, rng.randint(1, 6)), n=g.n, goal=t)
            dist = g.dist_list(t)
            plain, _ = space_time_astar(g.adj, s, t, dist, c)
            fails += plain is None
            for _ in range(2):  # the second call may be answered by the memo
                got, _ = space_time_astar(g.adj, s, t, dist, c, cut_cache=cache)
                assert got == plain, seed
            if cut_off(g.adj, s, t, dist, c.forbid_from, c.max_finish) < 0:
                cuts += 1
                assert plain is None, seed
        memo += sum(len(k) == 3 for k in cache)  # failed sets the cut-off did not catch
    assert cuts >= 20 and memo >= 3 and fails >= cuts + memo, (cuts, memo, fails)


def test_cut_off_finds_a_goal_in_reach_along_one_path():
    # On an open 20x20 grid (every shortest path from corner to corner has the same f)
    # the check dives to the goal: about one vertex per step, not the whole rectangle
    # between them; a goal walled off is still reported with every vertex it popped.
    from hierplan_opt.search.astar import cut_off

    g = Graph.grid(20, 20)
    goal = g.n - 1
    pops = cut_off(g.adj, 0, goal, g.dist_list(goal), {goal - 1: 5, 200: 0}, 1 << 40)
    assert 0 < pops <= 40
    walled = {goal - 1: 30, goal - 20: 30}
    assert cut_off(g.adj, 0, goal, g.dist_list(goal), walled, 1 << 40) == -(
        g.n - 3
    )  # all but the goal and its two walls


def test_constraint_copies_share_containers_until_written() -> None:
    """Copy on write: a child's constraints never show in its parent, and a child built
    step by step constrains exactly like one built from scratch."""
    n, goal, other_goal = 30, 7, 9
    own = [
        (NEG_V, 0, 3, -1, 2),
        (NEG_E, 0, 3, 4, 5),
        (POS_V, 0, 5, -1, 6),
        (POS_E, 0, 5, 6, 8),
        (LEN_GT, 0, -1, -1, 4),
    ]
    others = [(LEN_LE, 1, -1, -1, 3), (POS_E, 1, 11, 12, 4), (POS_V, 1, 13, -1, 2)]
    goals = [goal, other_goal]
    chain = [AgentConstraints.root(n, goal)]
    for con in own:
        chain.append(chain[-1].add(con, n=n, goal=goal))
    for con in others:
        chain.append(add_derived(chain[-1], [con], n=n, goals=goals, goal=goal))
    contents = [c.content() for c in chain]
    # A sibling of every version, written in every container: no version changes.
    for c in chain:
        add_derived(
            c.add((NEG_V, 0, 20, -1, 15), n=n, goal=goal), others, n=n, goals=goals, goal=goal
        )
        c.add_many([(POS_V, 0, 21, -1, 16), (NEG_E, 0, 1, 2, 17)], n=n, goal=goal)
    assert [c.content() for c in chain] == contents
    fresh = AgentConstraints.root(n, goal).add_many(own, n=n, goal=goal)
    fresh = add_derived(fresh, others, n=n, goals=goals, goal=goal)
    assert fresh.content() == chain[-1].content()
    assert chain[-1].forbid_from == {other_goal: 3} and not chain[0].forbid_from
