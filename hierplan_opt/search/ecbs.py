"""ECBS(w): bounded-suboptimal conflict-based search (Barer et al., SoCS 2014).

Both levels are focal searches with the same suboptimality factor ``w``:

* low level (:mod:`hierplan_opt.search.focal`): each agent's path costs at most
  ``w * lb_i``, where ``lb_i`` is the low-level ``f_min`` when the path was found (a
  lower bound on the agent's optimal cost under its constraints), and FOCAL prefers
  states with fewer conflicts with the other agents' paths;
* high level: OPEN holds constraint-tree nodes ordered by ``LB(N) = sum_i lb_i``;
  FOCAL = {N in OPEN : cost(N) <= w * LB_min} ordered by the number of conflicts.

A conflict-free node taken from FOCAL costs at most ``w * LB_min <= w * optimal``.
The search reports ``lower_bound = LB_min`` so ``cost / lower_bound`` is the proven
suboptimality.

The conflict split is a target conflict (an agent on another's goal after that one
has arrived for good) when there is one, else the earliest. With ``polish=True`` the
solution is finally improved agent by agent (shortest path around the others, never
longer), which keeps the plan valid and the bound.

The same engine, :func:`focal_cbs`, runs EECBS (:mod:`hierplan_opt.search.eecbs`):
explicit estimation search at the high level and bypassing. See ``docs/ecbs.md``.
"""

from __future__ import annotations

import logging
import time
from heapq import heappop, heappush
from typing import Any

from hierplan_opt.core.errors import OptionError
from hierplan_opt.core.feasibility import quick_infeasibility
from hierplan_opt.core.instance import Instance
from hierplan_opt.core.plan import Plan
from hierplan_opt.core.result import Result, Status
from hierplan_opt.core.timer import Deadline
from hierplan_opt.search.focal import Reservations, SearchTimeout, focal_path, goal_visits

log = logging.getLogger(__name__)

_EMPTY: frozenset[int] = frozenset()

#: Cap on EECBS's learned one-step error of "conflicts left" as a distance-to-go. The
#: estimate ``d / (1 - eps_d)`` explodes as ``eps_d -> 1`` (resolving one conflict often
#: creates others), which empties FOCAL and degrades EECBS to best-first search on LB;
#: capping keeps the inflation at most 2x. Any estimate keeps the bound.
_MAX_EPS_D = 0.5

#: Polishing may spend this share of the search's low-level expansions (at least
#: ``_POLISH_MIN``): on warehouse-10-20-10-2-1 it otherwise doubles the run time.
_POLISH_SHARE = 0.25
_POLISH_MIN = 20_000


# A conflict is (kind, t, a1, a2, x, y): a vertex conflict at x at time t when y == -1,
# else an edge conflict: a1 moves x -> y while a2 moves y -> x between t and t + 1.
# kind 0 marks a *target* conflict (x is the goal of a2, which has already arrived
# there for good: split like a vertex conflict), kind 1 any other. The split conflict
# is the smallest tuple: target conflicts first (they are the ones that tend to be
# cardinal, cf. target reasoning in CBSH2-RTC; on maze-32-32-2 with 30 agents this
# cut the high-level expansions from 165 to 7), then the earliest.
Conflict = tuple[int, int, int, int, int, int]


class _Node:
    """A constraint-tree node. ``cons = (agent, is_edge, key)`` is the constraint added
    on top of ``parent``'s; ``lbs[i]`` the low-level lower bound of agent ``i``."""

    __slots__ = (
        "paths",
        "lbs",
        "cost",
        "lb",
        "conflicts",
        "cons",
        "parent",
        "id",
        "fhat",
        "closed",
        "depth",
    )

    def __init__(
        self,
        paths: list[tuple[int, ...]],
        lbs: list[int],
        cost: int,
        lb: int,
        conflicts: list[Conflict],
        cons: tuple[int, bool, int] | None,
        parent: _Node | None,
        nid: int,
    ) -> None:
        self.paths = paths
        self.lbs = lbs
        self.cost = cost
        self.lb = lb
        self.conflicts = conflicts
        self.cons = cons
        self.parent = parent
        self.id = nid
        self.fhat = float(cost)
        self.closed = False
        self.depth = 0 if parent is None else parent.depth + 1


