"""One successor rule for the four space-time searches (issue 31).

The A* (pure Python and compiled), the MDD builders, the focal search and the
highway-inflated focal search each expand states in their own hot loop, written out for
speed; these tests tie the loops to the one rule, :class:`~hierplan_opt.search.
spacetime.Moves` (which move is allowed at which time, with which lower bound):

* the compiled kernel's rule (``_move_h`` with ``_landmark``, the one its A* and its MDD
  builder call) gives exactly ``Moves.at`` for every state of random instances and
  constraint sets;
* the Python A*'s path takes only moves of ``Moves``, lies in the MDD of its cost, and
  no path of one step less exists (the MDD of that cost is empty);
* the focal searches' shared rule (``focal.scored_moves``, ``park_conflicts``) allows
  the moves of ``Moves`` and counts conflicts as the other agents' paths say;
* the focal search at ``w = 1`` and the inflated search with every edge costing 1 find
  the A*'s cost under the same vertex and edge constraints, with or without other
  agents' paths to count conflicts with.

The kernel and the Python A* / MDDs are compared call by call in
``tests/test_jit_astar.py`` (same paths, expansions and levels).
"""

from __future__ import annotations

import random

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
)
from hierplan_opt.search.focal import focal_path, park_conflicts, scored_moves
from hierplan_opt.search.highways import inflated_focal_path
from hierplan_opt.search.mdd import build_mdd
from hierplan_opt.search.reservations import Reservations
from hierplan_opt.search.spacetime import Moves, lazy_successors, successor, successors


