"""The constraint-tree search of :mod:`hierplan_opt.search.cbs`: :class:`_CBS`.

The engine of the ``cbs`` solver (its options and accelerations are described there),
also the exact two-agent search that the ``ecbs`` family weighs conflicting pairs with
(``ecbs_engine.root_pair_bound``). A library module: it registers no solver, so a
solver that needs the engine imports it and not the ``cbs`` solver.
"""

from __future__ import annotations

import logging
import time
from heapq import heappop, heappush
from typing import Any

from hierplan_opt.core.progress import tick
from hierplan_opt.core.timer import Deadline
from hierplan_opt.search import jit
from hierplan_opt.search.astar import space_time_astar
from hierplan_opt.search.conflicts import EDGE, TARGET, VERTEX, Conflict, find_conflicts
from hierplan_opt.search.constraints import (
    LEN_GT,
    LEN_LE,
    NEG_E,
    NEG_V,
    POS_E,
    POS_V,
    AgentConstraints,
    Constraint,
    add_derived,
    is_positive,
    violates_derived,
)
from hierplan_opt.search.heuristics import dependent, min_vertex_cover
from hierplan_opt.search.mdd import MDD, build_mdd, restrict
from hierplan_opt.search.reservations import Reservations
from hierplan_opt.search.symmetry import (
    Corridors,
    Rectangles,
    corridor_split,
    corridor_target_split,
    generalized_rectangle_split,
    pseudo_corridor_split,
    rectangle_split,
    travel_time,
)

log = logging.getLogger(__name__)

HEURISTICS = ("wdg", "dg", "cg", "none")
#: High-level nodes a two-agent WDG sub-search may expand before its bound is used.
PAIR_NODE_LIMIT = 16
#: Cached MDDs before the cache is emptied (bounds memory on long runs).
MDD_CACHE_SIZE = 50_000
#: How far up the constraint sets' ancestry an MDD to restrict is looked for.
MDD_ANCESTORS = 16
# Generalised rectangles (option ``generalized_rectangle``), the variants measured in
# docs/cbs.md: a split is used where its class (0 cardinal: each child leaves its agent
# no path of the current cost; 1 semi; 2 non) is at most GR_MAX_CLASS and not worse than
# the conflict's own class. GR_ON_CARDINAL: also on cardinal vertex conflicts (CBSH2-RTC
# looks on semi- and non-cardinal ones only). GR_PROMOTE: choose the conflict by its
# rectangle's class (as CBSH2-RTC; it cost nodes here on random-32-32-20, see the docs).
GR_MAX_CLASS = 2
GR_ON_CARDINAL = True
GR_PROMOTE = False
#: True: a pair weight known at an ancestor is reused only while both agents keep the
#: *paths* it was computed on (as CBSH2-RTC copies its conflict graph for agents without
#: a new path; fewer CT nodes, more pair searches); False: while both keep their costs.
#: Measured in docs/cbs.md: no gain in CPU time over the reference set, so off.
PAIRW_SAME_PATHS = False
#: WDG pair searches start at the known lower bound (see ``_pair_weight``).
PAIR_ROOT_LB = True
#: Rectangle reasoning (the start-based rule) on conflicts of class <= this: 1 cardinal
#: and semi-cardinal ones; 2 also non-cardinal ones (as CBSH2-RTC, see docs/cbs.md).
RECT_MAX_CLASS = 2
#: A known pair weight: (w, path_a, path_b, cost_a, cost_b), see ``_Node.pairw``.
_PairWeight = tuple[int, tuple[int, ...], tuple[int, ...], int, int]


