"""The ECBS family's engine: the high level :class:`_ECBS` and how a search is run.

The ``ecbs`` and ``eecbs`` solvers (:mod:`hierplan_opt.search.ecbs`, where the
algorithm is described, and :mod:`hierplan_opt.search.eecbs`) are this search with
their options; ``cbs`` with highways reaches it through the registry. Here: the
constraint-tree node, the root's pair bound (:func:`root_pair_bound`, with the ``cbs``
engine's two-agent search), the split order, the search, LaCAM's anytime fallback
(through the registry), the options the two solvers share, and :func:`run_search` /
:func:`run_with_highways`. A library module: it registers no solver.
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Callable
from heapq import heappop, heappush
from typing import Any

from hierplan_opt import registry
from hierplan_opt.core.collector import paused_gc
from hierplan_opt.core.highways_learned import resolve
from hierplan_opt.core.instance import Instance
from hierplan_opt.core.options import Option
from hierplan_opt.core.plan import Plan
from hierplan_opt.core.progress import tick
from hierplan_opt.core.result import Result, Status
from hierplan_opt.core.timer import Deadline
from hierplan_opt.search import jit
from hierplan_opt.search.cbs_engine import _CBS, PAIR_NODE_LIMIT
from hierplan_opt.search.conflicts import EDGE, TARGET, Conflict
from hierplan_opt.search.constraints import NEG_E, NEG_V, AgentConstraints, Constraint
from hierplan_opt.search.focal import FocalLowLevel, focal_path
from hierplan_opt.search.heuristics import min_vertex_cover
from hierplan_opt.search.highways import HighwayLowLevel
from hierplan_opt.search.reservations import Reservations
from hierplan_opt.search.spacetime import SearchTimeout

log = logging.getLogger(__name__)

#: Share of the time limit LaCAM may spend on its plan.
LACAM_SHARE = 0.25
#: With ``lacam="fallback"``, LaCAM's plan is computed once the search has run this long
#: (or ``FALLBACK_AFTER_SHARE`` of the time limit, if less): a search that ends sooner
#: never pays for a plan it would not return (0.08 s of 0.55 s on
#: warehouse-10-20-10-2-1 k100, in a fresh process). The fallback then still has
#: ``LACAM_SHARE`` of the limit before it runs out.
FALLBACK_AFTER_S = 1.0
FALLBACK_AFTER_SHARE = 0.25
LACAM_MODES = ("fallback", "start", "off")

#: Polishing may spend this share of the search's low-level expansions (at least
#: ``_POLISH_MIN``): on warehouse-10-20-10-2-1 it otherwise doubles the run time.
_POLISH_SHARE = 0.25
_POLISH_MIN = 20_000

#: Slack on ``cost <= w * LB`` tests (w is a float).
_EPS = 1e-9

Path = tuple[int, ...]


class _Node:
    """A constraint-tree node: one path, one low-level bound ``lbs[i]`` and one
    :class:`AgentConstraints` per agent (shared with the parent unless changed)."""

    __slots__ = (
        "paths", "lbs", "cons", "cost", "lb", "conflicts", "id", "fhat", "closed", "depth", "pairs"
    )  # fmt: skip

    def __init__(
        self,
        paths: list[Path],
        lbs: list[int],
        cons: list[AgentConstraints],
        conflicts: list[Conflict],
        nid: int,
        depth: int,
        pairs: frozenset[tuple[int, int]] = frozenset(),
        floor: int = 0,
    ) -> None:
        self.paths = paths
        self.lbs = lbs
        self.cons = cons
        self.cost = sum(len(p) - 1 for p in paths)
        # LB: the agents' bounds, or the parent's LB if higher (a lower bound of every
        # solution below the parent holds below the child: the root's pair bound).
        self.lb = max(sum(lbs), floor)
        self.conflicts = conflicts
        self.id = nid
        self.fhat = float(self.cost)
        self.closed = False
        self.depth = depth
        self.pairs = pairs  # the pairs of agents split on from the root to here


#: High-level expansions after which the root's pair bound is computed (a search that
#: ends sooner does not pay for it: 0.4 s on warehouse-10-20-10-2-1 k100, bound 0).
ROOT_BOUND_AFTER = 64
#: Share of the time limit the root's pair bound may take (and at most this many seconds).
ROOT_BOUND_SHARE = 0.1
ROOT_BOUND_MAX_S = 5.0


def root_pair_bound(
    instance: Instance, conflicts: list[Conflict], deadline: Deadline, stats: dict[str, Any]
) -> int:
    """An admissible bound on what the agents' conflicts add to the sum of their
    shortest paths: for each pair of agents in conflict in the root, the extra cost of
    the pair's optimal two-agent plan (a CBS of at most ``PAIR_NODE_LIMIT`` expansions,
    else its lower bound), and the minimum weighted vertex cover of those pair weights
    (the WDG bound of Li et al. 2019, computed once, at the root, as EECBS raises its
    root's LB). Every solution costs at least the sum of the shortest paths plus it.

    Example
    -------
    >>> from hierplan_opt.core.graph import Graph
    >>> from hierplan_opt.core.timer import Deadline
    >>> g = Graph.grid(3, 2)  # a swap on a 3 x 2 grid: one agent steps aside
    >>> inst = Instance.mapf(g, [(0, 0), (2, 0)], [(2, 0), (0, 0)])
    >>> h = root_pair_bound(inst, [Conflict(1, 0, 0, 1, 1, -1)], Deadline(None), {})
    >>> from hierplan_opt import solve
    >>> h, inst.soc_lower_bound() + h == solve(inst, "cbs").cost  # two agents: exact
    (2, True)
    """
    g = instance.graph
    starts, goals = instance.starts, instance.goals
    remaining = deadline.remaining()
    budget = ROOT_BOUND_MAX_S if remaining == float("inf") else remaining * ROOT_BOUND_SHARE
    stop = time.perf_counter() + min(budget, ROOT_BOUND_MAX_S)
    pairs = sorted({(min(c[2], c[3]), max(c[2], c[3])) for c in conflicts})
    weights: dict[tuple[int, int], int] = {}
    done = 0
    for a, b in pairs:
        if time.perf_counter() > stop or deadline.expired():
            break  # the pairs weighed so far still give a lower bound
        sub_stats: dict[str, Any] = {"high_level_expanded": 0, "high_level_generated": 0,
                                     "low_level_calls": 0, "low_level_expanded": 0,
                                     "bypasses": 0, "mdds_built": 0, "pair_searches": 0,
                                     "conflicts_cardinal": 0, "conflicts_semi": 0,
                                     "conflicts_non": 0, "target_splits": 0,
                                     "corridor_splits": 0, "corridor_target_splits": 0,
                                     "rectangle_splits": 0}  # fmt: skip
        sub = _CBS(
            g,
            [starts[a], starts[b]],
            [goals[a], goals[b]],
            [AgentConstraints(), AgentConstraints()],
            deadline,
            prioritize=True,
            bypass=True,
            heuristic="none",
            disjoint=False,
            symmetry=True,
            rectangle=True,
            node_limit=PAIR_NODE_LIMIT,
            stats=sub_stats,
            sub=True,
        )
        res = sub.search()
        stats["low_level_expanded"] = stats.get("low_level_expanded", 0) + int(
            sub_stats["low_level_expanded"]
        )
        base = g.dist_list(goals[a])[starts[a]] + g.dist_list(goals[b])[starts[b]]
        if res is not None:
            extra = res.g - base
        elif sub.exhausted:  # no joint plan: the front door's checks say why; no bound
            extra = 0
        else:
            extra = sub.lower_bound - base
        if extra > 0:
            weights[(a, b)] = extra
        done += 1
    stats["root_pairs_weighed"] = done
    return min_vertex_cover(weights)


def split_order(c: Conflict, paths: list[Path]) -> tuple[int, int, int, int, int, int]:
    """The key by which ECBS picks the conflict to split: target conflicts first.

    A conflict with an agent parked at (or just arriving for good at) its goal comes
    first: those tend to be cardinal (cf. target reasoning in CBSH2-RTC; on
    maze-32-32-2 with 30 agents this cut the high-level expansions from 165 to 7); then
    the earliest, the newer agent first.

    Example
    -------
    >>> from hierplan_opt.search.conflicts import VERTEX
    >>> split_order(Conflict(4, VERTEX, 0, 1, -1, 7), [(7,), (6, 6, 6, 6, 7, 8)])
    (1, 4, 1, 0, 7, -1)
    >>> split_order(Conflict(4, TARGET, 0, 1, -1, 7), [(7,), (6, 6, 6, 6, 7, 8)])
    (0, 4, 1, 0, 7, -1)
    """
    t, kind, a, b, u, v = c
    if kind == EDGE:  # by departure time, as the moves u -> v of b and v -> u of a
        return (1, t - 1, b, a, v, u)
    at_goal = kind == TARGET or (len(paths[a]) - 1 == t and paths[a][-1] == v)
    return (0 if at_goal else 1, t, b, a, v, -1)


class _ECBS:
    """One ECBS(w) search: the constraint tree with OPEN and FOCAL lists.

    :class:`~hierplan_opt.search.eecbs._EECBS` overrides :meth:`focal_key`,
    :meth:`select` and :meth:`learn` (explicit estimation) and turns on bypassing.
    """

    name = "ecbs"
    #: Raise the root's LB by the pairwise bound of :func:`root_pair_bound` (class
    #: attribute so experiments can turn it off).
    root_bound = True
    #: On a repeated split of a pair, weigh conflicts with the other agent in the
    #: child's low level (class attribute so experiments can turn it off).
    avoid_partner = True

    def __init__(
        self,
        instance: Instance,
        deadline: Deadline,
        *,
        w: float,
        polish: bool,
        bypass: bool,
        lacam: str = "off",
        incumbent: Result | None = None,
        low: FocalLowLevel | None = None,
        fallback: Callable[[dict[str, Any]], Result | None] | None = None,
    ) -> None:
        g = instance.graph
        g.precompute_distances(instance.goals)  # one batch
        self.instance = instance
        self.adj = g.adj
        self.n = g.n
        self.k = instance.num_agents
        self.starts = instance.starts
        self.goals: list[int] = instance.goals
        self.dists = [g.dist_list(x) for x in self.goals]
        self.deadline = deadline
        self.w = w
        self.w_high = w  # the high level's factor (w * w_hwy with highways)
        self.polish = polish
        self.bypass = bypass
        self.split_pair = (-1, -1)  # the agents of the conflict split last
        self.res = Reservations(g.n)
        self.best_known_lb = instance.soc_lower_bound()
        self.stats: dict[str, Any] = {
            "high_level_expanded": 0,
            "high_level_generated": 0,
            "low_level_expanded": 0,
            "low_level_calls": 0,
            "bypasses": 0,
            "selected_focal": 0,
            "selected_open": 0,
            "selected_cleanup": 0,
            "head_on_conflicts": 0,
            "w": w,
        }
        # open_lb: every open node by LB (EECBS's CLEANUP); pending: open nodes not yet
        # in FOCAL, by their focal key; focal: by number of conflicts.
        self.open_lb: list[tuple[int, int, _Node]] = []
        self.pending: list[tuple[float, int, _Node]] = []
        self.focal: list[tuple[int, float, int, _Node]] = []
        self.bound = -1.0
        self.nid = 0
        # A lower bound on the optimum of the whole problem (the root's pair bound, once
        # computed): every node's LB is at least this.
        self.floor = 0
        # LaCAM's plan (option ``lacam``): returned when the limit runs out, and with
        # "start" as soon as the bound covers it.
        self.lacam = lacam
        self.inc_plan = incumbent.plan if incumbent is not None else None
        self.inc_cost = int(incumbent.cost or 0) if incumbent is not None else 0
        # ``fallback`` computes LaCAM's plan later (``lacam="fallback"``): at
        # ``fallback_at`` (perf_counter seconds), checked before each low-level call.
        self.fallback = fallback
        self.fallback_at = math.inf
        if fallback is not None:
            limit = deadline.remaining()
            wait = min(FALLBACK_AFTER_S, FALLBACK_AFTER_SHARE * limit)
            self.fallback_at = time.perf_counter() + wait
        self.infeasible_reason: str | None = None  # LaCAM proved that no plan exists
        # The low level (a strategy: plain focal search, or with highways).
        self.low = low if low is not None else FocalLowLevel()
        self.low.prepare(self)
        jit.new_solve()  # the compiled low level is loaded only for a long solve

    # ------------------------------------------------------------------ low level
    def plan(self, a: int, cons: AgentConstraints, partner: int = -1) -> tuple[Path, int] | None:
        """Agent ``a``'s path from the low level around the paths in ``self.res`` and its
        lower bound (conflicts with ``partner`` weigh more in FOCAL)."""
        if time.perf_counter() >= self.fallback_at:
            self.take_fallback()
        return self.low.plan(self, a, cons, partner)

    def take_fallback(self) -> None:
        """Compute the deferred LaCAM plan now (see ``FALLBACK_AFTER_S``)."""
        self.fallback_at = math.inf
        make, self.fallback = self.fallback, None
        r = make(self.stats) if make is not None else None
        if r is None:
            return
        if r.status == Status.INFEASIBLE:
            self.infeasible_reason = _lacam_infeasible(r)
            raise SearchTimeout  # ends the search; search() reports the proof
        self.inc_plan = r.plan
        self.inc_cost = int(r.cost or 0)

    # ------------------------------------------------------------------ root
    def root(self) -> _Node | None:
        """Each agent's focal path around the ones planned before it (None: no path)."""
        root_cons = [AgentConstraints() for _ in range(self.k)]
        paths: list[Path] = []
        lbs: list[int] = []
        conflicts: list[Conflict] = []
        for i in range(self.k):
            out = self.plan(i, root_cons[i])
            if out is None:  # pragma: no cover - the front door's checks catch this
                self.stats["reason"] = f"agent {self.instance.agents[i].name!r} has no path"
                return None
            path, lb = out
            conflicts += self.res.conflicts_of(i, path)
            self.res.add(i, path)
            paths.append(path)
            lbs.append(lb)
        node = _Node(paths, lbs, root_cons, conflicts, 0, 0)
        self.stats["root_cost"] = node.cost
        self.stats["root_conflicts"] = len(conflicts)
        self.stats["high_level_generated"] = 1
        return node

    # ------------------------------------------------------------------ lists
    def focal_key(self, node: _Node) -> float:
        """The key that admits ``node`` to FOCAL (``<= w * LB_min``): its cost."""
        return float(node.cost)

    def push(self, node: _Node) -> None:
        heappush(self.open_lb, (node.lb, node.id, node))
        key = self.focal_key(node)
        if key <= self.bound:
            heappush(self.focal, (len(node.conflicts), key, node.id, node))
        else:
            heappush(self.pending, (key, node.id, node))

    def lb_min(self) -> int | None:
        """The smallest LB of an open node (None when OPEN is empty)."""
        open_lb = self.open_lb
        while open_lb and open_lb[0][2].closed:
            heappop(open_lb)
        return max(open_lb[0][0], self.floor) if open_lb else None

    def raise_bound(self, lbm: int) -> None:
        """Set the focal bound ``w * LB_min`` and move the nodes it admits into FOCAL."""
        new_bound = self.w_high * lbm + _EPS
        if new_bound > self.bound:
            self.bound = new_bound
            pending = self.pending
            while pending and pending[0][0] <= new_bound:
                key, _, nd = heappop(pending)
                if not nd.closed:
                    heappush(self.focal, (len(nd.conflicts), key, nd.id, nd))
        focal = self.focal
        while focal and focal[0][3].closed:
            heappop(focal)

    def select(self) -> _Node:
        """The best FOCAL node (for ECBS the LB-minimal node is always in FOCAL)."""
        if self.focal and self.focal[0][3].cost <= self.bound:
            self.stats["selected_focal"] += 1
            return heappop(self.focal)[3]
        return self.open_lb[0][2]  # pragma: no cover

    def learn(self, node: _Node, children: list[_Node]) -> None:
        """Hook for EECBS's online error estimates (nothing for ECBS)."""

    # ------------------------------------------------------------------ expansion
    def split(self, node: _Node) -> list[tuple[int, Constraint]]:
        """The two branches of the conflict chosen by :func:`split_order`."""
        paths = node.paths
        c = min(node.conflicts, key=lambda c: split_order(c, paths))
        t, kind, a, b, u, v = c
        self.split_pair = (min(a, b), max(a, b))
        if kind == EDGE:  # b moves v -> u while a moves u -> v, arriving at t
            self.stats["head_on_conflicts"] += 1
            return [(b, (NEG_E, b, v, u, t)), (a, (NEG_E, a, u, v, t))]
        return [(b, (NEG_V, b, v, -1, t)), (a, (NEG_V, a, v, -1, t))]

    def child(self, node: _Node, a: int, con: Constraint) -> _Node | None:
        """``node`` with ``con`` on agent ``a``, replanned (None: ``a`` has no path)."""
        cons = list(node.cons)
        cons[a] = cons[a].add(con, n=self.n, goal=self.goals[a])
        self.res.sync(node.paths)
        self.res.remove(a)
        pair = self.split_pair
        # the pair was split on before in this branch: make the new path avoid the other
        partner = -1
        if self.avoid_partner and pair in node.pairs:
            partner = pair[1] if a == pair[0] else pair[0]
        out = self.plan(a, cons[a], partner)
        if out is None:
            return None
        path, lb = out
        new_conf = self.res.conflicts_of(a, path)
        kept = [c for c in node.conflicts if c[2] != a and c[3] != a]
        paths = list(node.paths)
        paths[a] = path
        lbs = list(node.lbs)
        lbs[a] = max(lbs[a], lb)
        self.nid += 1
        self.stats["high_level_generated"] += 1
        return _Node(
            paths,
            lbs,
            cons,
            kept + new_conf,
            self.nid,
            node.depth + 1,
            node.pairs | {pair},
            floor=node.lb,
        )

    def bypassed(self, node: _Node, child: _Node, a: int, lbm: int) -> _Node | None:
        """``node`` with ``child``'s path of ``a`` and no new constraint, if allowed.

        Allowed when the child has fewer conflicts, costs at most ``w * LB_min`` and,
        as in EECBS, the path is within ``w`` of the agent's bound *without* the new
        constraint, so ``cost_i <= w * lb_i`` keeps holding.
        """
        w = self.w_high
        if not (
            self.bypass
            and len(child.conflicts) < len(node.conflicts)
            and child.cost <= w * lbm + _EPS
            and len(child.paths[a]) - 1 <= w * node.lbs[a] + _EPS
        ):
            return None
        self.nid += 1
        self.stats["bypasses"] += 1
        return _Node(
            child.paths,
            list(node.lbs),
            node.cons,
            child.conflicts,
            self.nid,
            node.depth,
            node.pairs,
            floor=node.lb,
        )

    # ------------------------------------------------------------------ search
    def search(self) -> Result:
        """Best-first search of the constraint tree; the result (see :func:`solve`)."""
        try:
            root = self.root()
        except SearchTimeout:
            return self.timeout(self.best_known_lb)
        if root is None:  # pragma: no cover
            return self.result(Status.INFEASIBLE, None)
        root_conflicts = list(root.conflicts)
        root_lb = root.lb
        self.push(root)
        last_log = time.perf_counter()
        while True:
            lbm = self.lb_min()
            if lbm is None:
                self.stats["reason"] = "constraint tree exhausted"
                return self.result(Status.INFEASIBLE, None)
            if time.perf_counter() >= self.fallback_at:
                try:
                    self.take_fallback()
                except SearchTimeout:
                    return self.timeout(max(lbm, self.best_known_lb))
            self.deadline.keep_back_heap()  # freeing the tree fits in the limit
            if self.deadline.expired():
                return self.timeout(max(lbm, self.best_known_lb))
            if self.covers_lacam(lbm):
                return self.from_lacam(max(lbm, self.best_known_lb))
            now = time.perf_counter()
            if now - last_log > 5.0:
                last_log = now
                log.info(
                    "%s: %d expanded, LB %d, open %d, focal %d",
                    self.name,
                    self.stats["high_level_expanded"],
                    lbm,
                    len(self.open_lb),
                    len(self.focal),
                )
            if (
                self.root_bound
                and root_conflicts
                and self.stats["high_level_expanded"] == ROOT_BOUND_AFTER
            ):
                # Not solved at once: the root's pair bound (computed once, a floor
                # under every node's LB: it bounds the optimum of the whole problem).
                try:
                    h = root_pair_bound(self.instance, root_conflicts, self.deadline, self.stats)
                except SearchTimeout:
                    return self.timeout(max(lbm, self.best_known_lb))
                self.stats["root_pair_bound"] = h
                self.floor = root_lb + h
                lbm = max(lbm, self.floor)
            self.raise_bound(lbm)
            node = self.select()
            node.closed = True
            if not node.conflicts:
                return self.finish(node, lbm)
            self.stats["high_level_expanded"] += 1
            tick(
                "expanded",
                self.stats["high_level_expanded"],
                lb=lbm,
                best=None if self.inc_plan is None else self.inc_cost,
            )
            try:
                done = self.expand(node, lbm)
            except SearchTimeout:
                return self.timeout(max(lbm, self.best_known_lb))
            if done is not None:
                return done

    def expand(self, node: _Node, lbm: int) -> Result | None:
        """Generate ``node``'s children (or adopt a bypass); a result if one is a goal."""
        children: list[_Node] = []
        for a, con in self.split(node):
            child = self.child(node, a, con)
            if child is None:
                continue
            lb_now = max(min(lbm, node.lb), self.floor)
            if not child.conflicts and child.cost <= self.w_high * lb_now + _EPS:
                return self.finish(child, lb_now)
            adopted = self.bypassed(node, child, a, lbm)
            if adopted is not None:
                self.push(adopted)
                return None
            children.append(child)
        self.learn(node, children)
        for c in children:
            self.push(c)
        node.conflicts = []  # expanded: free memory (children keep their own lists)
        return None

    # ------------------------------------------------------------------ results
    def polished(self, paths: list[Path]) -> list[Path]:
        """One sweep: each agent in turn takes a shortest path around the others, if shorter.

        The plan stays conflict-free and its cost only decreases, so the bound still
        holds. Effort is capped at a quarter of the search's low-level expansions
        (deterministic, proportional).
        """
        paths = list(paths)
        res = self.res
        res.sync(paths)
        stats = self.stats
        gain = 0
        allowance = max(_POLISH_MIN, stats["low_level_expanded"] * _POLISH_SHARE)
        spent0 = stats["low_level_expanded"]
        starts, dists = self.starts, self.dists
        free = AgentConstraints()
        # Smallest detours first: each costs one more f-layer of A*, so the cheap
        # checks come first (measured better than largest-first and index order).
        order = sorted(range(self.k), key=lambda i: len(paths[i]) - dists[i][starts[i]])
        for a in order:
            old = paths[a]
            left = int(allowance - (stats["low_level_expanded"] - spent0))
            if left <= 0 or self.deadline.expired():
                break
            if len(old) - 1 <= dists[a][starts[a]]:
                continue
            res.remove(a)
            try:
                out = focal_path(
                    self.adj,
                    starts[a],
                    self.goals[a],
                    dists[a],
                    free,
                    res,
                    deadline=self.deadline,
                    max_t=len(old) - 1,
                    stats=stats,
                    budget=-1,
                    avoid=True,
                    limit=left,
                )
            except SearchTimeout:
                out = None
            new = out[0] if out is not None and len(out[0]) < len(old) else old
            gain += len(old) - len(new)
            res.add(a, new)
            paths[a] = new
        stats["polish_gain"] = gain
        return paths

    def finish(self, node: _Node, lb: int) -> Result:
        paths = self.polished(node.paths) if self.polish else node.paths
        plan = Plan(tuple(paths))
        cost = sum(len(p) - 1 for p in paths)
        lb = max(lb, self.best_known_lb)
        self.stats["runtime"] = self.deadline.elapsed()
        self.stats["depth"] = node.depth
        self.stats["cost_before_polish"] = node.cost
        if self.lacam == "start" and self.inc_plan is not None and self.inc_cost < cost:
            return self.from_lacam(lb)
        self.stats["plan_from"] = "search"
        self.stats["bound_met"] = True  # the search's own plan: cost <= w * LB
        status = Status.OPTIMAL if cost <= lb else Status.FEASIBLE
        return self.result(status, plan, cost, min(lb, cost))

    def timeout(self, lb: float) -> Result:
        """The result when the limit (time or memory) stopped the search: LaCAM's plan
        if there is one, else TIME_LIMIT; ``stats["stopped_by"]`` names the limit."""
        if self.infeasible_reason is not None:
            self.stats["reason"] = self.infeasible_reason
            return self.result(Status.INFEASIBLE, None)
        self.stats.update(self.deadline.limit_stats(self.name.upper()))
        if self.inc_plan is not None:
            return self.from_lacam(lb)
        return self.result(Status.TIME_LIMIT, None, None, lb)

    def covers_lacam(self, lbm: int) -> bool:
        """With ``lacam="start"``: whether ``w * LB_min`` covers LaCAM's plan."""
        return (
            self.lacam == "start"
            and self.inc_plan is not None
            and self.inc_cost <= self.w_high * lbm + 1e-9
        )

    def from_lacam(self, lb: float) -> Result:
        """LaCAM's plan with this search's own lower bound."""
        self.stats["plan_from"] = "lacam"
        cost = self.inc_cost
        # Result.bound_met: whether this plan is shown within the bound asked (w * LB).
        self.stats["bound_met"] = bool(cost <= self.w_high * lb + 1e-9)
        status = Status.OPTIMAL if cost <= lb else Status.FEASIBLE
        return self.result(status, self.inc_plan, cost, min(lb, cost))

    def result(
        self, status: Status, plan: Plan | None, cost: float | None = None, lb: float | None = None
    ) -> Result:
        if plan is not None:
            self.low.annotate(self.stats, plan)
        self.stats.update(self.deadline.stop_stats(self.name.upper()))
        self.stats["runtime"] = self.deadline.elapsed()
        return Result(status, plan, cost, lb, stats=self.stats, objective="soc")


#: The option of the suboptimality factor, shared with EECBS.
W_OPTION = Option("w", "float", "suboptimality bound: cost <= w * optimum", low=1.0, high=1e9)
POLISH_OPTION = Option("polish", "bool", "shorten paths one by one after the search")
LACAM_OPTION = Option(
    "lacam",
    "choice",
    "LaCAM's plan when the limit runs out (fallback), also as an early stop (start), or off",
    choices=LACAM_MODES,
)


def _lacam_plan(
    instance: Instance, mode: str, time_limit: float | None, seed: int, stats: dict[str, Any]
) -> Result | None:
    """LaCAM's first plan for ``mode`` (None when not asked for or not found in time)."""
    if mode == "off" or (mode == "fallback" and time_limit is None):
        return None
    budget = None if time_limit is None else LACAM_SHARE * time_limit
    # Through the registry (solvers do not import each other); the bare function: the
    # front door has checked the instance already.
    lacam_solve = registry.get("lacam").load()
    r = lacam_solve.fn(instance, time_limit=budget, seed=seed, anytime=0)
    stats["lacam_status"] = r.status.value
    stats["lacam_time"] = r.stats.get("first_time", budget)
    if r.status == Status.INFEASIBLE or r.plan is None:
        return r if r.status == Status.INFEASIBLE else None
    stats["lacam_cost"] = r.cost
    return r


def _lacam_infeasible(r: Result) -> str:
    """The reason of an INFEASIBLE answer that LaCAM's exhausted search proved."""
    return f"lacam: {r.stats.get('reason', 'no plan exists')}"


def run_search(
    cls: type[_ECBS],
    instance: Instance,
    time_limit: float | None,
    seed: int,
    *,
    w: float,
    polish: bool,
    bypass: bool,
    lacam: str,
) -> Result:
    """LaCAM's plan first (option ``lacam``), then the search ``cls`` in the rest."""
    deadline = Deadline(time_limit)
    extra: dict[str, Any] = {}
    incumbent = None
    if lacam != "fallback":  # "start" needs the plan from the start (see the module doc)
        incumbent = _lacam_plan(instance, lacam, time_limit, seed, extra)
    if incumbent is not None and incumbent.status == Status.INFEASIBLE:
        extra["reason"] = _lacam_infeasible(incumbent)
        extra["runtime"] = deadline.elapsed()
        return Result(Status.INFEASIBLE, None, stats=extra, objective="soc")
    fallback: Callable[[dict[str, Any]], Result | None] | None = None
    if lacam == "fallback" and time_limit is not None:

        def deferred(stats: dict[str, Any]) -> Result | None:
            return _lacam_plan(instance, lacam, time_limit, seed, stats)

        fallback = deferred

    def make() -> _ECBS:
        search = cls(
            instance,
            deadline,
            w=w,
            polish=polish,
            bypass=bypass,
            lacam=lacam,
            incumbent=incumbent,
            fallback=fallback,
        )
        search.stats.update(extra)
        return search

    return searched(make)


def searched(make: Callable[[], _ECBS]) -> Result:
    """The result of ``make()``'s search, with the cyclic collector paused as in CBS
    (``core.collector``: 9.7 of 30 s went to it on empty-32-32 k200, EECBS w 1.005).

    The search object dies inside the block, so its tree is freed by reference
    counting (within the time limit, see ``Deadline.keep_back_heap``), not by the
    next full collection after it.
    """
    with paused_gc():
        return make().search()


def run_with_highways(
    cls: type[_ECBS],
    instance: Instance,
    time_limit: float | None,
    *,
    highways: str,
    w_hwy: float,
    hwy_mode: str,
    w: float,
    polish: bool,
    bypass: bool,
) -> Result:
    """The search ``cls`` with the highway low level (:mod:`hierplan_opt.search.highways`):
    ECBS(w)+HWY(w_hwy), EECBS(w)+HWY(w_hwy), or CBS+HWY(w_hwy) as ECBS(1)+HWY(w_hwy).

    Example
    -------
    >>> from hierplan_opt.core.graph import Graph
    >>> g = Graph.grid(5, 2, obstacles=[(0, 1), (1, 1), (3, 1), (4, 1)])
    >>> inst = Instance.mapf(g, [(0, 0), (4, 0)], [(4, 0), (0, 0)])
    >>> r = run_with_highways(_ECBS, inst, 10, highways="crisscross", w_hwy=2.0,
    ...                       hwy_mode="heuristic", w=1.2, polish=True, bypass=False)
    >>> r.stats["bound"], r.cost <= 2.4 * r.lower_bound
    (2.4, True)
    """
    deadline = Deadline(time_limit)
    low = HighwayLowLevel(resolve(instance, highways, cls.name), w_hwy, hwy_mode)

    def make() -> _ECBS:
        search = cls(instance, deadline, w=w, polish=polish, bypass=bypass, low=low)
        search.stats["highway_time"] = deadline.elapsed()
        return search

    return searched(make)


#: ECBS's option ``bypass`` (off by default; CBS+HWY runs ECBS(1) with CBS's bypass).
BYPASS_OPTION = Option(
    "bypass", "bool", "adopt a child's path when it lowers the conflicts in the bound"
)
