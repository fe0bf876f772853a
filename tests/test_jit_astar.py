"""The compiled low level and MDDs (numba) against the pure-Python ones: identical."""

from __future__ import annotations

import random
import subprocess
import sys

import numpy as np
import pytest
from spacetime_cases import walk

from hierplan_opt.core.graph import UNREACHABLE, Graph
from hierplan_opt.search import astar, jit
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
)
from hierplan_opt.search.reservations import Reservations
from hierplan_opt.search.symmetry import travel_time


@pytest.fixture
def both():
    """Run ``space_time_astar`` once per low level; restore the mode afterwards."""

    def call(*args, **kw):
        out = []
        for mode in ("python", "jit"):
            jit.set_low_level(mode)
            out.append(astar.space_time_astar(*args, **kw))
        return out

    yield call
    jit.set_low_level(None)


def random_grid(rng: random.Random) -> tuple[Graph, list[int]]:
    """A small grid with random obstacles, and its free vertices."""
    w, h = rng.choice([(5, 4), (6, 6), (8, 3)])
    obst = [(rng.randrange(w), rng.randrange(h)) for _ in range(rng.randint(0, w * h // 5))]
    g = Graph.grid(w, h, obstacles=obst)
    return g, [v for v in range(g.n) if g.passable[v]]


def random_cons(g: Graph, rng: random.Random, free: list[int], goal: int) -> AgentConstraints:
    goals = [goal, rng.choice([v for v in free if v != goal])]
    c = AgentConstraints.root(g.n, goal, max_finish=rng.choice([1 << 40, 1 << 40, 14, 9]))
    for _ in range(rng.randint(0, 8)):
        kind = rng.choice(["v", "v", "e", "pos_v", "pos_e", "gt", "le", "range", "dpos", "dlen"])
        v = rng.choice(free)
        nb = rng.choice([*g.adj[v], v])
        t = rng.randint(1, 10)
        if kind == "v":
            c = c.add((NEG_V, 0, v, -1, t), n=g.n, goal=goal)
        elif kind == "e":
            c = c.add((NEG_E, 0, v, nb, t), n=g.n, goal=goal)
        elif kind == "pos_v" and rng.random() < 0.5:
            c = c.add((POS_V, 0, v, -1, t), n=g.n, goal=goal)
        elif kind == "pos_e" and rng.random() < 0.5:
            c = c.add((POS_E, 0, v, nb, t), n=g.n, goal=goal)
        elif kind == "gt":
            c = c.add((LEN_GT, 0, -1, -1, t), n=g.n, goal=goal)
        elif kind == "le":
            c = c.add((LEN_LE, 0, -1, -1, t + 6), n=g.n, goal=goal)
        elif kind == "range":
            c = c.add((NEG_RANGE, 0, v, t, t + 2), n=g.n, goal=goal)
        elif kind == "dpos":
            c = add_derived(c, [(POS_E, 1, v, nb, t)], n=g.n, goals=goals, goal=goal)
        elif kind == "dlen":
            c = add_derived(c, [(LEN_LE, 1, -1, -1, t)], n=g.n, goals=goals, goal=goal)
    return c


@pytest.mark.parametrize("seed", range(60))
def test_random_calls_identical(both, seed):
    # Random constraints of every kind, a random conflict-avoidance table (tie-breaking),
    # sometimes a node limit: the path and the expansion count agree exactly.
    rng = random.Random(seed)
    g, free = random_grid(rng)
    if len(free) < 3:
        return
    res = Reservations(g.n)
    for a in range(rng.randint(0, 5)):
        res.add(a, walk(g, rng, free, rng.randint(0, 12)))
    for _ in range(8):
        s, t = rng.sample(free, 2)
        c = random_cons(g, rng, free, t)
        limit = rng.choice([None, None, None, 5, 20])
        py, jt = both(
            g.adj, s, t, g.dist_list(t), c, res=res, dist_of=g.dist_list, node_limit=limit
        )
        assert py == jt, (seed, c.landmarks, c.forbid_from, c.min_finish, c.max_finish)
        py, jt = both(g.adj, s, t, g.dist_list(t), c, dist_of=g.dist_list)
        assert py == jt
        # Patch the table between calls as CBS does: the mirror follows.
        a = rng.randrange(6)
        res.remove(a)
        if rng.random() < 0.7:
            res.add(a, walk(g, rng, free, rng.randint(0, 14)))


@pytest.mark.parametrize("seed", range(40))
def test_random_travel_times_identical(seed):
    # Corridor reasoning's earliest arrivals (symmetry.travel_time): the same value from
    # the Python search and the kernel's, under random constraints of every kind, a
    # random blocked edge and random upper bounds, and against a plain BFS over
    # (vertex, time) that never prunes (so neither search's pruning hides a time).
    rng = random.Random(seed)
    g, free = random_grid(rng)
    if len(free) < 3:
        return
    k = jit.load()
    for _ in range(10):
        s, target = rng.sample(free, 2)
        c = random_cons(g, rng, free, rng.choice(free))
        v = rng.choice(free)
        blocked = rng.choice([None, (v, rng.choice(g.adj[v]))]) if g.adj[v] else None
        upper = rng.choice([UNREACHABLE, rng.randint(1, 16)])
        h = g.dist_list(target)
        py = travel_time(g.adj, s, target, h, c, blocked, upper)
        jt = travel_time(g.adj, s, target, h, c, blocked, upper, kernel=k)
        assert py == jt, (seed, s, target, blocked, upper)
        assert py == min(upper, earliest(g, s, target, c, blocked, upper)), (seed, s, target)


def earliest(g: Graph, s: int, target: int, c: AgentConstraints, blocked, upper: int) -> int:
    """The earliest time at ``target`` by a breadth-first sweep of the time steps."""
    now = {s}
    for t in range(min(upper, 4 * g.n + c.tmax + 2)):
        if target in now:
            return t
        nxt = set()
        for v in now:
            for u in (*g.adj[v], v):
                if blocked is not None and {v, u} == set(blocked):
                    continue
                if (t + 1) * g.n + u in c.vertex:
                    continue
                if u != v and ((t + 1) * g.n + v) * g.n + u in c.edge:
                    continue
                if u in c.forbid_from and t + 1 >= c.forbid_from[u]:
                    continue
                nxt.add(u)
        now = nxt
    return UNREACHABLE


@pytest.mark.parametrize("seed", range(30))
def test_head_on_tables_identical(both, seed):
    # Tables holding the agent's own shortest path walked backwards (shifted in time):
    # many head-on swaps to count, which random walks rarely give.
    rng = random.Random(500 + seed)
    g, free = random_grid(rng)
    if len(free) < 3:
        return
    jit.set_low_level("python")
    for _ in range(6):
        s, t = rng.sample(free, 2)
        p, _ = astar.space_time_astar(g.adj, s, t, g.dist_list(t), AgentConstraints.root(g.n, t))
        if p is None:
            continue
        res = Reservations(g.n)
        back = tuple(reversed(p))
        res.add(0, back[rng.randint(0, 1) :])
        res.add(1, walk(g, rng, free, rng.randint(0, 12)))
        c = random_cons(g, rng, free, t) if rng.random() < 0.5 else AgentConstraints.root(g.n, t)
        py, jt = both(g.adj, s, t, g.dist_list(t), c, res=res, dist_of=g.dist_list)
        assert py == jt, seed


@pytest.mark.parametrize("mode", ["python", "jit"])
@pytest.mark.parametrize(("other", "want"), [((1, 0, 0), (0, 2, 3)), ((2, 0, 0), (0, 1, 3))])
def test_swap_avoided_among_equal_paths(mode, other, want):
    # 2x2 grid, 0 -> 3 has two shortest paths; the other agent comes head-on along one
    # (1 -> 0 or 2 -> 0 at t = 1: a swap, no vertex conflict): the search takes the other.
    g = Graph.grid(2, 2)
    res = Reservations(g.n)
    res.add(0, other)
    jit.set_low_level(mode)
    try:
        path, _ = astar.space_time_astar(
            g.adj, 0, 3, g.dist_list(3), AgentConstraints.root(g.n, 3), res=res
        )
    finally:
        jit.set_low_level(None)
    assert path == want
    assert res.conflicts_of(1, want) == []


def ordered(levels: list[dict[int, list[int]]]) -> list[list[tuple[int, list[int]]]]:
    """The levels with their insertion orders (consumers iterate them)."""
    return [list(lv.items()) for lv in levels]


@pytest.mark.parametrize("seed", range(40))
def test_random_mdds_identical(seed):
    # build_mdd from the kernel: the same levels, children and orders for random
    # constraints (landmarks, forbid_from, finish bounds) and costs, also above optimal.
    from hierplan_opt.search.mdd import build_mdd

    rng = random.Random(1000 + seed)
    g, free = random_grid(rng)
    if len(free) < 3:
        return
    try:
        for _ in range(8):
            s, t = rng.sample(free, 2)
            c = random_cons(g, rng, free, t)
            jit.set_low_level("python")
            p, _ = astar.space_time_astar(g.adj, s, t, g.dist_list(t), c, dist_of=g.dist_list)
            cost = len(p) - 1 + rng.choice([0, 0, 1, 2]) if p is not None else rng.randint(0, 9)
            out = []
            for mode in ("python", "jit"):
                jit.set_low_level(mode)
                m = build_mdd(g.adj, s, t, g.dist_list(t), c, cost, g.dist_list)
                # single() first: from the kernel's arrays before the levels are made
                ones = [[m.single(x, v) for v in range(g.n)] for x in range(-1, cost + 2)]
                out.append((ones, ordered(m.levels)))
            assert out[0] == out[1], (seed, cost)
    finally:
        jit.set_low_level(None)


@pytest.mark.parametrize("seed", range(40))
def test_restricted_mdds_identical(seed):
    # restrict on the kernel's arrays (chained, as CBS restricts an ancestor's MDD
    # along its descendants) against restrict on the Python-built levels: the same
    # levels in the same orders, the same one-vertex levels, the same "cost gone".
    from hierplan_opt.search.mdd import MDD, build_mdd, restrict

    rng = random.Random(2000 + seed)
    g, free = random_grid(rng)
    if len(free) < 3:
        return
    s, t = rng.sample(free, 2)
    goals = [t, rng.choice([v for v in free if v != t])]
    dist = g.dist_list(t)
    root = AgentConstraints.root(g.n, t)
    p0, _ = astar.space_time_astar(g.adj, s, t, dist, root)
    if p0 is None or len(p0) < 2:
        return
    cost = len(p0) - 1 + rng.choice([0, 0, 1, 2])
    try:
        jit.set_low_level("python")
        py = build_mdd(g.adj, s, t, dist, root, cost, g.dist_list)
        jit.set_low_level("jit")
        jt = build_mdd(g.adj, s, t, dist, root, cost, g.dist_list)
    finally:
        jit.set_low_level(None)
    seen = 0
    for _ in range(6):
        own, derived = [], []
        for _ in range(rng.randint(1, 3)):
            kind = rng.choice(
                ["v", "v", "e", "pos_v", "pos_e", "gt", "le", "range", "dpos", "dlen"]
            )
            v = rng.choice(free)
            nb = rng.choice([*g.adj[v], v])
            tt = rng.randint(0, cost + 1)
            if kind == "v":
                own.append((NEG_V, 0, v, -1, tt))
            elif kind == "e":
                own.append((NEG_E, 0, v, nb, max(tt, 1)))
            elif kind == "pos_v":
                own.append((POS_V, 0, v, -1, tt))
            elif kind == "pos_e":
                own.append((POS_E, 0, v, nb, max(tt, 1)))
            elif kind == "gt":
                own.append((LEN_GT, 0, -1, -1, tt))
            elif kind == "le":
                own.append((LEN_LE, 0, -1, -1, tt + 2))
            elif kind == "range":
                own.append((NEG_RANGE, 0, v, tt, tt + 2))
            elif kind == "dpos":
                derived.append(((rng.choice([POS_V, POS_E]), 1, v, nb, max(tt, 1)), goals[1]))
            else:
                derived.append(((LEN_LE, 1, -1, -1, tt), rng.choice(goals)))
        r_py = restrict(py, own, derived)
        r_jt = restrict(jt, own, derived)
        assert (r_py is None) == (r_jt is None), (seed, own, derived)
        if r_py is None or r_jt is None:
            continue
        seen += 1
        twin = MDD(None, cost, t, r_jt._raw)  # compared; r_jt stays arrays for the chain
        ones = [[twin.single(x, v) for v in range(g.n)] for x in range(-1, cost + 2)]
        assert ones == [[r_py.single(x, v) for v in range(g.n)] for x in range(-1, cost + 2)]
        span = range(-cost - 2, cost + 2)
        has = [[twin.has(x, v) for v in range(g.n)] for x in span if x >= -cost - 1]
        passes = [[twin.passes(v, x) for v in range(g.n)] for x in span]
        assert ordered(twin.levels) == ordered(r_py.levels)
        assert has == [[r_py.has(x, v) for v in range(g.n)] for x in span if x >= -cost - 1]
        assert passes == [[r_py.passes(v, x) for v in range(g.n)] for x in span]
        assert passes == [
            [v == t or any(v in lv for lv in r_py.levels[x:]) for v in range(g.n)] for x in span
        ]
        if rng.random() < 0.7:  # chain: restrict the restricted MDD further
            py, jt = r_py, r_jt
    assert seen > 0 or cost < 2


def dense(res: Reservations, graph: jit._Graph, h: int) -> tuple[np.ndarray, np.ndarray]:
    n = res.n
    nnz = graph.idx.shape[0]
    vt = np.zeros(h * n, np.int64)
    et = np.zeros(h * nnz, np.int64)
    for p in res.paths:
        if p is None:
            continue
        for t, v in enumerate(p):
            vt[t * n + v] += 1
            if t and p[t - 1] != v:  # counted at the reverse move v -> u (a swap's slot)
                u = p[t - 1]
                row = graph.idx[graph.ptr[v] : graph.ptr[v + 1]].tolist()
                et[t * nnz + graph.ptr[v] + row.index(u)] += 1
    return vt, et


def as_dicts(res: Reservations | None) -> Reservations | None:
    """A dict-kept copy of ``res`` (the same agents in the same order at every key)."""
    if res is None or res.dense is None:
        return res
    copy = Reservations(res.n)
    for a in sorted(
        (a for a, p in enumerate(res.paths) if p is not None), key=res.stamps.__getitem__
    ):
        p = res.paths[a]
        assert p is not None
        copy.add(a, p)
    copy.parked, copy.park_t = res.dense.parked()
    copy.paths.extend([None] * (len(res.paths) - len(copy.paths)))
    copy.horizon = res.horizon
    return copy


@pytest.mark.parametrize("seed", range(4))
def test_dense_table_answers_as_the_dicts(seed):
    # The same updates on a dict-kept table and on one the kernel has taken over: the
    # counts, the parking and conflicts_of (conflicts and their order) agree throughout,
    # also after handing the reservations back (undense).
    k = jit.load()
    rng = random.Random(seed)
    g = Graph.grid(6, 5, obstacles=[(2, 2), (3, 2)])
    free = [v for v in range(g.n) if g.passable[v]]
    gr = jit._graph(g.adj)
    plain, own = Reservations(g.n), Reservations(g.n, dense_ok=True)
    ks = 6
    plain.sync([None] * ks)
    own.sync([None] * ks)
    checks = 0
    for step in range(400):
        if step == 5:
            d = jit._mirror(k, gr, own)
            assert own.dense is d and not own.vt
        if step == 300:
            own.undense()
            assert own.dense is None
        a = rng.randrange(ks)
        op = rng.random()
        for res in (plain, own):
            res.remove(a)
        if op < 0.8:
            p = walk(g, rng, free, rng.randint(0, 30))
            for res in (plain, own):
                res.add(a, p)
        r = rng.randrange(ks + 1)
        path = walk(g, rng, free, rng.randint(0, 30))
        skip = set(rng.sample(range(ks), rng.randint(0, 2)))
        want = plain.conflicts_of(r, path, skip)
        assert own.conflicts_of(r, path, skip) == want, step
        checks += bool(want)
        if own.dense is not None:
            vt, et = dense(plain, gr, own.dense.h)
            assert np.array_equal(own.dense.vt, vt) and np.array_equal(own.dense.et, et)
            assert own.dense.park_t.tolist() == plain.park_t
    assert own.vt == plain.vt and own.et == plain.et and own.parked == plain.parked
    assert checks > 50


def test_resync_to_other_agent_count_drops_the_kernels_parking():
    # A table the kernel holds (``parked`` empty, the parking in its copy) re-synced to a
    # different number of agents is rebuilt from the dicts: no parking time of the old
    # paths may stay behind (the review's reproducer: agent 0's parking at 1 did).
    jit.load()
    g = Graph.grid(4, 1)
    res = Reservations(g.n, dense_ok=True)
    res.add(0, (0, 1))
    cons = AgentConstraints.root(g.n, 3)
    jit.set_low_level("jit")
    try:
        astar.space_time_astar(g.adj, 2, 3, g.dist_list(3), cons, res=res)
    finally:
        jit.set_low_level(None)
    assert res.dense is not None
    res.sync([(3, 2), None, None])
    fresh = Reservations(g.n)
    fresh.add(0, (3, 2))
    assert res.park_t == fresh.park_t and res.parked == fresh.parked


def test_mirrors_follow_their_tables():
    # More tables than shared buffers, patched in turn (as CBS and its pair searches do):
    # whenever a table owns a buffer, the counts equal its paths.
    k = jit.load()
    rng = random.Random(7)
    g = Graph.grid(6, 5, obstacles=[(2, 2), (3, 2)])
    free = [v for v in range(g.n) if g.passable[v]]
    gr = jit._graph(g.adj)
    tables = [Reservations(g.n) for _ in range(jit.MIRRORS + 2)]
    for _ in range(200):
        res = rng.choice(tables)
        m = jit._mirror(k, gr, res)
        assert res.mirror is m and m.owner is res
        op = rng.random()
        if op < 0.1:
            res.sync([walk(g, rng, free, rng.randint(0, 9)) for _ in range(rng.randint(1, 4))])
        else:
            a = rng.randrange(4)
            res.remove(a)
            if op < 0.8:
                res.add(a, walk(g, rng, free, rng.randint(0, 80)))
        if res.mirror is None:  # sync with another agent count detaches
            m = jit._mirror(k, gr, res)
        vt, et = dense(res, gr, m.h)
        assert np.array_equal(m.vt, vt) and np.array_equal(m.et, et)
        assert m.park_t.tolist() == res.park_t
        others = [b for b in jit._mirrors if b is not m]
        assert all(b.owner is None or b.owner.mirror is b for b in others)


INSTANCES = ["empty-8-8-even-1:16", "random-32-32-20-random-1:20", "room-32-32-4-even-1:20"]


def test_cbs_identical_call_by_call(monkeypatch):
    # CBS end to end under the kernel, every low-level call re-run in Python: the same
    # results call by call (incl. the pair searches of WDG and the disjoint splits'
    # landmarks / forbid_from), so the node counts agree too; with the default splits
    # and with disjoint splitting.
    import hierplan_opt
    from hierplan_opt.bench import scenario

    seen = {"mdds": 0, "calls": 0, "landmarks": 0, "edge": 0, "forbid_from": 0, "cat": 0}
    run = jit.run

    def checked(k, adj, start, goal, dist, cons, res, dist_of, node_limit, **kw):
        got = run(k, adj, start, goal, dist, cons, res, dist_of, node_limit, **kw)
        if kw:
            moves = astar.Moves(adj, goal, dist, cons, dist_of)
            res = as_dicts(res)
            want = astar._search(adj, start, goal, dist, cons, res, node_limit, moves.succ, **kw)
            assert got == want
            seen["calls"] += 1
            seen["landmarks"] += bool(cons.landmarks)
            seen["edge"] += bool(cons.edge)
            seen["forbid_from"] += bool(cons.forbid_from)
            seen["cat"] += res is not None
        return got

    from hierplan_opt.search import mdd

    build = jit.build_mdd

    def checked_mdd(k, adj, start, goal, dist, cons, cost, dist_of):
        got = build(k, adj, start, goal, dist, cons, cost, dist_of)
        jit.set_low_level("python")
        want = mdd.build_mdd(adj, start, goal, dist, cons, cost, dist_of)
        jit.set_low_level("jit")
        assert ordered(jit.mdd_levels(got, cost, goal)) == ordered(want.levels)
        one = jit.mdd_singles(got, cost, goal)
        assert all(
            want.single(t, v) == (one[t] == v)
            for t in range(cost + 1)
            for v in (-1, *want.levels[t])
        )
        seen["mdds"] += 1
        return got

    conflicts_of = jit.DenseMirror.conflicts_of
    # The table of each dense mirror (a mirror keeps no reference back to its table).
    tables = {}
    mirror = jit._mirror

    def recorded(k, g, res):
        m = mirror(k, g, res)
        tables[id(m)] = res
        return m

    def checked_conflicts(self, r, path, skip):
        got = conflicts_of(self, r, path, skip)
        assert got == as_dicts(tables[id(self)]).conflicts_of(r, path, skip)
        seen["dense_conflicts"] += 1
        return got

    seen["dense_conflicts"] = 0
    stats = {}
    try:
        for mode in ("python", "jit"):
            jit.set_low_level(mode)
            monkeypatch.setattr(jit, "run", checked)
            monkeypatch.setattr(jit, "build_mdd", checked_mdd)
            monkeypatch.setattr(jit.DenseMirror, "conflicts_of", checked_conflicts)
            monkeypatch.setattr(jit, "_mirror", recorded)
            for i, spec in enumerate(INSTANCES):
                # Disjoint splitting (off by default) on one of them: its positive
                # constraints are where the landmarks come from.
                r = hierplan_opt.solve(
                    scenario(spec)[1], "cbs", time_limit=60, disjoint_splitting=i == 2
                )
                keys = ("high_level_expanded", "high_level_generated", "low_level_expanded")
                stats.setdefault(spec, []).append((r.cost, *(r.stats[x] for x in keys)))
    finally:
        jit.set_low_level(None)
    for spec, (py, jt) in stats.items():
        assert py == jt, spec
    assert seen["calls"] > 100 and seen["cat"] > 50 and seen["mdds"] > 100
    assert seen["dense_conflicts"] > 100
    assert min(seen["landmarks"], seen["edge"], seen["forbid_from"]) > 0, seen


def test_auto_switches_after_python_time(monkeypatch):
    # ``auto`` starts the compiler process once the Python low level has run JIT_AFTER_S
    # seconds, loads the kernel when it is done; the calls switch when it is ready.
    monkeypatch.setattr(jit, "_proc", None)
    monkeypatch.setattr(jit, "_cached", False)
    monkeypatch.setattr(jit, "_kernel", None)
    monkeypatch.setattr(jit, "_loading", False)
    monkeypatch.setattr(jit, "_failed", False)
    monkeypatch.setattr(jit, "python_seconds", 0.0)
    jit.set_low_level("auto")
    try:
        assert jit.kernel(1024) is None
        jit.note_python(jit.JIT_AFTER_S)
        proc = jit._proc
        assert proc is not None and jit.kernel(1024) is None
        assert proc.wait(300) == 0
        jit.note_python(0.0)
        assert jit.kernel(1024) is not None
        jit.new_solve()  # the next solve starts in Python again, kernel loaded or not
        n = 1024  # a 32x32 grid: loaded, it switches sooner (no pause to pay) ...
        assert jit.kernel(n) is None
        jit.note_python(n * jit.JIT_WARM_S_PER_VERTEX / 2)
        assert jit.kernel(n) is None
        jit.note_python(n * jit.JIT_WARM_S_PER_VERTEX)
        assert jit.kernel(n) is not None
        assert jit.kernel(16 * n) is None  # ... and later on a larger map
    finally:
        jit.set_low_level(None)


def test_small_solve_does_not_import_numba():
    code = (
        "import sys, hierplan_opt\n"
        "from hierplan_opt.bench import scenario\n"
        "r = hierplan_opt.solve(scenario('random-32-32-20-random-1:10')[1], 'cbs')\n"
        "assert r.plan is not None\n"
        "assert 'numba' not in sys.modules, 'numba imported'\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert out.returncode == 0, out.stderr


def test_bad_mode():
    from hierplan_opt.core.errors import OptionError

    with pytest.raises(OptionError, match="low level"):
        jit.set_low_level("fast")


def test_a_solve_leaves_no_dense_table_behind():
    # CBS's table hands its paths to a DenseMirror under the kernel. The mirror keeps
    # no reference back to the table: with the cyclic collector off, both are freed when
    # the solve returns (a cycle kept tens of MB a solve until a full collection), and
    # the arrays kept per distance list are dropped when the next solve starts.
    import gc

    import hierplan_opt
    from hierplan_opt.bench import scenario

    def mirrors() -> int:
        return sum(isinstance(o, jit.DenseMirror) for o in gc.get_objects())

    jit.set_low_level("jit")
    gc.collect()
    gc.disable()
    try:
        before = mirrors()
        r = hierplan_opt.solve(scenario("room-32-32-4-even-1:10")[1], "cbs", time_limit=60)
        assert r.plan is not None and jit._ARRAYS
        assert mirrors() == before
        jit.new_solve()
        assert not jit._ARRAYS and not jit._CONS
    finally:
        gc.enable()
        jit.set_low_level(None)


def test_graphs_of_one_map_share_their_lists():
    # Graphs with the same edges share ``adj`` (so the kernel's arrays kept per ``adj``
    # are made once per map); others do not; only the last few maps are kept.
    from hierplan_opt.core import graph as core_graph

    a, b = Graph.grid(5, 4), Graph.grid(5, 4)
    assert a.adj is b.adj and a.dist_list(3) is not b.dist_list(3)
    assert Graph.grid(4, 5).adj is not a.adj and Graph.grid(4, 5).adj == Graph.grid(4, 5).adj
    blocked = Graph.grid(5, 4, obstacles=[(2, 2)])
    assert blocked.adj is not a.adj and blocked.adj[2 + 5 * 2] == []
    for w in range(6, 6 + core_graph.SHARED_ADJ_GRAPHS):
        Graph.grid(w, 2).adj  # noqa: B018 - fills the shared lists
    assert Graph.grid(5, 4).adj is not a.adj  # the oldest was dropped
    jit._graph(a.adj)
    assert jit._graph(b.adj) is jit._graph(a.adj)


@pytest.mark.parametrize("seed", range(3))
def test_compiled_distance_tables_equal_the_bfs(seed, monkeypatch):
    # Once the kernels are loaded, Graph.fill_distances makes its tables with the
    # compiled BFS (undirected graphs): the same distances as the Python BFS, unreachable
    # cells and blocked targets included; the hook is the kernel's.
    from hierplan_opt.core import graph as core_graph
    from hierplan_opt.core.graph import _bfs

    k = jit.load()
    assert core_graph._compiled_bfs is k.bfs_many
    calls = []

    def counted(*args):
        calls.append(1)
        return k.bfs_many(*args)

    monkeypatch.setattr(core_graph, "_compiled_bfs", counted)
    expected = 0
    rng = random.Random(seed)
    for _ in range(10):
        w, h = rng.randint(2, 14), rng.randint(1, 10)
        obst = [(rng.randrange(w), rng.randrange(h)) for _ in range(rng.randint(0, w * h // 3))]
        g = Graph.grid(w, h, obstacles=obst)
        targets = rng.sample(range(g.n), min(g.n, 6))
        expected += not g._open_grid  # (an open grid's tables are Manhattan distances)
        assert g.fill_distances(targets)
        for t in targets:
            assert g.dist_list(t) == _bfs(g.adj, t)
            assert g.dist_to(t).tolist() == g.dist_list(t)
    assert len(calls) == expected > 0


@pytest.mark.parametrize("seed", range(4))
def test_mdd_dependence_identical(seed):
    # The compiled dependence test on two MDDs' arrays gives the Python test's answer
    # (on the same MDDs as levels) for random pairs, dependent and independent ones.
    from hierplan_opt.search import heuristics, mdd

    k = jit.load()
    rng = random.Random(seed)
    seen = {True: 0, False: 0}
    for _ in range(60):
        w, h = rng.randint(2, 7), rng.randint(1, 5)
        obst = [(rng.randrange(w), rng.randrange(h)) for _ in range(rng.randint(0, w * h // 5))]
        g = Graph.grid(w, h, obstacles=obst)
        free = [v for v in range(g.n) if g.passable[v]]
        if len(free) < 3:
            continue
        mdds = []
        for _ in range(2):
            s, t = rng.sample(free, 2)
            d = g.dist_list(t)
            if d[s] >= 1 << 30:
                break
            cost = d[s] + rng.randint(0, 2)
            raw = jit.build_mdd(k, g.adj, s, t, d, AgentConstraints(), cost, None)
            mdds.append((raw, cost, t))
        if len(mdds) < 2:
            continue
        (ra, ca, ta), (rb, cb, tb) = mdds
        got = jit.mdd_dependent(ra, ca, ta, rb, cb, tb, k)
        la = mdd.MDD(jit.mdd_levels(ra, ca, ta), ca, ta)
        lb = mdd.MDD(jit.mdd_levels(rb, cb, tb), cb, tb)
        assert got == heuristics.dependent(la, lb)
        assert got == heuristics.dependent(mdd.MDD(None, ca, ta, ra), mdd.MDD(None, cb, tb, rb))
        seen[got] += 1
    assert min(seen.values()) > 3, seen