class _Node:
    __slots__ = (
        "paths",
        "costs",
        "cons",
        "g",
        "f",
        "hdone",
        "conflicts",
        "depth",
        "seq",
        "pairw",
        "ranks",
        "corr",
        "grs",
    )

    def __init__(
        self,
        paths: list[tuple[int, ...]],
        costs: list[int],
        cons: list[AgentConstraints],
        g: int,
        conflicts: list[Conflict],
        depth: int,
    ) -> None:
        self.paths = paths
        self.costs = costs
        self.cons = cons
        self.g = g
        self.f = g
        self.hdone = False
        self.conflicts = conflicts
        self.depth = depth
        self.seq = 0
        # Pair weights known at this node or an ancestor: (a, b) -> (w, path_a, path_b,
        # cost_a, cost_b). A descendant has more constraints, so a weight stays a valid
        # lower bound on the pair's extra cost while both costs are unchanged; it is
        # reused while both paths are (PAIRW_SAME_PATHS) or both costs.
        self.pairw: dict[tuple[int, int], _PairWeight] = {}
        # Classes (0 cardinal, 1 semi, 2 non) of conflicts classified here or inherited
        # from the parent for agents it did not replan: their paths and costs are the
        # same, their constraints can only have grown, so a conflict's MDD levels can
        # only have narrowed and the inherited class is at most too low (a heuristic
        # choice and a smaller CG bound, never a wrong one). Saves rebuilding the MDDs
        # of agents whose constraints changed but whose paths did not.
        self.ranks: dict[Conflict, int] = {}
        # Corridor splits found for conflicts (None: not a corridor conflict), inherited
        # like ``ranks``: the range bounds come from constraints that a descendant only
        # extends, so they stay valid, and the paths they were checked on are unchanged.
        self.corr: dict[Conflict, list[tuple[int, list[Constraint]]] | None] = {}
        # Generalised rectangle splits found for conflicts, inherited like ``corr`` (the
        # proof uses the entries and constraints, which a descendant only extends).
        self.grs: dict[Conflict, list[tuple[int, list[Constraint]]] | None] = {}