def conflicts_of(
    a: int,
    path: tuple[int, ...],
    res: Reservations,
    paths: list[tuple[int, ...] | None],
) -> list[Conflict]:
    """Every conflict between agent ``a`` on ``path`` and the paths in ``res``.

    ``paths[j]`` must be the path of ``j`` reserved in ``res`` (None if absent);
    ``paths[a]`` is ignored.

    Example
    -------
    >>> r = Reservations(4)
    >>> r.add(1, (3, 2, 1))
    >>> conflicts_of(0, (0, 1, 2), r, [None, (3, 2, 1)])
    [(1, 1, 0, 1, 1, 2)]
    """
    n = res.n
    vt = res.vt
    et = res.et
    parked = res.parked
    out: list[Conflict] = []
    prev = -1
    for t, v in enumerate(path):
        occ = vt.get(t * n + v)
        if occ:
            p = parked.get(v)
            for j in occ:
                # j is at its goal at its very last step: a target conflict too
                out.append((0 if p is not None and p[1] == j and p[0] == t else 1, t, a, j, v, -1))
        p = parked.get(v)
        if p is not None and t > p[0]:
            out.append((0, t, a, p[1], v, -1))
        if t and prev != v:
            occ = et.get(((t - 1) * n + v) * n + prev)
            if occ:
                for j in occ:
                    out.append((1, t - 1, a, j, prev, v))
        prev = v
    last = len(path) - 1
    goal = path[-1]
    for j, pj in enumerate(paths):
        if j == a or pj is None or len(pj) <= last + 1 or goal not in pj:
            continue
        for t in range(last + 1, len(pj)):
            if pj[t] == goal:
                out.append((0, t, j, a, goal, -1))
    return out


def _cost(path: tuple[int, ...]) -> int:
    return len(path) - 1


def check_w(w: float) -> float:
    """Refuse a suboptimality factor below 1 (or not a finite number).

    Example
    -------
    >>> check_w(1.5)
    1.5
    """
    if isinstance(w, bool) or not isinstance(w, (int, float)) or not (1.0 <= float(w) < 1e9):
        raise OptionError(f"w must be a number >= 1 (the suboptimality bound), got {w!r}")
    return float(w)


