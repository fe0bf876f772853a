"""The compiled focal search (numba) against the pure-Python one: identical results."""

from __future__ import annotations

import random

import pytest
from spacetime_cases import walk

from hierplan_opt.core.graph import UNREACHABLE, Graph
from hierplan_opt.core.timer import Deadline
from hierplan_opt.search import focal, jit
from hierplan_opt.search.constraints import NEG_E, NEG_V, AgentConstraints
from hierplan_opt.search.reservations import Reservations
from hierplan_opt.search.spacetime import SearchTimeout, successors


def random_grid(rng: random.Random) -> tuple[Graph, list[int]]:
    """A small grid with random obstacles, and its free vertices."""
    w, h = rng.choice([(5, 4), (6, 6), (8, 3), (7, 7)])
    obst = [(rng.randrange(w), rng.randrange(h)) for _ in range(rng.randint(0, w * h // 5))]
    g = Graph.grid(w, h, obstacles=obst)
    return g, [v for v in range(g.n) if g.passable[v]]


def random_cons(g: Graph, rng: random.Random, free: list[int], goal: int) -> AgentConstraints:
    """Vertex and edge constraints (the kinds the focal search takes), some on the goal."""
    c = AgentConstraints.root(g.n, goal)
    for _ in range(rng.randint(0, 10)):
        v = goal if rng.random() < 0.2 else rng.choice(free)
        t = rng.randint(1, 12)
        if rng.random() < 0.6:
            c = c.add((NEG_V, 0, v, -1, t), n=g.n, goal=goal)
        else:
            c = c.add((NEG_E, 0, v, rng.choice([*g.adj[v], v]), t), n=g.n, goal=goal)
    return c


def both(*args, **kw):
    """``focal_path`` under each low level: ``[(result, expansions)] * 2``, or the
    exception type each raised."""
    out = []
    for mode in ("python", "jit"):
        jit.set_low_level(mode)
        assert (jit.focal_kernel(16) is not None) == (mode == "jit")
        stats: dict[str, int] = {}
        try:
            got = focal.focal_path(*args, stats=stats, **kw)
            out.append((got, stats.get("low_level_expanded")))
        except SearchTimeout:
            out.append(("timeout", stats.get("low_level_expanded")))
    jit.set_low_level(None)
    return out


@pytest.fixture(autouse=True)
def _restore_mode():
    yield
    jit.set_low_level(None)


def test_kernel_constants_agree():
    jit.load()
    fk = jit._focal
    assert fk is not None
    assert (fk.TIE, fk.PARTNER_WEIGHT) == (focal._TIE, focal.PARTNER_WEIGHT)


@pytest.mark.parametrize("seed", range(80))
def test_random_calls_identical(seed):
    # Random constraints, reservations (tie-breaking, swaps, parked agents), partner,
    # avoid, budget (the fallback order), limit, max_t and w: same path, same lb, same
    # expansion count; the table is patched between calls as ECBS does.
    rng = random.Random(seed)
    g, free = random_grid(rng)
    if len(free) < 3:
        return
    res = Reservations(g.n)
    n_agents = rng.randint(0, 7)
    for a in range(n_agents):
        if rng.random() < 0.85:
            res.add(a, walk(g, rng, free, rng.randint(0, 16)))
    checked = 0
    for _ in range(10):
        s, t = rng.sample(free, 2) if rng.random() < 0.9 else [rng.choice(free)] * 2
        c = random_cons(g, rng, free, t)
        kw = {
            "w": rng.choice([1.0, 1.0, 1.1, 1.2, 1.5, 2.0]),
            "budget": rng.choice([focal.DEFAULT_BUDGET, -1, 1, 3, 10, 40]),
            "avoid": rng.random() < 0.25,
            "limit": rng.choice([-1, -1, -1, 1, 5, 30]),
            "partner": rng.choice([-1, -1, *range(n_agents + 1)]),
            "max_t": rng.choice([None, None, 6, 12, 30]),
        }
        py, jt = both(g.adj, s, t, g.dist_list(t), c, res, **kw)
        assert py == jt, (seed, s, t, kw)
        checked += py[0] is not None
        a = rng.randrange(n_agents + 1)
        if a < len(res.paths):
            res.remove(a)
        if rng.random() < 0.7:
            res.add(a, walk(g, rng, free, rng.randint(0, 18)))
    assert checked or seed % 7 != 3  # most seeds find paths (one fixed seed must)


@pytest.mark.parametrize("seed", range(20))
def test_inconsistent_heuristic_identical(seed):
    # A heuristic that is not consistent (as the highway one, mode "heuristic"): f drops
    # along paths, f_min is raised past live states below it; still identical.
    rng = random.Random(900 + seed)
    g, free = random_grid(rng)
    if len(free) < 3:
        return
    res = Reservations(g.n)
    for a in range(rng.randint(0, 5)):
        res.add(a, walk(g, rng, free, rng.randint(0, 14)))
    for _ in range(6):
        s, t = rng.sample(free, 2)
        d = g.dist_list(t)
        h = [x if x >= UNREACHABLE else x * rng.choice([1, 1, 2, 3]) for x in d]
        h[t] = 0
        c = random_cons(g, rng, free, t)
        kw = {"w": rng.choice([1.0, 1.3, 2.0]), "budget": rng.choice([-1, 5, 50])}
        py, jt = both(g.adj, s, t, h, c, res, **kw)
        assert py == jt, (seed, kw)


@pytest.mark.parametrize(("start", "far"), [(0, 4), (0, 0)])
def test_unreachable_heuristic_falls_back_to_python(start, far):
    # A reachable vertex at an "unreachable" distance (here a neighbour of the start, or
    # the start itself): the kernel declines the call (its f tables are dense) and the
    # Python loop answers, so the results still agree.
    g = Graph.grid(4, 2)
    h = list(g.dist_list(3))
    h[far] = UNREACHABLE
    res = Reservations(g.n)
    c = AgentConstraints.root(g.n, 3)
    jit.load()
    assert jit._focal is not None
    direct = jit.run_focal(
        jit._focal, g.adj, start, 3, h, c, res, hold=0, max_t=6, partner=-1, w=1.0,
        deadline=None, budget=-1, avoid=False, limit=-1,
    )  # fmt: skip
    assert direct is None
    py, jt = both(g.adj, start, 3, h, c, res, max_t=6)
    assert py == jt and py[0] is not None


def test_head_on_and_partner_tables_identical():
    # Others walking the agent's own shortest path backwards (many swaps) and one of
    # them the partner (its swaps, visits and parking weigh PARTNER_WEIGHT).
    rng = random.Random(7)
    for _ in range(40):
        g, free = random_grid(rng)
        if len(free) < 3:
            continue
        s, t = rng.sample(free, 2)
        jit.set_low_level("python")
        p = focal.focal_path(g.adj, s, t, g.dist_list(t), AgentConstraints(), Reservations(g.n))
        if p is None:
            continue
        res = Reservations(g.n)
        back = tuple(reversed(p[0]))
        res.add(0, back[rng.randint(0, 1) :])
        res.add(1, back + (back[-1],) * rng.randint(0, 3))
        res.add(2, walk(g, rng, free, rng.randint(0, 12)))
        for partner in (-1, 0, 1, 2):
            py, jt = both(g.adj, s, t, g.dist_list(t), AgentConstraints(), res, partner=partner)
            assert py == jt


def test_deadline_raises_at_the_same_check():
    # An expired deadline: a search longer than 1024 expansions (the check's
    # granularity) raises SearchTimeout in both; one that ends sooner returns its result.
    g = Graph.grid(12, 12)
    res = Reservations(g.n)
    res.add(0, (143,) * 3)  # parked on the goal: with avoid, no path to find
    args = (g.adj, 0, 143, g.dist_list(143), AgentConstraints(), res)
    py, jt = both(*args, deadline=Deadline(0), avoid=True, max_t=60)
    assert py[0] == jt[0] == "timeout"
    py, jt = both(*args, deadline=Deadline(0), max_t=60)
    assert py == jt and py[0] is not None and py[0] != "timeout"
    # ... and without a deadline the long call runs to its end (no path) in both
    py, jt = both(*args, avoid=True, max_t=60)
    assert py == jt and py[0] is None and py[1] > 1024


def test_kernel_clock_is_perf_counter():
    from time import perf_counter

    jit.load()
    assert jit._focal is not None
    a = perf_counter()
    b = jit._focal.monotonic()
    c = perf_counter()
    assert a <= b <= c


def test_successors_layout_is_the_kernels():
    # The kernel walks the CSR lists of jit._graph: the same order as successors().
    g = Graph.grid(4, 3, obstacles=[(1, 1)])
    csr = jit._graph(g.adj)
    succ = successors(g.adj)
    assert [tuple(csr.idx[csr.ptr[v] : csr.ptr[v + 1]].tolist()) for v in range(g.n)] == succ


ECBS_INSTANCES = [
    "random-32-32-20-random-1:40",
    "warehouse-10-20-10-2-1-even-1:40",
    "room-32-32-4-even-1:20",
]


def test_ecbs_eecbs_identical_call_by_call(monkeypatch):
    # ECBS and EECBS end to end under the kernel, every focal call re-run in the Python
    # loop on the same table: the same results call by call (incl. the polish pass's
    # avoid / limit calls and the partner weights), so the plans and node counts of the
    # two low levels agree.
    import hierplan_opt
    from hierplan_opt.bench import scenario

    seen = {"calls": 0, "partner": 0, "avoid": 0, "cons": 0}
    run = jit.run_focal

    def checked(fk, adj, start, goal, dist, cons, res, **kw):
        got = run(fk, adj, start, goal, dist, cons, res, **kw)
        partner = kw["partner"]
        pp = res.paths[partner] if 0 <= partner < len(res.paths) else None
        want = focal._focal_loop(
            successors(adj), len(adj), start, goal, dist, cons.vertex, cons.edge, kw["hold"],
            kw["max_t"], res.visits(goal), res.vt, res.et, res.park_t, partner,
            pp[-1] if pp else -1, [t for t, x in enumerate(pp) if x == goal] if pp else [],
            kw["w"], None, kw["budget"], kw["avoid"], kw["limit"],
        )  # fmt: skip
        assert got == want
        seen["calls"] += 1
        seen["partner"] += pp is not None
        seen["avoid"] += kw["avoid"]
        seen["cons"] += bool(cons.vertex or cons.edge)
        return got

    rows: dict[tuple[str, str], list[tuple[object, ...]]] = {}
    for mode in ("python", "jit"):
        jit.set_low_level(mode)
        monkeypatch.setattr(jit, "run_focal", checked)
        for spec in ECBS_INSTANCES:
            inst = scenario(spec)[1]
            for name in ("ecbs", "eecbs"):
                r = hierplan_opt.solve(inst, name, time_limit=60, w=1.2)
                keys = ("high_level_expanded", "high_level_generated", "low_level_expanded")
                plan = r.plan.paths if r.plan is not None else None
                rows.setdefault((spec, name), []).append(
                    (r.cost, plan, *(r.stats[x] for x in keys))
                )
    for key, (py, jt) in rows.items():
        assert py == jt, key
    # (the partner weights are rare on instances this small: the random calls cover them)
    assert seen["calls"] > 200 and seen["avoid"] > 0 and seen["cons"] > 0, seen


def test_focal_python_time_counts_toward_the_switch(monkeypatch):
    noted: list[float] = []
    monkeypatch.setattr(jit, "note_python", noted.append)
    jit.set_low_level("python")
    g = Graph.grid(3, 1)
    focal.focal_path(g.adj, 0, 2, g.dist_list(2), AgentConstraints(), Reservations(g.n))
    assert len(noted) == 1 and noted[0] > 0


def test_auto_switches_focal_calls_per_solve(monkeypatch):
    # ``auto`` with the kernel loaded: a solve starts in Python (ECBS resets the count),
    # and the calls go to the kernel once the Python low level has run
    # JIT_WARM_S_PER_VERTEX seconds per vertex of the map.
    import hierplan_opt

    jit.load()
    used: list[int] = []
    run = jit.run_focal

    def counted(*args, **kw):
        used.append(1)
        return run(*args, **kw)

    monkeypatch.setattr(jit, "run_focal", counted)
    # An earlier solve's 10 s would switch at once (over the threshold, here 5 s on the
    # 16 vertices so that a slow machine does not reach it within this solve)
    monkeypatch.setattr(jit, "JIT_WARM_S_PER_VERTEX", 5.0 / 16)
    monkeypatch.setattr(jit, "python_seconds", 10.0)
    jit.set_low_level("auto")
    g = Graph.grid(4, 4)
    inst = hierplan_opt.Instance.mapf(g, [(0, 0), (3, 0)], [(3, 0), (0, 0)])
    r = hierplan_opt.solve(inst, "eecbs", w=1.2)
    assert r.plan is not None and not used  # a short solve: Python only
    jit.note_python(5.0)
    focal.focal_path(g.adj, 0, 3, g.dist_list(3), AgentConstraints(), Reservations(g.n))
    assert used == [1]


def test_highway_heuristic_identical():
    # ECBS with the highway heuristic (not consistent: f drops along paths) as the
    # focal search's distances: the same plans and node counts under both low levels.
    import hierplan_opt
    from hierplan_opt.bench import scenario

    inst = scenario("random-32-32-20-random-1:20")[1]
    out = []
    for mode in ("python", "jit"):
        jit.set_low_level(mode)
        r = hierplan_opt.solve(
            inst, "ecbs", time_limit=60, w=1.2, highways="crisscross", w_hwy=2.0,
            hwy_mode="heuristic",
        )  # fmt: skip
        keys = ("high_level_expanded", "high_level_generated", "low_level_expanded")
        out.append((r.cost, r.plan.paths if r.plan else None, *(r.stats[k] for k in keys)))
    assert out[0] == out[1] and out[0][1] is not None


def test_tables_grow_mid_search_identical():
    # A search far longer and deeper than the kernel's first tables (states, entries,
    # hash slots and the f tables, which start at 2 f0 + 64 for f0 = 1 here): the kernel
    # hands back to grow them several times and still ends as the Python loop does.
    g = Graph.grid(12, 12)
    res = Reservations(g.n)
    res.add(0, (143,) * 3)  # parked on the goal: with avoid, no path to find
    args = (g.adj, 142, 143, g.dist_list(143), AgentConstraints(), res)
    for kw in ({"avoid": True, "max_t": 120}, {"avoid": True, "max_t": 120, "w": 1.5}):
        py, jt = both(*args, **kw)
        assert py == jt and py[0] is None and py[1] > 10_000
    res.remove(0)
    res.add(0, (143,) * 90 + (131,))  # leaves the goal at t = 90: a path, found late
    py, jt = both(*args, avoid=True, max_t=120)
    assert py == jt and py[0] is not None and len(py[0][0]) == 91


def test_python_focal_admits_a_far_f_jump_from_its_buckets(monkeypatch: pytest.MonkeyPatch):
    """A state at an "unreachable" distance (f about 2^30) once raised the bound through
    every integer up to it (minutes); now the waiting buckets themselves are admitted.
    The kernel declines such calls, so this is the Python loop's path."""
    import signal

    def hang(*_: object) -> None:
        raise AssertionError("the bound was raised one integer at a time")

    monkeypatch.setattr(jit, "focal_kernel", lambda n: None)
    old = signal.signal(signal.SIGALRM, hang)
    signal.alarm(20)
    try:
        g = Graph.grid(3, 1)
        out = focal.focal_path(
            g.adj, 0, 2, [2, UNREACHABLE, 0], AgentConstraints(), Reservations(3), max_t=6
        )
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, old)
    assert out == ((0, 1, 2), UNREACHABLE + 1)


def test_stale_cache_entries_of_the_focal_kernel_are_dropped(tmp_path):
    # numba checks a cached function against its own file only; the focal kernel calls
    # leaves of _astar_kernel.py, so jit.load drops its entries older than that file.
    import os
    import types

    source = tmp_path / "_astar_kernel.py"
    source.write_text("")
    index = tmp_path / "_focal_kernel._loop.nbi"
    index.write_text("")
    os.utime(index, (1_000_000, 1_000_000))  # cached long before the source's edit
    flushed = []

    class Cache:
        _cache_file = types.SimpleNamespace(_index_path=str(index))

        def flush(self):
            flushed.append(self)

    def kernel(name, module):
        py = types.FunctionType((lambda: None).__code__, {}, name)
        py.__module__ = module
        return types.SimpleNamespace(py_func=py, _cache=Cache())

    fake = types.ModuleType("fake_focal")
    loop = kernel("_loop", "fake_focal")
    # _contains is imported from another file there: that file's cache decides
    fake.__dict__.update(_loop=loop, _contains=kernel("_contains", "elsewhere"))
    assert jit.drop_stale_cache(fake, str(source)) == 1
    assert flushed == [loop._cache]
    os.utime(index, None)  # compiled after the edit: kept
    os.utime(source, (1_000_000, 1_000_000))
    assert jit.drop_stale_cache(fake, str(source)) == 0
    assert jit.drop_stale_cache(fake, str(tmp_path / "missing.py")) == 0