class _CBS:
    """One CBS search (also used for the two-agent sub-searches of WDG)."""

    def __init__(
        self,
        instance_graph: Any,
        starts: list[int],
        goals: list[int],
        root_cons: list[AgentConstraints],
        deadline: Deadline,
        *,
        prioritize: bool,
        bypass: bool,
        heuristic: str,
        disjoint: bool,
        symmetry: bool,
        rectangle: bool = False,
        gr: bool = False,
        corridor_target: bool = False,
        greedy: bool = False,
        node_limit: int | None = None,
        stats: dict[str, Any] | None = None,
        sub: bool = False,
        mdd_cache: dict[int, MDD] | None = None,
        corridors: Corridors | None = None,
        rectangles: Rectangles | None = None,
        init_paths: list[tuple[int, ...]] | None = None,
        root_f: int = 0,
    ) -> None:
        g = instance_graph
        self.graph = g
        self.adj: list[list[int]] = g.adj
        self.n = g.n
        self.dist_of = g.dist_list
        self.starts = starts
        self.goals = goals
        self.k = len(starts)
        self.dists = [g.dist_list(x) for x in goals]
        self.root_cons = root_cons
        self.deadline = deadline
        self.prioritize = prioritize
        self.bypass = bypass
        self.heuristic = heuristic
        self.disjoint = disjoint
        self.symmetry = symmetry
        self.corridor_target = corridor_target
        self.greedy = greedy
        self.node_limit = node_limit
        #: ``"node_limit"`` once :meth:`search` stopped at ``node_limit`` (else None).
        self.stopped_by: str | None = None
        self.sub = sub
        self.stats = (
            stats
            if stats is not None
            else {
                "high_level_expanded": 0,
                "high_level_generated": 0,
                "low_level_calls": 0,
                "low_level_expanded": 0,
                "bypasses": 0,
                "mdds_built": 0,
                "pair_searches": 0,
                "conflicts_cardinal": 0,
                "conflicts_semi": 0,
                "conflicts_non": 0,
                "target_splits": 0,
                "corridor_splits": 0,
                "corridor_target_splits": 0,
                "rectangle_splits": 0,
                "gr_splits": 0,
            }
        )
        self.corridors = (corridors or Corridors(g)) if symmetry else None
        # The grid coordinates (rectangle reasoning, and the reach test of positive
        # constraints in ``child``): built on first use, a few numpy passes over the graph
        # that most small searches never need.
        self._want_rect = symmetry and rectangle
        #: Generalised rectangles too (:func:`.symmetry.generalized_rectangle_split`).
        self.gr = gr
        self._rect = rectangles
        self.init_paths = init_paths
        # A known lower bound on the solution cost (WDG pair searches): the root's f.
        self.root_f = root_f
        # One table of the node's paths, patched per child: the low level's
        # conflict-avoidance table (without the agent being replanned) and the index
        # the new paths' conflicts are found with (one table: each is patched once).
        # The main search's table may become the compiled low level's own (see
        # Reservations.dense); the short pair searches' ones share its buffers.
        self._occ = self._cat = Reservations(g.n, dense_ok=not sub)
        if not sub:
            jit.new_solve()  # the compiled low level is loaded only for a long solve
        # MDDs keyed by the constraint object's version (unique per agent and set);
        # shared with the two-agent sub-searches of WDG.
        self.mdd_cache: dict[int, MDD] = mdd_cache if mdd_cache is not None else {}
        self.pair_cache: dict[tuple[int, int, int, int], int] = {}
        # The same weights keyed by the constraints' content (see AgentConstraints.content).
        self.pair_memo: dict[tuple[int, int, tuple[object, ...], tuple[object, ...]], int] = {}
        # Goals cut off by forbidden-from constraints (see astar.cut_off), shared with
        # the WDG sub-searches.
        self.cut_cache: dict[tuple[object, ...], int] = {}
        self.lower_bound = 0
        self.seq = 0

    def _grid(self) -> Rectangles | None:
        """The graph's coordinates if it is a 4-connected 2D grid (made on first call)."""
        if self._rect is None:
            self._rect = Rectangles(self.graph)
        return self._rect if self._rect.enabled else None

    def rectangles(self) -> Rectangles | None:
        """The grid coordinates for rectangle reasoning, None if it is not used."""
        return self._grid() if self._want_rect else None

    # ------------------------------------------------------------------ low level
    def plan(
        self, a: int, cons: AgentConstraints, paths: list[tuple[int, ...]]
    ) -> tuple[int, ...] | None:
        """Agent ``a``'s shortest path under ``cons``, fewest conflicts with ``paths``.

        Leaves ``a`` out of the shared table: the caller's next ``sync`` puts in the
        path it keeps (the new one), so the old path is not re-added only to be dropped.
        """
        res = None
        if self.k > 1:
            res = self._cat
            res.sync(paths, skip=a)
        path, exp = space_time_astar(
            self.adj,
            self.starts[a],
            self.goals[a],
            self.dists[a],
            cons,
            res=res,
            dist_of=self.dist_of,
            cut_cache=self.cut_cache,
        )
        st = self.stats
        st["low_level_calls"] += 1
        st["low_level_expanded"] += exp
        return path

    def mdd(self, node: _Node, a: int) -> MDD:
        c = node.cons[a]
        key = c.ver
        m = self.mdd_cache.get(key)
        if m is not None and m.cost != node.costs[a]:
            m = None
        if m is None:
            # The nearest ancestor constraint set with a cached MDD of this cost: its
            # paths that obey the constraints added since are this MDD's paths.
            own: tuple[Constraint, ...] = ()
            derived: tuple[tuple[Constraint, int], ...] = ()
            p = c
            for _ in range(MDD_ANCESTORS):
                q = p.parent
                if q is None:
                    break
                own = p.delta + own if own else p.delta
                derived = p.derived + derived if derived else p.derived
                pm = self.mdd_cache.get(q.ver)
                if pm is not None and pm.cost == node.costs[a]:
                    m = restrict(pm, own, derived)
                    if m is not None:
                        self.mdd_cache[key] = m
                        self.stats["mdds_restricted"] = self.stats.get("mdds_restricted", 0) + 1
                    break
                p = q
        if m is None:
            m = build_mdd(
                self.adj,
                self.starts[a],
                self.goals[a],
                self.dists[a],
                c,
                node.costs[a],
                self.dist_of,
            )
            if len(self.mdd_cache) > MDD_CACHE_SIZE:
                self.mdd_cache.clear()
            self.mdd_cache[key] = m
            self.stats["mdds_built"] += 1
        return m

    # ------------------------------------------------------------------ root
    def root(self) -> _Node | None:
        paths: list[tuple[int, ...]] = []
        if self.init_paths is not None:
            # Paths already optimal under the root constraints (WDG sub-searches).
            paths = list(self.init_paths)
        # The search's shared table: the first child's ``sync`` then finds these paths in it.
        res = self._cat
        if len(paths) < self.k:
            for a, p in enumerate(paths):
                res.add(a, p)
        for a in range(len(paths), self.k):
            if self.deadline.expired():
                return None
            p, exp = space_time_astar(
                self.adj,
                self.starts[a],
                self.goals[a],
                self.dists[a],
                self.root_cons[a],
                res=res if self.k > 1 else None,
                dist_of=self.dist_of,
            )
            self.stats["low_level_calls"] += 1
            self.stats["low_level_expanded"] += exp
            if p is None:
                return None
            res.add(a, p)
            paths.append(p)
        costs = [len(p) - 1 for p in paths]
        return _Node(
            paths, costs, list(self.root_cons), sum(costs), find_conflicts(paths, self.n), 0
        )

    # ------------------------------------------------------------------ conflicts
    def classify(self, node: _Node, c: Conflict) -> int:
        """0 cardinal, 1 semi-cardinal, 2 non-cardinal."""
        t, kind, a, b, u, v = c
        ma = self.mdd(node, a)
        mb = self.mdd(node, b)
        if kind == VERTEX:
            ca = ma.single(t, v)
            cb = mb.single(t, v)
        elif kind == EDGE:
            ca = ma.single(t - 1, u) and ma.single(t, v)
            cb = mb.single(t - 1, v) and mb.single(t, u)
        else:  # TARGET: a must arrive later than t, or b must avoid v from t on
            ca = True
            cb = mb.single(t, v)
        return 2 - int(ca) - int(cb)

    def rank(self, node: _Node, c: Conflict) -> int:
        """:meth:`classify`, remembered in the node (see ``_Node.ranks``)."""
        r = node.ranks.get(c)
        if r is None:
            r = node.ranks[c] = self.classify(node, c)
        return r

    def choose(self, node: _Node) -> tuple[Conflict, int]:
        confs = node.conflicts
        if not self.prioritize:
            c = min(confs)
            return c, 2
        best = None
        best_key = None
        ranks = node.ranks
        for c in confs:
            r = ranks.get(c)
            if r is None:
                r = ranks[c] = self.classify(node, c)
            key = (r, c[1] != TARGET, c[0])
            if best_key is None or key < best_key:
                best_key = key
                best = c
                if r == 0 and c[1] == TARGET:
                    break
        assert best is not None and best_key is not None
        r = best_key[0]
        gr = self._best_gr(node, r) if best[1] != TARGET else None
        if gr is not None and gr[1] < r:
            return gr
        if self.corridors is not None and best[1] != TARGET and not self.sub:
            # Among the conflicts of the best class, a corridor conflict first (its
            # split resolves the whole corridor at once), then the earliest.
            cands = sorted((c for c in confs if ranks[c] == r), key=lambda c: c[0])
            for c in cands:
                if self.corridor(node, c, r) is not None:
                    return c, r
        return gr if gr is not None else (best, r)

    def _best_gr(self, node: _Node, r: int) -> tuple[Conflict, int] | None:
        """The vertex conflict with a generalised rectangle split of the best class
        ``<= r`` (earliest first), or None. As in CBSH2-RTC, a rectangle's class comes
        from its barriers: cardinal if each child leaves its agent no path of the
        current cost, semi-cardinal if one does; among equals it goes before a plain
        conflict (after target and corridor conflicts)."""
        if not self.gr or not GR_PROMOTE or self.sub or self.rectangles() is None:
            return None
        out = None
        ranks = node.ranks
        for c in sorted((c for c in node.conflicts if c[1] == VERTEX), key=lambda c: c[0]):
            if not GR_ON_CARDINAL and ranks.get(c, 2) == 0:
                continue
            res = self.gr_split(node, c)
            if res is None:
                continue
            k = self._gr_rank(node, res)
            if k <= min(r, GR_MAX_CLASS) and (out is None or k < out[1]):
                out = (c, k)
                if k == 0:
                    break
        return out

    def _gr_rank(self, node: _Node, res: list[tuple[int, list[Constraint]]]) -> int:
        """A barrier split's class: 0 if each child leaves its agent no path of the current
        cost (both children cost more), 1 if one does, else 2."""
        return 2 - sum(restrict(self.mdd(node, x), cs, []) is None for x, cs in res)

    def gr_split(self, node: _Node, c: Conflict) -> list[tuple[int, list[Constraint]]] | None:
        """The generalised rectangle split of vertex conflict ``c`` or None, cached."""
        cache = node.grs
        if c in cache:
            return cache[c]
        rects = self.rectangles()
        res = None
        if rects is not None:
            t, _, a, b, _, v = c
            res = generalized_rectangle_split(
                rects, self.starts, node.cons, node.paths, a, b, v, t,
                key=lambda r: self._gr_rank(node, r),
            )  # fmt: skip
        cache[c] = res
        return res

    def corridor(
        self, node: _Node, c: Conflict, rank: int
    ) -> list[tuple[int, list[Constraint]]] | None:
        """The corridor split of conflict ``c`` (see :mod:`.symmetry`) or None, cached."""
        cache = node.corr
        if c in cache:
            return cache[c]
        res = None
        t, kind, a, b, u, v = c
        if self.corridors is not None:
            cons = node.cons

            def travel(x: int, target: int, blocked: tuple[int, int] | None, upper: int) -> int:
                return self.travel(x, cons[x], target, blocked, upper)

            verts = (u, v) if kind == EDGE else (v,)
            # A goal in the corridor first (corridor-target), as CBSH2-RTC does; a
            # TARGET conflict's parked agent is ``a``.
            pairs = ((a, b),) if kind == TARGET else ((a, b), (b, a))
            for m, o in pairs if self.corridor_target else ():
                res = corridor_target_split(
                    self.corridors, travel, self.starts, self.goals, node.paths, m, o, verts,
                    t if kind == TARGET else -1,
                )  # fmt: skip
                if res is not None:
                    break
            if res is None and kind != TARGET:
                res = corridor_split(self.corridors, travel, self.starts, node.paths, a, b, verts)
            if (
                res is None
                and kind != TARGET
                and rank == 0
                and self.corridors.enabled
                and self._head_on(node, c)
            ):
                res = pseudo_corridor_split(travel, node.paths, a, b, u, v, t)
        cache[c] = res
        return res

    def split(self, node: _Node, c: Conflict, rank: int) -> list[tuple[int, list[Constraint]]]:
        """The children's new constraints: ``[(agent, [constraints]), ...]``."""
        t, kind, a, b, u, v = c
        if kind == TARGET and self.symmetry:
            res = self.corridor(node, c, rank) if self.corridor_target else None
            if res is not None:
                self.stats["corridor_target_splits"] += 1
                return res
            self.stats["target_splits"] += 1
            return [(a, [(LEN_GT, a, -1, -1, t)]), (a, [(LEN_LE, a, -1, -1, t)])]
        if self.corridors is not None and kind != TARGET:
            res = self.corridor(node, c, rank)
            if res is not None:
                key = "corridor_target_splits" if res[0][1][0][0] == LEN_GT else "corridor_splits"
                self.stats[key] += 1
                return res
        rects = self.rectangles() if kind == VERTEX else None
        if rects is not None:
            res = None
            if rank <= RECT_MAX_CLASS:
                res = rectangle_split(
                    rects, self.starts, self.goals, node.cons, node.paths, a, b, v, t
                )
            if res is None and self.gr and (GR_ON_CARDINAL or node.ranks.get(c, rank) > 0):
                res = self.gr_split(node, c)
                # Only where its class is not worse than the conflict's own (CBSH2-RTC
                # looks for rectangles on semi- and non-cardinal conflicts only; see
                # GR_ON_CARDINAL).
                if res is not None and self._gr_rank(node, res) > min(rank, GR_MAX_CLASS):
                    res = None
                if res is not None:
                    self.stats["gr_splits"] = self.stats.get("gr_splits", 0) + 1
            if res is not None:
                self.stats["rectangle_splits"] = self.stats.get("rectangle_splits", 0) + 1
                return res
        if kind == EDGE:
            if self.disjoint:
                x = a
                if self.prioritize and rank == 1:
                    mb = self.mdd(node, b)
                    if mb.single(t - 1, v) and mb.single(t, u):
                        x = b
                xu, xv = (u, v) if x == a else (v, u)
                return [(x, [(POS_E, x, xu, xv, t)]), (x, [(NEG_E, x, xu, xv, t)])]
            return [(a, [(NEG_E, a, u, v, t)]), (b, [(NEG_E, b, v, u, t)])]
        # VERTEX (or TARGET without target reasoning)
        if self.disjoint:
            x = a
            if self.prioritize and rank == 1 and kind == VERTEX and self.mdd(node, b).single(t, v):
                x = b
            return [(x, [(POS_V, x, v, -1, t)]), (x, [(NEG_V, x, v, -1, t)])]
        return [(a, [(NEG_V, a, v, -1, t)]), (b, [(NEG_V, b, v, -1, t)])]

    def travel(
        self,
        a: int,
        cons: AgentConstraints,
        target: int,
        blocked: tuple[int, int] | None,
        upper: int,
    ) -> int:
        """:func:`~hierplan_opt.search.symmetry.travel_time` of agent ``a``, cached."""
        assert self.corridors is not None
        cache = self.corridors.travel_cache
        key = (cons.ver, self.starts[a], target, blocked)
        hit = cache.get(key)
        if hit is not None and (hit[0] < hit[1] or upper <= hit[1]):
            return min(hit[0], upper)
        val = travel_time(
            self.adj, self.starts[a], target, self.dist_of(target), cons, blocked, upper,
            jit.kernel(self.n),
        )  # fmt: skip
        if len(cache) > MDD_CACHE_SIZE:
            cache.clear()
        cache[key] = (val, upper)
        return val

    def _head_on(self, node: _Node, c: Conflict) -> bool:
        """Whether every optimal path of both agents makes the moves of the conflict
        (a cardinal vertex conflict also needs singletons one step before and after)."""
        t, kind, a, b, _, _ = c
        if kind != VERTEX:
            return kind == EDGE  # cardinal edge conflict: singletons at t-1 and t
        ma, mb = self.mdd(node, a), self.mdd(node, b)
        pa, pb = node.paths[a], node.paths[b]
        if len(pa) <= t + 1 or len(pb) <= t + 1:
            return False
        return (
            ma.single(t - 1, pa[t - 1])
            and ma.single(t + 1, pa[t + 1])
            and mb.single(t - 1, pb[t - 1])
            and mb.single(t + 1, pb[t + 1])
        )

    def child(self, node: _Node, agent: int, new: list[Constraint]) -> _Node | None:
        """The child of ``node`` with constraints ``new`` (``agent``'s, and possibly others':
        each constraint names its agent), its changed paths replanned; None if one fails."""
        n = self.n
        cons = list(node.cons)
        paths = list(node.paths)
        costs = list(node.costs)
        replan: list[int] = []
        own: dict[int, list[Constraint]] = {}
        for x in new:
            own.setdefault(x[1], []).append(x)
        for y, ys in own.items():
            cons[y] = cons[y].add_many(ys, n=n, goal=self.goals[y])
            if not cons[y].allows_path(paths[y], n):
                replan.append(y)
        pos = [x for x in new if is_positive(x)]
        if pos:
            starts = self.starts
            dists = self.dists
            # A vertex that agent y cannot reach by the constraint's time gives y a
            # constraint no path of y can break: y keeps its constraint object, and with
            # it its cached MDD and pair weights. "Cannot reach" from lower bounds on the
            # distance from y's start (no BFS): the grid distance on a 4-connected grid,
            # and the triangle inequality on y's distances to its goal.
            grid: Rectangles | None = None
            grid_made = False  # the coordinates, made on first need
            sym = not self.graph.directed
            # (constraint, its vertex or -1 for a length constraint, its time)
            at = [(x, -1 if x[0] == LEN_LE else x[3] if x[0] == POS_E else x[2], x[4]) for x in pos]
            for y in range(self.k):
                s = starts[y]
                dy = dists[y]
                rel = []
                for x, v, t in at:
                    if x[1] == y:
                        continue
                    if v >= 0:
                        lb = dy[s] - dy[v]
                        if sym and lb < 0:
                            lb = -lb
                        if lb <= t and not grid_made:
                            grid, grid_made = self._grid(), True
                        if lb <= t and grid is not None:
                            lb = abs(grid.xs[s] - grid.xs[v]) + abs(grid.ys[s] - grid.ys[v])
                        if lb > t:
                            continue
                    rel.append(x)
                if not rel:
                    continue
                old = cons[y]
                cons[y] = add_derived(old, rel, n=n, goals=self.goals, goal=self.goals[y])
                self._inherit_mdd(y, old, cons[y], rel, node.costs[y])
                if y not in replan and any(
                    violates_derived(x, paths[y], n, self.goals) for x in rel
                ):
                    replan.append(y)
        for y in replan:
            p = self.plan(y, cons[y], paths)
            if p is None:
                return None
            paths[y] = p
            costs[y] = len(p) - 1
        g = sum(costs)
        if replan:
            gone = set(replan)
            confs = [c for c in node.conflicts if c[2] not in gone and c[3] not in gone]
            ranks = {c: r for c, r in node.ranks.items() if c[2] not in gone and c[3] not in gone}
            corr = {c: r for c, r in node.corr.items() if c[2] not in gone and c[3] not in gone}
            grs = {c: r for c, r in node.grs.items() if c[2] not in gone and c[3] not in gone}
            occ = self._occ
            occ.sync(paths)
            done: set[int] = set()
            for y in replan:
                confs += occ.conflicts_of(y, paths[y], done)
                done.add(y)
        else:
            confs = list(node.conflicts)
            ranks = dict(node.ranks)
            corr = dict(node.corr)
            grs = dict(node.grs)
        ch = _Node(paths, costs, cons, g, confs, node.depth + 1)
        if not self.sub:  # measured: in the short WDG sub-searches stale classes cost time
            ch.ranks = ranks
            ch.corr = corr
            ch.grs = grs
        ch.f = max(g, node.f) if not self.greedy else g
        ch.pairw = node.pairw
        return ch

    def _inherit_mdd(
        self, y: int, old: AgentConstraints, new: AgentConstraints, pos: list[Constraint], cost: int
    ) -> None:
        """Keep ``y``'s MDD when the derived constraints do not touch it."""
        m = self.mdd_cache.get(old.ver)
        if m is None or m.cost != cost:
            return
        for kind, ag, a, b, t in pos:
            if kind == POS_V:
                if m.has(t, a):
                    return
            elif kind == POS_E:
                if m.has(t, b) or m.has(t - 1, a) or m.has(t - 1, b):
                    return
            elif kind == LEN_LE:
                g = self.goals[ag]
                if m.passes(g, t):
                    return
        self.mdd_cache[new.ver] = m

    # ------------------------------------------------------------------ heuristic
    def compute_h(self, node: _Node) -> int | None:
        """Admissible h of ``node``; None if a pair has no joint solution at all."""
        if self.heuristic == "none" or not node.conflicts:
            return 0
        pairs: dict[tuple[int, int], list[Conflict]] = {}
        for c in node.conflicts:
            a, b = c[2], c[3]
            key = (a, b) if a < b else (b, a)
            pairs.setdefault(key, []).append(c)
        weights: dict[tuple[int, int], int] = {}
        if self.heuristic == "cg":
            for key, cs in pairs.items():
                if any(self.rank(node, c) == 0 for c in cs):
                    weights[key] = 1
            return min_vertex_cover(weights)
        known = node.pairw
        costs = node.costs
        # An entry whose costs are no longer the pair's is never used again below this
        # node (an agent's cost only grows along a branch): it is not inherited.
        mine = {k: x for k, x in known.items() if x[3] == costs[k[0]] and x[4] == costs[k[1]]}
        paths = node.paths
        for (a, b), cs in pairs.items():
            if self.deadline.expired():
                break  # the edges weighed so far still give a lower bound
            old = known.get((a, b))
            if old is not None and (
                (old[1] is paths[a] and old[2] is paths[b])
                if PAIRW_SAME_PATHS
                else (old[3] == costs[a] and old[4] == costs[b])
            ):
                w = old[0]
            else:
                ca, cb = node.cons[a], node.cons[b]
                ck = (a, ca.ver, b, cb.ver)
                w = self.pair_cache.get(ck)
                if w is None:
                    # Another CT node may have had the same constraints on a and b
                    # (reached by another branch): the weight depends on them only.
                    content = (a, b, ca.content(), cb.content())
                    w = self.pair_memo.get(content)
                    if w is None:
                        # A weight known at an ancestor for the same costs is a lower
                        # bound on this one (constraints only grow).
                        lb = old[0] if old is not None and old[3:] == (costs[a], costs[b]) else 0
                        w = self._pair_weight(node, a, b, cs, lb)
                        self.pair_memo[content] = w
                    else:
                        self.stats["pair_memo_hits"] = self.stats.get("pair_memo_hits", 0) + 1
                    self.pair_cache[ck] = w
                if w < 0:
                    return None
                mine[(a, b)] = (w, paths[a], paths[b], costs[a], costs[b])
            weights[(a, b)] = w
        node.pairw = mine
        return min_vertex_cover(weights)

    def _pair_weight(self, node: _Node, a: int, b: int, cs: list[Conflict], lb: int = 0) -> int:
        """The pair's WDG weight (DG: 0 or 1); ``lb``: a known lower bound on it."""
        # A cardinal conflict already proves the pair dependent.
        if (
            lb <= 0
            and not (self.prioritize and any(self.rank(node, c) == 0 for c in cs))
            and not dependent(self.mdd(node, a), self.mdd(node, b))
        ):
            return 0
        if self.heuristic == "dg":
            return 1
        # WDG: solve the two-agent problem under the pair's constraints.
        self.stats["pair_searches"] += 1
        sub = _CBS(
            self.graph,
            [self.starts[a], self.starts[b]],
            [self.goals[a], self.goals[b]],
            [node.cons[a], node.cons[b]],
            self.deadline,
            prioritize=True,
            bypass=True,
            heuristic="none",
            disjoint=False,
            symmetry=self.symmetry,
            rectangle=self.rectangles() is not None,
            gr=self.gr,
            corridor_target=self.corridor_target,
            node_limit=PAIR_NODE_LIMIT,
            sub=True,
            mdd_cache=self.mdd_cache,
            corridors=self.corridors,
            rectangles=self._rect,
            init_paths=[node.paths[a], node.paths[b]],
            # The pair is dependent: its cost rises by at least max(lb, 1). Starting
            # there (as CBSH2-RTC's lower bound does) makes the sub-search look for a
            # pair of paths of that cost first instead of proving every level below.
            root_f=node.costs[a] + node.costs[b] + (max(lb, 1) if PAIR_ROOT_LB else 0),
        )
        sub.cut_cache = self.cut_cache
        res = sub.search()
        base = node.costs[a] + node.costs[b]
        # Counted in the total, and apart: CBSH2-RTC's low-level count leaves its WDG
        # sub-searches out, so ``low_level_expanded - pair_low_level_expanded`` compares.
        sub_ll = sub.stats["low_level_expanded"]
        self.stats["low_level_expanded"] += sub_ll
        self.stats["pair_low_level_expanded"] = (
            self.stats.get("pair_low_level_expanded", 0) + sub_ll
        )
        if res is None:
            if sub.exhausted:
                return -1
            return max(1, sub.lower_bound - base)
        return max(1, res.g - base)

    # ------------------------------------------------------------------ search
    def _key(self, node: _Node) -> tuple:
        if self.greedy:
            return (len(node.conflicts), node.g, node.seq)
        return (node.f, len(node.conflicts), node.seq)

    def search(self) -> _Node | None:
        """Best-first CT search; the solution node, or None (see ``exhausted``)."""
        self.exhausted = False
        root = self.root()
        if root is None:
            self.exhausted = not self.deadline.expired()
            return None
        st = self.stats
        scanned = root.paths  # the root's conflicts come from a full scan of these paths
        openl: list[tuple] = []
        root.f = max(root.f, self.root_f)
        self._push(openl, root)
        expanded = 0
        last_log = time.perf_counter()
        while openl:
            at_limit = self.node_limit is not None and expanded >= self.node_limit
            if at_limit or self.deadline.expired():
                if at_limit:
                    self.stopped_by = "node_limit"
                if not self.greedy:  # OPEN is ordered by f: its head is the bound
                    self.lower_bound = max(self.lower_bound, openl[0][0])
                return None
            entry = heappop(openl)
            node: _Node = entry[-1]
            if not self.greedy:
                self.lower_bound = max(self.lower_bound, node.f)
            if not node.hdone and not self.greedy:
                node.hdone = True
                if node.conflicts:
                    h = self.compute_h(node)
                    if h is None:
                        continue
                    if node.g + h > node.f:
                        node.f = node.g + h
                        self._push(openl, node)
                        continue
            if not node.conflicts:
                # Conflicts are tracked incrementally; confirm a solution with one scan.
                if node.paths is not scanned:
                    node.conflicts = find_conflicts(node.paths, self.n)
                if not node.conflicts:
                    return node
                log.warning("CBS: incremental conflict tracking missed a conflict")
            expanded += 1
            if not self.sub:
                st["high_level_expanded"] += 1
                self.deadline.keep_back_heap()  # freeing the tree fits in the limit
                tick("expanded", expanded, lb=self.lower_bound or None, open=len(openl))
                now = time.perf_counter()
                if now - last_log > 5.0:
                    last_log = now
                    log.info(
                        "CBS: %d expanded, %d open, lower bound %s, %d conflicts",
                        expanded,
                        len(openl),
                        self.lower_bound,
                        len(node.conflicts),
                    )
            self._expand(node, openl)
        self.exhausted = True
        return None

    def _push(self, openl: list[tuple], node: _Node) -> None:
        self.seq += 1
        node.seq = self.seq
        heappush(openl, (*self._key(node), node))

    def _expand(self, node: _Node, openl: list[tuple]) -> None:
        st = self.stats
        while True:
            c, rank = self.choose(node)
            if not self.sub:
                st[("conflicts_cardinal", "conflicts_semi", "conflicts_non")[rank]] += 1
            children: list[_Node] = []
            adopted = False
            for agent, new in self.split(node, c, rank):
                ch = self.child(node, agent, new)
                if ch is None:
                    continue
                if not self.sub:
                    st["high_level_generated"] += 1
                if (
                    self.bypass
                    and rank != 0
                    and ch.g == node.g
                    and len(ch.conflicts) < len(node.conflicts)
                ):
                    # Adopt the child's paths: they obey the node's constraints too.
                    node.paths = ch.paths
                    node.costs = ch.costs
                    node.conflicts = ch.conflicts
                    node.ranks = ch.ranks
                    node.corr = ch.corr
                    node.grs = ch.grs
                    st["bypasses"] += 1
                    adopted = True
                    break
                children.append(ch)
            if adopted:
                if not node.conflicts:
                    self._push(openl, node)
                    return
                continue
            if not self.sub:
                # CBSH2-RTC's "generated": the children that enter OPEN (the children
                # made and dropped in bypass attempts are in high_level_generated too).
                st["high_level_pushed"] = st.get("high_level_pushed", 0) + len(children)
            for ch in children:
                self._push(openl, ch)
            return
