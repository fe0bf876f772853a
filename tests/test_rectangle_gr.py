"""Generalised rectangle reasoning (symmetry.generalized_rectangle_split) in CBS."""

from __future__ import annotations

import random

import pytest

import hierplan_opt
from hierplan_opt.core.graph import Graph
from hierplan_opt.core.instance import Instance
from hierplan_opt.core.result import Status
from hierplan_opt.search.constraints import NEG_V, AgentConstraints
from hierplan_opt.search.symmetry import Rectangles, barriers_force_conflict, rectangle_barriers


def _escape(g, entries, cons, bars) -> bool:
    """Whether two conflict-free walks (waits allowed) through ``entries`` that obey the
    vertex constraints ``cons`` can both be on a vertex-time of their barrier.

    Joint BFS over (position 1, position 2, hit 1, hit 2), written independently of
    the solver; an agent whose entry is later than 0 may start anywhere.
    """
    n = g.n
    horizon = max(t for bar in bars for _, t in bar)
    sets = [set(b) for b in bars]
    free = [u for u in range(n) if g.passable[u]]
    opts = [[v] if t == 0 else free for v, t in entries]
    layer = {(p, q, (p, 0) in sets[0], (q, 0) in sets[1]) for p in opts[0] for q in opts[1]}
    layer = {s for s in layer if s[0] != s[1]}
    for t in range(horizon + 1):
        ok = set()
        for p, q, h1, h2 in layer:
            if any(t == et and x != ev for x, (ev, et) in zip((p, q), entries, strict=True)):
                continue
            if h1 and h2:
                return True
            ok.add((p, q, h1, h2))
        layer = set()
        for p, q, h1, h2 in ok:
            for p2 in (p, *g.adj[p]):
                if (t + 1) * n + p2 in cons[0].vertex:
                    continue
                for q2 in (q, *g.adj[q]):
                    if (t + 1) * n + q2 in cons[1].vertex or p2 == q2 or (p2 == q and q2 == p):
                        continue
                    hit1 = h1 or (p2, t + 1) in sets[0]
                    hit2 = h2 or (q2, t + 1) in sets[1]
                    layer.add((p2, q2, hit1, hit2))
    return False


def test_barriers_force_conflict_is_sound_against_joint_search():
    """Whenever the proof says "always a conflict", no conflict-free pair breaks both
    barriers (brute force); barriers drawn from wrong (virtual) entries, shifted in time,
    with random vertex constraints, so that both answers occur."""
    rng = random.Random(3)
    proved = refuted = 0
    for _ in range(150):
        w, h = rng.choice([(5, 5), (6, 4), (5, 6)])
        cells = [(x, y) for y in range(h) for x in range(w)]
        obs = rng.sample(cells, rng.choice([0, 1, 3]))
        g = Graph.grid(w, h, obstacles=obs)
        free = [g.vertex(c) for c in cells if c not in obs]
        ta, tb = rng.choice([(0, 0), (0, 0), (1, 0), (2, 1)])
        # The barriers of a rectangle whose entries may differ from the real ones.
        da, db = rng.choice([0, 0, 0, 1, 2]), rng.choice([0, 0, 0, 1])
        for _ in range(300):  # draw until the rectangle lemma's geometry applies
            va, vb, ga, gb = rng.sample(free, 4)
            cands = rectangle_barriers(Rectangles(g), (va, ta + da), (vb, tb + db), ga, gb)
            if cands:
                break
        if not cands:
            continue
        a_first, b1, b2 = cands[0]
        if any(t <= 0 for _, t in b1 + b2):
            continue
        e1, e2 = ((va, ta), (vb, tb)) if a_first else ((vb, tb), (va, ta))
        cons = []
        for i in range(2):
            c = AgentConstraints()
            for _ in range(rng.choice([0, 0, 2])):
                c = c.add((NEG_V, i, rng.choice(free), -1, rng.randint(1, 5)), n=g.n, goal=-1)
            cons.append(c)
        if any(t * g.n + v in c.vertex for (v, t), c in zip((e1, e2), cons, strict=True)):
            continue
        if barriers_force_conflict(g, e1, cons[0], b1, e2, cons[1], b2):
            proved += 1
            assert not _escape(g, [e1, e2], cons, [b1, b2]), (g.shape, obs, e1, e2, b1, b2)
        else:
            refuted += _escape(g, [e1, e2], cons, [b1, b2])
    assert proved >= 20 and refuted >= 5, (proved, refuted)


def _check(inst: Instance, **options):
    options = {"generalized_rectangle": True, **options}
    r = hierplan_opt.solve(inst, "cbs", time_limit=30, **options)
    assert r.status == Status.OPTIMAL
    return r


def test_gr_fires_where_plain_rectangle_does_not():
    # Two agents whose starts are not on one anti-diagonal (the plain rule's entries):
    # the rectangle is drawn where their optimal paths run as staircases.
    obs = [(1, 6), (2, 3), (3, 4), (3, 5), (5, 1), (5, 2), (6, 2)]
    inst = Instance.mapf(Graph.grid(7, 7, obstacles=obs), [(2, 6), (6, 6)], [(6, 0), (4, 2)])
    on = _check(inst)
    off = _check(inst, generalized_rectangle=False)
    plain = _check(inst, symmetry=False, heuristic="none", bypass=False)
    assert on.stats["gr_splits"] >= 1
    assert off.stats["rectangle_splits"] == 0 and off.stats.get("gr_splits", 0) == 0
    assert on.cost == off.cost == plain.cost == 17


@pytest.mark.parametrize("block", range(3))
def test_gr_keeps_the_optimum_on_random_grids(block):
    """Cost with generalised rectangles equals the cost without any symmetry reasoning
    (every plan validated by ``hierplan_opt.solve``); the rule must fire sometimes."""
    rng = random.Random(40 + block)
    fired = solved = 0
    for _ in range(15):
        w, h = rng.choice([(8, 8), (9, 7), (10, 10)])
        cells = [(x, y) for y in range(h) for x in range(w)]
        obs = set(rng.sample(cells, rng.choice([5, 10, 15])))
        g = Graph.grid(w, h, obstacles=sorted(obs))
        first = next(c for c in cells if c not in obs)
        d = g.dist_list(g.vertex(first))
        free = [c for c in cells if c not in obs and d[g.vertex(c)] < g.n]
        k = rng.choice([4, 6, 8, 10])
        if len(free) < 2 * k:
            continue
        inst = Instance.mapf(g, rng.sample(free, k), rng.sample(free, k))
        on = _check(inst)
        off = _check(inst, symmetry=False)
        assert on.cost == off.cost
        fired += on.stats.get("gr_splits", 0) > 0
        solved += 1
    assert fired >= 1 and solved >= 12, (fired, solved)