def focal_cbs(
    instance: Instance,
    *,
    time_limit: float | None,
    objective: str,
    w: float,
    explicit_estimation: bool,
    bypass: bool,
    solver: str,
    polish: bool = True,
) -> Result:
    """The ECBS / EECBS engine (see the module docstring and :mod:`.eecbs`)."""
    if objective != "soc":
        raise OptionError(f"{solver} optimises only the sum of costs ('soc'), not {objective!r}")
    w = check_w(w)
    deadline = Deadline(time_limit)
    stats: dict[str, Any] = {
        "high_level_expanded": 0,
        "high_level_generated": 0,
        "low_level_expanded": 0,
        "low_level_calls": 0,
        "bypasses": 0,
        "selected_focal": 0,
        "selected_open": 0,
        "selected_cleanup": 0,
        "w": w,
    }
    if instance.is_tapf:
        raise OptionError(f"{solver} solves MAPF instances (fixed goals), not TAPF")
    g = instance.graph
    if not instance.is_tapf:
        g.precompute_distances(instance.goals)  # one batch, before the checks use them
    why = quick_infeasibility(instance)
    if why is not None:
        stats["reason"] = why
        return Result(Status.INFEASIBLE, None, stats=stats, objective=objective)

    n = g.n
    k = instance.num_agents
    starts = instance.starts
    goals: list[int] = instance.goals
    hs = [g.dist_list(x) for x in goals]
    adj_self = [list(a) + [v] for v, a in enumerate(g.adj)]
    res = Reservations(n)
    cur: list[tuple[int, ...] | None] = [None] * k
    best_known_lb = instance.soc_lower_bound()

    def sync(paths: list[tuple[int, ...]]) -> None:
        for j in range(k):
            c = cur[j]
            p = paths[j]
            if c is not p:
                if c is not None:
                    res.remove(j, c)
                res.add(j, p)
                cur[j] = p

    def timeout(lb: float) -> Result:
        stats["runtime"] = deadline.elapsed()
        return Result(Status.TIME_LIMIT, None, None, lb, stats=stats, objective=objective)

    def polished(paths: list[tuple[int, ...]]) -> list[tuple[int, ...]]:
        # One sweep: each agent in turn takes a shortest path that avoids every other
        # agent's current path, if that is shorter. The plan stays conflict-free and
        # its cost only decreases, so the bound still holds. Effort is capped at a
        # quarter of the search's low-level expansions (deterministic, proportional).
        paths = list(paths)
        sync(paths)
        gain = 0
        allowance = max(_POLISH_MIN, stats["low_level_expanded"] * _POLISH_SHARE)
        spent0 = stats["low_level_expanded"]
        # Smallest detours first: each costs one more f-layer of A*, so the cheap
        # checks come first (measured better than largest-first and index order).
        order = sorted(range(k), key=lambda i: len(paths[i]) - hs[i][starts[i]])
        for a in order:
            old = paths[a]
            left = int(allowance - (stats["low_level_expanded"] - spent0))
            if left <= 0 or deadline.expired():
                break
            if len(old) - 1 <= hs[a][starts[a]]:
                continue
            res.remove(a, old)
            cur[a] = None
            try:
                out = focal_path(
                    adj_self,
                    hs[a],
                    starts[a],
                    goals[a],
                    1.0,
                    _EMPTY,
                    _EMPTY,
                    res,
                    goal_visits(goals[a], a, paths),
                    deadline=deadline,
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
            cur[a] = new
            paths[a] = new
        stats["polish_gain"] = gain
        return paths

    def finish(node: _Node, lb: int) -> Result:
        paths = polished(node.paths) if polish else node.paths
        plan = Plan(tuple(paths))
        cost = sum(map(_cost, paths))
        lb = max(lb, best_known_lb)
        status = Status.OPTIMAL if cost <= lb else Status.FEASIBLE
        stats["runtime"] = deadline.elapsed()
        stats["depth"] = node.depth
        stats["cost_before_polish"] = node.cost
        return Result(status, plan, cost, min(lb, cost), stats=stats, objective=objective)

    # ------------------------------------------------------------------ root
    root_paths: list[tuple[int, ...]] = []
    root_lbs: list[int] = []
    conflicts: list[Conflict] = []
    try:
        for i in range(k):
            stats["low_level_calls"] += 1
            out = focal_path(
                adj_self,
                hs[i],
                starts[i],
                goals[i],
                w,
                _EMPTY,
                _EMPTY,
                res,
                goal_visits(goals[i], i, cur),
                deadline=deadline,
                stats=stats,
            )
            if out is None:  # pragma: no cover - quick_infeasibility catches this
                stats["reason"] = f"agent {instance.agents[i].name!r} has no path"
                return Result(Status.INFEASIBLE, None, stats=stats, objective=objective)
            path, lb = out
            conflicts += conflicts_of(i, path, res, cur)
            res.add(i, path)
            cur[i] = path
            root_paths.append(path)
            root_lbs.append(lb)
    except SearchTimeout:
        return timeout(best_known_lb)
    nid = 0
    root = _Node(
        list(root_paths),
        root_lbs,
        sum(map(_cost, root_paths)),
        sum(root_lbs),
        conflicts,
        None,
        None,
        nid,
    )
    stats["root_cost"] = root.cost
    stats["root_conflicts"] = len(conflicts)
    stats["high_level_generated"] = 1

    # ------------------------------------------------------------------ lists
    # open_lb: all open nodes by LB (EECBS's CLEANUP); pending: open nodes not yet in
    # FOCAL by their focal key (cost for ECBS, f-hat for EECBS); focal: by conflicts.
    open_lb: list[tuple[int, int, _Node]] = []
    pending: list[tuple[float, int, _Node]] = []
    focal: list[tuple[int, float, int, _Node]] = []
    open_fhat: list[tuple[float, int, _Node]] = []
    bound = -1.0
    # Online error estimates of EECBS: cost increase per expansion and the error of
    # the number of conflicts as a distance-to-go.
    err = {"n": 0, "c": 0.0, "d": 0.0}

    def estimate(node: _Node) -> float:
        if not explicit_estimation or err["n"] == 0:
            return float(node.cost)
        eps_c = err["c"] / err["n"]
        eps_d = min(err["d"] / err["n"], _MAX_EPS_D)
        return node.cost + eps_c * len(node.conflicts) / (1.0 - eps_d)

    def push(node: _Node) -> None:
        heappush(open_lb, (node.lb, node.id, node))
        node.fhat = estimate(node)
        key = node.fhat if explicit_estimation else float(node.cost)
        if explicit_estimation:
            heappush(open_fhat, (node.fhat, node.id, node))
        if key <= bound:
            heappush(focal, (len(node.conflicts), key, node.id, node))
        else:
            heappush(pending, (key, node.id, node))

    def lb_min() -> int | None:
        while open_lb and open_lb[0][2].closed:
            heappop(open_lb)
        return open_lb[0][0] if open_lb else None

    def constraints(node: _Node, a: int) -> tuple[set[int], set[int]]:
        vc: set[int] = set()
        ec: set[int] = set()
        nd: _Node | None = node
        while nd is not None:
            c = nd.cons
            if c is not None and c[0] == a:
                (ec if c[1] else vc).add(c[2])
            nd = nd.parent
        return vc, ec

    push(root)
    last_log = time.perf_counter()
    while True:
        lbm = lb_min()
        if lbm is None:
            stats["runtime"] = deadline.elapsed()
            stats["reason"] = "constraint tree exhausted"
            return Result(Status.INFEASIBLE, None, stats=stats, objective=objective)
        if deadline.expired():
            return timeout(max(lbm, best_known_lb))
        now = time.perf_counter()
        if now - last_log > 5.0:
            last_log = now
            log.info(
                "%s: %d expanded, LB %d, open %d, focal %d",
                solver,
                stats["high_level_expanded"],
                lbm,
                len(open_lb),
                len(focal),
            )
        new_bound = w * lbm + 1e-9
        if new_bound > bound:
            bound = new_bound
            while pending and pending[0][0] <= bound:
                key, _, nd = heappop(pending)
                if not nd.closed:
                    heappush(focal, (len(nd.conflicts), key, nd.id, nd))
        while focal and focal[0][3].closed:
            heappop(focal)

        # -------------------------------------------------------------- select
        node: _Node | None = None
        if focal and focal[0][3].cost <= bound:
            node = heappop(focal)[3]
            stats["selected_focal"] += 1
        elif explicit_estimation:
            while open_fhat and open_fhat[0][2].closed:
                heappop(open_fhat)
            best_f = open_fhat[0][2] if open_fhat else None
            if best_f is not None and best_f.cost <= bound:
                node = best_f
                stats["selected_open"] += 1
            else:
                node = open_lb[0][2]
                stats["selected_cleanup"] += 1
        else:  # pragma: no cover - the LB-min node is always in FOCAL for ECBS
            node = open_lb[0][2]
        node.closed = True
        if not node.conflicts:
            return finish(node, lbm)
        stats["high_level_expanded"] += 1

        # -------------------------------------------------------------- expand
        _, t, a1, a2, x, y = min(node.conflicts)
        if y < 0:
            branches = [(a1, False, t * n + x), (a2, False, t * n + x)]
        else:
            branches = [(a1, True, (t * n + x) * n + y), (a2, True, (t * n + y) * n + x)]
        children: list[_Node] = []
        adopted: _Node | None = None
        for a, is_edge, key in branches:
            vc, ec = constraints(node, a)
            (ec if is_edge else vc).add(key)
            sync(node.paths)
            res.remove(a, node.paths[a])
            cur[a] = None
            stats["low_level_calls"] += 1
            try:
                out = focal_path(
                    adj_self,
                    hs[a],
                    starts[a],
                    goals[a],
                    w,
                    vc,
                    ec,
                    res,
                    goal_visits(goals[a], a, node.paths),
                    deadline=deadline,
                    stats=stats,
                )
            except SearchTimeout:
                return timeout(max(lbm, best_known_lb))
            if out is None:
                continue
            path, lb = out
            new_conf = conflicts_of(a, path, res, node.paths)
            kept = [c for c in node.conflicts if c[2] != a and c[3] != a]
            paths = list(node.paths)
            paths[a] = path
            lbs = list(node.lbs)
            lbs[a] = max(lbs[a], lb)
            nid += 1
            child = _Node(
                paths,
                lbs,
                node.cost - _cost(node.paths[a]) + _cost(path),
                node.lb - node.lbs[a] + lbs[a],
                kept + new_conf,
                (a, is_edge, key),
                node,
                nid,
            )
            stats["high_level_generated"] += 1
            lb_now = min(lbm, node.lb)
            if not child.conflicts and child.cost <= w * lb_now + 1e-9:
                return finish(child, lb_now)
            if (
                bypass
                and len(child.conflicts) < len(node.conflicts)
                and child.cost <= w * lbm + 1e-9
                and _cost(path) <= w * node.lbs[a] + 1e-9
            ):
                # Bypass: adopt the child's path in the parent (no new constraint).
                # As in EECBS, the path must also be within w of the agent's bound
                # *without* the new constraint, so cost_i <= w * lb_i keeps holding.
                nid += 1
                adopted = _Node(
                    paths,
                    list(node.lbs),
                    child.cost,
                    node.lb,
                    child.conflicts,
                    node.cons,
                    node.parent,
                    nid,
                )
                adopted.depth = node.depth
                stats["bypasses"] += 1
                break
            children.append(child)
        if adopted is not None:
            push(adopted)
            continue
        if explicit_estimation and children:
            best = min(children, key=lambda c: (c.cost, len(c.conflicts)))
            err["n"] += 1
            err["c"] += max(0, best.cost - node.cost)
            err["d"] += max(0, len(best.conflicts) - (len(node.conflicts) - 1))
        for c in children:
            push(c)
        node.conflicts = []  # expanded: free memory (children keep their own lists)


def solve(
    instance: Instance,
    *,
    time_limit: float | None = None,
    seed: int = 0,
    objective: str = "soc",
    w: float = 1.2,
    polish: bool = True,
) -> Result:
    """ECBS(w): a plan whose sum of costs is at most ``w`` times the optimum.

    Parameters
    ----------
    w
        Suboptimality factor (``>= 1``) used by both the low and the high level.
    polish
        After the search, give each agent in turn a shortest path around the others'
        paths when that is shorter (keeps the plan valid and the bound; typically
        2-4 % lower cost). ``False`` returns the plain ECBS solution.

    Returns
    -------
    Result
        FEASIBLE (OPTIMAL when the cost meets the lower bound) with ``lower_bound`` the
        smallest LB in OPEN; TIME_LIMIT with the lower bound; INFEASIBLE when proven.

    Example
    -------
    >>> from hierplan_opt.core.graph import Graph
    >>> g = Graph.grid(5, 2, obstacles=[(0, 1), (1, 1), (3, 1), (4, 1)])
    >>> inst = Instance.mapf(g, [(0, 0), (1, 0)], [(4, 0), (3, 0)])
    >>> r = solve(inst, w=1.5)
    >>> r.cost <= 1.5 * 8, r.cost / r.lower_bound <= 1.5
    (True, True)
    """
    del seed  # deterministic
    return focal_cbs(
        instance,
        time_limit=time_limit,
        objective=objective,
        w=w,
        explicit_estimation=False,
        bypass=False,
        solver="ecbs",
        polish=bool(polish),
    )