def grid(rng: random.Random) -> tuple[Graph, list[int]]:
    w, h = rng.choice([(4, 4), (5, 3), (6, 5)])
    obst = [(rng.randrange(w), rng.randrange(h)) for _ in range(rng.randint(0, w * h // 5))]
    g = Graph.grid(w, h, obstacles=obst)
    return g, [v for v in range(g.n) if g.passable[v]]


def constraints(
    g: Graph, rng: random.Random, free: list[int], goal: int, kinds: tuple[str, ...]
) -> AgentConstraints:
    c = AgentConstraints.root(g.n, goal)
    for _ in range(rng.randint(0, 8)):
        kind = rng.choice(kinds)
        v = rng.choice(free)
        nb = rng.choice([*g.adj[v], v])
        t = rng.randint(1, 9)
        if kind == "v":
            c = c.add((NEG_V, 0, v, -1, t), n=g.n, goal=goal)
        elif kind == "e":
            c = c.add((NEG_E, 0, v, nb, t), n=g.n, goal=goal)
        elif kind == "range":
            c = c.add((NEG_RANGE, 0, v, t, t + 2), n=g.n, goal=goal)
        elif kind == "pos_v" and rng.random() < 0.4:
            c = c.add((POS_V, 0, v, -1, t), n=g.n, goal=goal)
        elif kind == "pos_e" and rng.random() < 0.4:
            c = c.add((POS_E, 0, v, nb, t), n=g.n, goal=goal)
        elif kind == "gt":
            c = c.add((LEN_GT, 0, -1, -1, t), n=g.n, goal=goal)
        elif kind == "le":
            c = c.add((LEN_LE, 0, -1, -1, t + 6), n=g.n, goal=goal)
    return c


ALL_KINDS = ("v", "v", "e", "range", "pos_v", "pos_e", "gt", "le")
FOCAL_KINDS = ("v", "v", "e")  # the focal searches take vertex and edge constraints only


@pytest.mark.parametrize("seed", range(25))
def test_kernel_rule_is_moves(seed):
    k = jit.load()
    rng = random.Random(seed)
    g, free = grid(rng)
    if len(free) < 3:
        return
    for _ in range(4):
        s, goal = rng.sample(free, 2)
        cons = constraints(g, rng, free, goal, ALL_KINDS)
        dist = g.dist_list(goal)
        moves = Moves(g.adj, goal, dist, cons, g.dist_list)
        kg, args, _ = jit._search_args(g.adj, s, goal, dist, cons, moves.nxt, 0)
        ptr, idx, darr = kg.ptr, kg.idx, args[2]
        vkeys, ekeys, ff, lm_need, nxt_tl, nxt_hb, nxt_row, lmd, minf = args[6:]
        for t in range(1, cons.tmax + 4):
            need, lrow, ltl, lhb = k._landmark(t, lm_need, nxt_row, nxt_tl, nxt_hb)
            for v in free:
                kernel = []
                for j in range(ptr[v], ptr[v + 1]):
                    u = int(idx[j])
                    hu = k._move_h(
                        u, v, t, g.n, need, lrow, ltl, lhb, vkeys, ekeys, ff, darr, lmd, minf,
                        UNREACHABLE,
                    )  # fmt: skip
                    if hu >= 0:
                        kernel.append((u, int(hu)))
                assert kernel == moves.at(v, t), (seed, v, t)


@pytest.mark.parametrize("seed", range(40))
def test_astar_moves_and_mdd_agree(seed):
    rng = random.Random(100 + seed)
    g, free = grid(rng)
    if len(free) < 3:
        return
    jit.set_low_level("python")
    try:
        for _ in range(5):
            s, goal = rng.sample(free, 2)
            cons = constraints(g, rng, free, goal, ALL_KINDS)
            dist = g.dist_list(goal)
            path, _ = astar.space_time_astar(g.adj, s, goal, dist, cons, dist_of=g.dist_list)
            if path is None:
                continue
            cost = len(path) - 1
            moves = Moves(g.adj, goal, dist, cons, g.dist_list)
            for t in range(1, cost + 1):
                assert path[t] in [u for u, _ in moves.at(path[t - 1], t)], (seed, t)
            m = build_mdd(g.adj, s, goal, dist, cons, cost, g.dist_list)
            assert all(m.has(t, v) for t, v in enumerate(path))
            if cost >= 2:  # one step less: no path (the MDD of that cost is empty)
                less = build_mdd(g.adj, s, goal, dist, cons, cost - 1, g.dist_list)
                assert not less.levels[0], seed
    finally:
        jit.set_low_level(None)


@pytest.mark.parametrize("seed", range(40))
def test_focal_and_inflated_find_the_astar_cost(seed):
    rng = random.Random(200 + seed)
    g, free = grid(rng)
    if len(free) < 3:
        return
    res = Reservations(g.n)
    for a in range(rng.randint(0, 4)):
        res.add(a, walk(g, rng, free, rng.randint(0, 10)))
    every_edge = frozenset((v, u) for v in range(g.n) for u in g.adj[v])
    jit.set_low_level("python")
    try:
        for _ in range(5):
            s, goal = rng.sample(free, 2)
            cons = constraints(g, rng, free, goal, FOCAL_KINDS)
            dist = g.dist_list(goal)
            path, _ = astar.space_time_astar(g.adj, s, goal, dist, cons, res=res)
            found = focal_path(g.adj, s, goal, dist, cons, res, w=1.0)
            if path is None:
                assert found is None, seed
                continue
            cost = len(path) - 1
            assert found is not None and len(found[0]) - 1 == cost and found[1] == cost
            bounded = focal_path(g.adj, s, goal, dist, cons, res, w=1.5)
            assert bounded is not None and bounded[1] <= cost
            assert len(bounded[0]) - 1 <= 1.5 * bounded[1] + 1e-9
            # Every move (and wait) costs 1: the inflated search is the same problem.
            h = np.array([float(x) if x < UNREACHABLE else np.inf for x in dist])
            infl = inflated_focal_path(g.adj, s, goal, h, every_edge, 1.0, cons, res, w=1.0)
            assert infl is not None and len(infl[0]) - 1 == cost and infl[1] == cost
    finally:
        jit.set_low_level(None)


def brute_conflicts(paths: list[tuple[int, ...]], v: int, u: int, nt: int) -> int:
    """Conflicts of the move ``v -> u`` arriving at ``nt`` with ``paths`` (parked at
    their last vertex forever), counted from the paths themselves."""
    c = 0
    for p in paths:
        at = p[nt] if nt < len(p) else p[-1]
        if at == u:
            c += 1  # on u at nt (moving there or parked there)
        elif u != v and nt < len(p) and p[nt - 1] == u and p[nt] == v:
            c += 1  # swap
    return c


@pytest.mark.parametrize("seed", range(20))
def test_scored_moves_is_the_rule_and_counts_conflicts(seed):
    """The focal searches' shared rule (``focal.scored_moves``, used by the focal loop
    and the inflated search) allows exactly the moves of ``Moves`` (vertex and edge
    constraints, goal reachable), counts each move's conflicts as the paths say, and
    ``park_conflicts`` counts every later visit to the goal."""
    rng = random.Random(500 + seed)
    g, free = grid(rng)
    if len(free) < 3:
        return
    res = Reservations(g.n)
    paths = []
    for a in range(rng.randint(1, 4)):
        p = walk(g, rng, free, rng.randint(0, 10))
        if p[-1] in {q[-1] for q in paths}:
            continue  # one agent parked per vertex
        res.add(a, p)
        paths.append(p)
    succ = successors(g.adj)
    for _ in range(3):
        goal = rng.choice(free)
        cons = constraints(g, rng, free, goal, FOCAL_KINDS)
        dist = g.dist_list(goal)
        moves = Moves(g.adj, goal, dist, cons)
        goal_times = res.visits(goal)
        for v in free:
            for nt in range(1, 14):
                got = scored_moves(
                    succ[v], v, nt, g.n, 5, cons.vertex, cons.edge, res.vt, res.et, res.park_t
                )
                allowed = [u for u, _ in moves.at(v, nt)]
                assert [u for u, _ in got if dist[u] < UNREACHABLE] == allowed, (seed, v, nt)
                for u, c in got:
                    assert c == 5 + brute_conflicts(paths, v, u, nt), (seed, v, u, nt)
                # visits along the paths (an agent parked at the goal is one conflict
                # of the move there, counted above)
                later = sum(1 for p in paths for t in range(nt + 1, len(p)) if p[t] == goal)
                assert park_conflicts(0, nt, goal_times) == later, (seed, nt)


@pytest.mark.parametrize("seed", range(20))
def test_focal_loop_counts_as_scored_moves(seed):
    """The focal loop writes ``scored_moves`` / ``park_conflicts`` out (speed): a path it
    returns with ``avoid`` (conflicts forbidden) takes only moves the shared rule allows
    and has no conflict by its counts."""
    rng = random.Random(900 + seed)
    g, free = grid(rng)
    if len(free) < 3:
        return
    res = Reservations(g.n)
    ends: set[int] = set()
    for a in range(rng.randint(1, 4)):
        p = walk(g, rng, free, rng.randint(0, 10))
        if p[-1] not in ends:
            res.add(a, p)
            ends.add(p[-1])
    succ = successors(g.adj)
    for _ in range(5):
        open_cells = [v for v in free if v not in ends]
        if len(open_cells) < 2:
            return
        s, goal = rng.sample(open_cells, 2)
        cons = constraints(g, rng, free, goal, FOCAL_KINDS)
        dist = g.dist_list(goal)
        found = focal_path(g.adj, s, goal, dist, cons, res, avoid=True)
        if found is None:
            continue
        path = found[0]
        c = 0
        for t in range(1, len(path)):
            moves = dict(
                scored_moves(
                    succ[path[t - 1]], path[t - 1], t, g.n, c, cons.vertex, cons.edge,
                    res.vt, res.et, res.park_t,
                )
            )  # fmt: skip
            assert path[t] in moves, (seed, t)
            c = moves[path[t]]
        assert park_conflicts(c, len(path) - 1, res.visits(goal)) == 0, seed


def test_lazy_successors_equal_the_full_lists_and_are_keyed_by_the_adjacency(monkeypatch):
    """``Moves`` and the A* read :func:`lazy_successors` (an entry made when a search
    first expands its vertex: a short search touches few cells): every entry made equals
    :func:`successors`' one (the order the A* and the kernel's CSR lists try moves in),
    one list per adjacency object, and a new graph with the same cells, or a copy of the
    lists, gets its own list, not the first one's entries."""
    from hierplan_opt.search import spacetime

    # An empty cache: it holds 17 adjacencies at most (earlier tests' would push ours out).
    monkeypatch.setattr(spacetime, "_LAZY", {})
    g = Graph.grid(5, 4, obstacles=[(1, 1), (3, 2)])
    lazy = lazy_successors(g.adj)
    assert lazy == [None] * g.n  # nothing made before a search asks
    assert lazy_successors(g.adj) is lazy
    full = successors(g.adj)
    assert successor(lazy, g.adj, 6) == full[6] and lazy[6] == full[6]
    assert sum(x is not None for x in lazy) == 1
    for v in range(g.n):
        assert successor(lazy, g.adj, v) == full[v]
    assert lazy == full
    other = Graph.grid(5, 4, obstacles=[(2, 2)])
    assert other.adj is not g.adj
    assert lazy_successors(other.adj) is not lazy
    assert successor(lazy_successors(other.adj), other.adj, 7) == (*other.adj[7], 7) != lazy[7]
    copy = [list(nb) for nb in g.adj]  # equal to an adjacency but another object
    assert lazy_successors(copy) is not lazy
    assert Moves(g.adj, 0, g.dist_list(0), AgentConstraints.root(g.n, 0)).succ is lazy
    # The moves of a fresh graph's first search fill only the entries it expands.
    h = Graph.grid(6, 6)
    path, expanded = astar.space_time_astar(
        h.adj, 0, 7, h.dist_list(7), AgentConstraints.root(h.n, 7)
    )
    made = [v for v, x in enumerate(lazy_successors(h.adj)) if x is not None]
    assert path is not None and 0 < len(made) <= expanded < h.n


@pytest.mark.parametrize("seed", range(10))
def test_astar_with_lazy_successors_equals_the_full_lists(seed):
    """The Python A* loop on the lazy table finds the same path with the same expansion
    count as on the full list of :func:`successors` (the rule before the change)."""
    rng = random.Random(3100 + seed)
    g, free = grid(rng)
    if len(free) < 3:
        return
    res = Reservations(g.n)
    for a in range(rng.randint(0, 3)):
        res.add(a, walk(g, rng, free, rng.randint(0, 8)))
    jit.set_low_level("python")
    try:
        for _ in range(4):
            s, goal = rng.sample(free, 2)
            cons = constraints(g, rng, free, goal, ALL_KINDS)
            dist = g.dist_list(goal)
            if cons.infeasible or dist[s] >= UNREACHABLE:
                continue  # space_time_astar's early exits: the loop never runs
            moves = Moves(g.adj, goal, dist, cons, g.dist_list)
            args = (g.adj, s, goal, dist, cons, res, None)
            tail = (moves.nxt, moves.horizon(), moves.h0(s))
            lazy = astar._search(*args, lazy_successors(g.adj), *tail)  # type: ignore[arg-type]
            full = astar._search(*args, successors(g.adj), *tail)  # type: ignore[arg-type]
            assert lazy == full, (seed, s, goal)
    finally:
        jit.set_low_level(None)
