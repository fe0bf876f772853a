"""LaCAM*: lazy constraints addition search for MAPF, complete and anytime.

LaCAM (Okumura, AAAI 2023) searches over *configurations* (one vertex per agent).
A high-level node is a configuration; its successors are generated lazily, one per
visit: a low-level search tree of *constraints* ("agent i goes to vertex v next",
added breadth-first, agent by agent in priority order) says what the next successor
must respect, and PIBT (:mod:`hierplan_opt.search.pibt_engine`) completes it. A node is
dropped only when its constraint tree is exhausted, i.e. when every successor
configuration has been generated, so the search is complete: it finds a plan when
one exists and otherwise proves that none does. Nodes are kept on a stack (depth
first), which makes the first solution come as fast as PIBT when PIBT alone would
succeed.

LaCAM* (Okumura, IJCAI 2023) keeps searching after the first solution. Nodes remember
the transitions found between them; whenever a cheaper way into a node appears the
new cost is propagated to everything reachable from it (*rewiring*), and nodes whose
cost plus an admissible estimate reaches the incumbent are pruned. When the stack runs
empty the incumbent is optimal.

**Sum of costs.** LaCAM*'s guarantee holds for costs that add up over transitions; the
sum of costs does not (an agent that waits at its goal and leaves later pays for the
waiting, one that stays does not). Our anytime search therefore runs on configurations
augmented with the set ``F`` of *finished* agents: a finished agent rests on its goal
for good. A transition ``(Q, F) -> (Q', F')`` keeps ``F ⊆ F'`` and costs one per agent
not finished in ``F'`` plus one per agent that became finished by moving onto its goal.
A plan whose agents are marked finished on their final arrival then costs exactly its
sum of costs, every plan has such a path, and ``sum over unfinished agents of the
distance to goal`` is a consistent heuristic. The low-level constraints also decide,
for an agent on its goal, whether it is finished, so successors are still enumerated
completely; by default an agent becomes finished after waiting one step on its goal.

**Refinements** (Okumura, AAMAS 2024 "Engineering LaCAM*", which we adopt as measured
in ``docs/lacam.md``): PIBT with the swap technique and elapsed-time priorities as the
configuration generator (IJCAI 2023); random restarts of the search from the start
node and random picks from the stack after the first solution; optional Monte-Carlo
configuration generation (``mc`` PIBT runs per successor, the one with the smallest
estimate wins); and iterative refinement of the incumbent by large neighbourhood
search (:mod:`hierplan_opt.search.lns`), whose plans are inserted into the search graph
so that the search continues from them. The search and the refiner take turns in one
thread.
"""

from __future__ import annotations

import logging
import random
from array import array
from collections import deque
from collections.abc import Callable, Sequence
from dataclasses import dataclass

from hierplan_opt.core.errors import OptionError
from hierplan_opt.core.instance import Instance
from hierplan_opt.core.options import Option
from hierplan_opt.core.result import Result, Status
from hierplan_opt.core.timer import Deadline
from hierplan_opt.registry import solver
from hierplan_opt.search.guidance import guide_paths, guide_table
from hierplan_opt.search.lns import Refiner
from hierplan_opt.search.pibt_engine import (
    NIL,
    PIBT,
    SWAP_OPTION,
    Expired,
    Space,
    initial_priorities,
    next_priorities,
    prepare,
    priority_order,
    sum_of_costs,
)

log = logging.getLogger(__name__)

#: On reaching a known configuration, continue from the start node instead (AAMAS 2024).
P_RESTART = 0.001
#: After the first solution, expand a random node of the stack instead of the top.
P_RANDOM_PICK = 0.01
#: One round of the anytime phase: the search for a number of iterations (starting at
#: SEARCH_ITERATIONS, adapted within the bounds), then REFINE_STEPS LNS neighbourhoods.
SEARCH_ITERATIONS = 64
MIN_SEARCH_ITERATIONS = 4
MAX_SEARCH_ITERATIONS = 4096
REFINE_STEPS = 4
#: The anytime search stops storing nodes beyond this many per-agent entries
#: (configurations, priorities, orders; about 8 bytes each); the refiner goes on alone.
MAX_STORED = 30_000_000

Conf = tuple[int, ...]


class _Node:
    """A high-level node: configuration ``q`` with finished flags ``fin`` (phase 2)."""

    __slots__ = ("q", "fin", "parent", "succ", "g", "h", "f", "prio", "order", "tree", "goal")

    def __init__(self, q: Conf, fin: bytes, parent: _Node | None, g: int, h: int, goal: bool):
        self.q = q
        self.fin = fin
        self.parent = parent
        self.succ: dict[_Node, int] = {}
        self.g = g
        self.h = h
        self.f = g + h
        self.prio: array[float] | None = None  # compact: many nodes, many agents
        self.order: list[int] | None = None
        self.tree: deque[tuple[tuple[int, ...], tuple[int, ...]]] | None = None
        self.goal = goal


class _LaCAM:
    """The search: :meth:`first_solution` (LaCAM), then :meth:`improve` (LaCAM*)."""

    def __init__(
        self,
        space: Space,
        seed: int,
        *,
        swap: bool = True,
        mc: int = 1,
        guide: list[dict[int, int]] | None = None,
    ) -> None:
        self.space = space
        self.n = space.n_agents
        self.goals = space.goals
        self.goal_q: Conf = tuple(space.goals)
        self.rng = random.Random(seed)
        self.pibts = [
            PIBT(space, seed * 1_000_003 + k, swap=swap, guide=guide) for k in range(max(1, mc))
        ]
        self.star = False
        self.root: _Node | None = None
        self.explored: dict[object, _Node] = {}
        self.open: list[_Node] = []
        self.best = 1 << 62
        self.best_node: _Node | None = None
        self.best_configs: list[Conf] | None = None
        self.stored = 0
        self.full = False
        self.iterations = 0
        self.nodes = 0

    # ------------------------------------------------------------------ nodes
    def _make(self, q: Conf, fin: bytes, parent: _Node | None, g: int, h: int) -> _Node:
        node = _Node(q, fin, parent, g, h, q == self.goal_q)
        self.explored[(q, fin) if self.star else q] = node
        self.nodes += 1
        self.stored += self.n
        return node

    def _prepare(self, node: _Node) -> None:
        """Priorities, agent order and the constraint tree, computed on first visit."""
        if node.order is not None:
            return
        chain = []
        x: _Node | None = node
        while x is not None and x.prio is None:
            chain.append(x)
            x = x.parent
        for y in reversed(chain):
            if y.parent is None:
                y.prio = array("d", initial_priorities(self.space))
            else:
                assert y.parent.prio is not None
                y.prio = array("d", next_priorities(y.parent.prio, y.q, self.goals))
        assert node.prio is not None
        order = priority_order(node.prio)
        if self.star:
            fin = node.fin
            order = [i for i in order if not fin[i]]
        node.order = order
        node.tree = deque([((), ())])
        self.stored += 2 * self.n

    # ------------------------------------------------------------------ low level
    def next_constraints(self, node: _Node) -> tuple[tuple[int, ...], tuple[int, ...]] | None:
        """The next constraint set of ``node`` (breadth first), or None when exhausted.

        Children constrain the next agent in priority order to each of its possible
        moves; in the anytime phase an agent that can be on its goal gets two
        children for it: finished (``v``) and not finished (``~v``).
        """
        self._prepare(node)
        tree = node.tree
        assert tree is not None and node.order is not None
        if not tree:
            return None
        who, where = tree.popleft()
        depth = len(who)
        if depth < len(node.order):
            i = node.order[depth]
            cands = self.space.perms[node.q[i]][0][:]
            self.rng.shuffle(cands)
            nwho = (*who, i)
            gl = self.goals[i]
            for u in cands:
                tree.append((nwho, (*where, u)))
                if self.star and u == gl:
                    tree.append((nwho, (*where, ~u)))
        return who, where

    # ------------------------------------------------------------------ successors
    def successor(self, node: _Node, cons: tuple[tuple[int, ...], tuple[int, ...]]):
        """Configuration generation: PIBT completes the constraints (best of ``mc`` runs).

        Returns ``(q, fin, cost, h)`` or None when PIBT finds no completion.
        """
        who, where = cons
        assert node.order is not None
        best = None
        for pibt in self.pibts if self.star else self.pibts[:1]:
            q_to = [NIL] * self.n
            fixed = list(who)
            marks: dict[int, bool] = {}
            for i, u in zip(who, where, strict=True):
                if u < 0:
                    q_to[i] = ~u
                    marks[i] = False
                else:
                    q_to[i] = u
                    if u == self.goals[i]:
                        marks[i] = True
            if self.star:
                fin = node.fin
                goals = self.goals
                for i in range(self.n):
                    if fin[i]:
                        q_to[i] = goals[i]
                        fixed.append(i)
            if not pibt.step(node.q, q_to, node.order, fixed):
                continue
            if not self.star:
                return tuple(q_to), b"", 0, 0
            fin2, cost, h = self._evaluate(node, q_to, marks)
            if best is None or cost + h < best[2] + best[3]:
                best = (tuple(q_to), fin2, cost, h)
        return best

    def _evaluate(self, node: _Node, q_to: list[int], marks: dict[int, bool]):
        """Finished flags of the successor, transition cost and heuristic."""
        fin = node.fin
        q = node.q
        goals = self.goals
        dist = self.space.dist
        new = bytearray(fin)
        cost = 0
        h = 0
        for i in range(self.n):
            if fin[i]:
                continue
            v = q_to[i]
            if v == goals[i]:
                m = marks.get(i)
                if m is None:
                    m = q[i] == v  # waited one step on the goal: finished for free
                if m:
                    new[i] = 1
                    if q[i] != v:
                        cost += 1
                    continue
            cost += 1
            h += dist[i][v]
        return bytes(new), cost, h

    # ------------------------------------------------------------------ LaCAM
    def first_solution(self, deadline: Deadline) -> list[Conf] | None:
        """Plain LaCAM until the goal configuration; None when the space is exhausted.

        Raises :class:`Expired` when the deadline passes first.
        """
        start = tuple(self.space.starts)
        root = self._make(start, b"", None, 0, 0)
        self.root = root
        if root.goal:
            return [start]
        stack = [root]
        explored = self.explored
        rng = self.rng
        while stack:
            self.iterations += 1
            if deadline.expired():
                raise Expired
            node = stack[-1]
            cons = self.next_constraints(node)
            if cons is None:
                stack.pop()
                continue
            res = self.successor(node, cons)
            if res is None:
                continue
            q = res[0]
            known = explored.get(q)
            if known is not None:
                stack.append(root if rng.random() < P_RESTART else known)
                continue
            child = self._make(q, b"", node, 0, 0)
            stack.append(child)
            if child.goal:
                return self.backtrack(child)
        return None

    @staticmethod
    def backtrack(node: _Node) -> list[Conf]:
        """The configurations from the start to ``node``."""
        out = []
        x: _Node | None = node
        while x is not None:
            out.append(x.q)
            x = x.parent
        out.reverse()
        return out

    def use_guide(self, guide: list[dict[int, int]]) -> None:
        """Let the configuration generators follow guide paths from now on."""
        for pibt in self.pibts:
            pibt.guide = guide

    # ------------------------------------------------------------------ LaCAM*
    def start_anytime(self, configs: list[Conf]) -> None:
        """Switch to the augmented search (finished flags) seeded with a first plan."""
        self.star = True
        self.explored = {}
        self.stored = 0
        start = tuple(self.space.starts)
        fin0 = bytes(self.n)
        h0 = self.space.lower_bound()
        self.root = self._make(start, fin0, None, 0, h0)
        self.open = [self.root]
        self.offer(configs)

    def plan_configs(self) -> list[Conf]:
        """The incumbent as a configuration sequence."""
        if self.best_configs is not None:
            return self.best_configs
        assert self.best_node is not None
        return self.backtrack(self.best_node)

    def offer(self, configs: list[Conf], soc: int | None = None) -> bool:
        """A plan found elsewhere (or by the search); returns True if it is better."""
        if soc is None:
            soc = sum_of_costs(configs, self.goals)
        if soc >= self.best:
            return False
        if self.full:
            self.best = soc
            self.best_node = None
            self.best_configs = configs
            return True
        self._insert(configs)
        if soc < self.best:  # the graph already held something better than the plan
            self.best = soc
            self.best_node = None
            self.best_configs = configs
        return True

    def _insert(self, configs: list[Conf]) -> None:
        """Add a plan to the graph, each agent finished on its final arrival."""
        goals = self.goals
        n = self.n
        arrival = [0] * n
        for i in range(n):
            t = len(configs) - 1
            while t > 0 and configs[t - 1][i] == goals[i]:
                t -= 1
            arrival[i] = max(t, 1)
        assert self.root is not None
        frm = self.root
        dist = self.space.dist
        for t in range(1, len(configs)):
            q = configs[t]
            fin = bytes(1 if t >= arrival[i] else 0 for i in range(n))
            cost = 0
            h = 0
            for i in range(n):
                if not fin[i]:
                    cost += 1
                    h += dist[i][q[i]]
                elif not frm.fin[i] and frm.q[i] != goals[i]:
                    cost += 1
            known = self.explored.get((q, fin))
            if known is None:
                node = self._make(q, fin, frm, frm.g + cost, h)
                frm.succ[node] = cost
                self.open.append(node)
                if node.goal:
                    self._incumbent(node)
            else:
                node = known
                old = frm.succ.get(node)
                if old is None or cost < old:
                    frm.succ[node] = cost
                self._rewire(frm)
            frm = node

    def _incumbent(self, node: _Node) -> None:
        if node.g < self.best:
            self.best = node.g
            self.best_node = node
            self.best_configs = None

    def _rewire(self, src: _Node) -> None:
        """Propagate cheaper costs from ``src`` to every node reachable from it."""
        todo = deque([src])
        while todo:
            a = todo.popleft()
            for b, c in a.succ.items():
                g = a.g + c
                if g < b.g:
                    b.g = g
                    b.f = g + b.h
                    b.parent = a
                    if b.goal:
                        self._incumbent(b)
                    todo.append(b)
                    if b.f < self.best:
                        self.open.append(b)

    def improve(self, iterations: int, stop: Callable[[], bool]) -> bool:
        """LaCAM* for some iterations; True when the stack is empty (incumbent optimal)."""
        stack = self.open
        rng = self.rng
        root = self.root
        assert root is not None
        while stack:
            if self.full or iterations <= 0 or stop():
                return False
            iterations -= 1
            self.iterations += 1
            node = stack[-1]
            top = True
            if rng.random() < P_RANDOM_PICK:
                pick = stack[rng.randrange(len(stack))]
                if pick.f < self.best and not pick.goal:
                    node = pick
                    top = pick is stack[-1]
            if node.f >= self.best or node.goal:
                stack.pop()
                continue
            cons = self.next_constraints(node)
            if cons is None:  # every successor generated: the node is done for good
                if top:
                    stack.pop()
                    node.prio = None  # free the memory; an empty order marks it done
                    node.order = []
                continue
            res = self.successor(node, cons)
            if res is None:
                continue
            q, fin, cost, h = res
            known = self.explored.get((q, fin))
            if known is not None:
                old = node.succ.get(known)
                if old is None or cost < old:
                    node.succ[known] = cost
                self._rewire(node)
                stack.append(root if rng.random() < P_RESTART else known)
                continue
            child = self._make(q, fin, node, node.g + cost, h)
            node.succ[child] = cost
            stack.append(child)
            if child.goal:
                before = self.best
                self._incumbent(child)
                if self.best < before:
                    configs = self.backtrack(child)
                    soc = sum_of_costs(configs, self.goals)
                    if soc < child.g:  # finished too late on this path: re-mark it
                        self.offer(configs, soc)
            if self.stored > MAX_STORED:
                self.full = True
                log.info("lacam: node store full (%d nodes); refinement only", self.nodes)
        return True


# ---------------------------------------------------------------------- solver
@solver(
    "lacam",
    Option(
        "anytime",
        "float",
        "seconds of improvement after the first plan (none: until the time limit, so "
        "lacam runs the whole --time-limit unless it proves the optimum; 0: return the "
        "first plan, --set anytime=0)",
        low=0,
        optional=True,
    ),
    Option("refine", "bool", "interleave LNS refinement with the search"),
    Option("guide", "bool", "guide paths (space utilisation) in the anytime phase"),
    SWAP_OPTION,
    Option("mc", "int", "PIBT runs per successor in the anytime search (Monte-Carlo)", low=1),
)
def solve(
    instance: Instance,
    *,
    time_limit: float | None = None,
    seed: int = 0,
    objective: str = "soc",
    anytime: float | None = None,
    refine: bool = True,
    guide: bool = True,
    swap: bool = True,
    mc: int = 1,
) -> Result:
    """LaCAM*: a first plan fast, then better plans until the time runs out.

    Parameters
    ----------
    anytime
        Seconds spent improving after the first plan (0: return the first plan).
        None: until ``time_limit``; with no time limit either, until the optimum is
        proven (which on large instances does not happen in practice).
    refine
        Interleave large-neighbourhood-search refinement with the search.
    guide
        At the start of the anytime phase, plan guide paths that spread the agents
        out (space utilisation optimisation) and restart LaCAM with them; the search
        keeps using them.
    swap
        PIBT's swap technique (undirected graphs).
    mc
        PIBT runs per successor in the anytime search (Monte-Carlo generation).

    Returns
    -------
    Result
        OPTIMAL when the anytime search is exhausted (or the cost meets the sum of
        distances); FEASIBLE with the best plan when the time runs out after a first
        plan; TIME_LIMIT without a plan when it runs out before; INFEASIBLE when the
        search space is exhausted without reaching the goals. ``lower_bound`` is the
        sum of distances (the proven cost when OPTIMAL).

    Example
    -------
    >>> from hierplan_opt.core.graph import Graph
    >>> g = Graph.grid(5, 2, obstacles=[(0, 1), (1, 1), (3, 1), (4, 1)])
    >>> inst = Instance.mapf(g, [(0, 0), (1, 0)], [(4, 0), (3, 0)])
    >>> r = solve(inst, time_limit=5)
    >>> r.status.value, r.cost, r.lower_bound
    ('OPTIMAL', 8, 8)
    """
    if objective != "soc":
        raise OptionError(f"lacam does not optimise {objective!r}")
    deadline = Deadline(time_limit)
    prepared = prepare(instance, deadline, seed)
    if isinstance(prepared, Result):
        return prepared
    space, lb = prepared
    search = _LaCAM(space, seed, swap=swap, mc=mc)
    stats: dict = {}
    try:
        configs = search.first_solution(deadline)
    except Expired:
        stats.update(iterations=search.iterations, nodes=search.nodes, stopped_by="time_limit")
        return Result(Status.TIME_LIMIT, None, lower_bound=lb, stats=stats)
    if configs is None:
        stats.update(iterations=search.iterations, nodes=search.nodes)
        stats["reason"] = "search space exhausted: no plan exists"
        return Result(Status.INFEASIBLE, None, lower_bound=lb, stats=stats)
    first_time = deadline.elapsed()
    first_cost = sum_of_costs(configs, space.goals)
    stats.update(first_time=first_time, first_cost=first_cost, first_nodes=search.nodes)
    log.info("lacam: first plan after %.3f s, cost %d (lower bound %d)", first_time, first_cost, lb)
    proven = first_cost == lb
    history = [(first_time, first_cost)]
    if not proven and anytime != 0:
        opts = _Options(anytime, refine, guide, swap, mc, seed)
        proven = _anytime(search, space, configs, deadline, opts, history, stats)
    configs = search.plan_configs() if search.star else configs
    plan = space.plan(configs)
    cost = plan.sum_of_costs
    if cost == lb:
        proven = True
    stats.update(iterations=search.iterations, nodes=search.nodes, history=history)
    if not proven and anytime != 0:  # the anytime phase ended at a limit, not a proof
        if deadline.expired():
            stats["stopped_by"] = "time_limit"
        elif anytime is not None:
            stats["stopped_by"] = "anytime"  # its own budget, option ``anytime``
    status = Status.OPTIMAL if proven else Status.FEASIBLE
    return Result(status, plan, cost=cost, lower_bound=cost if proven else lb, stats=stats)


@dataclass(frozen=True)
class _Options:
    anytime: float | None
    refine: bool
    guide: bool
    swap: bool
    mc: int
    seed: int


def _anytime(
    search: _LaCAM,
    space: Space,
    configs: list[Conf],
    deadline: Deadline,
    opts: _Options,
    history: list[tuple[float, int]],
    stats: dict,
) -> bool:
    """Alternate LaCAM* and LNS refinement; True when the optimum is proven."""
    end = Deadline(opts.anytime) if opts.anytime is not None else deadline
    seed = opts.seed
    search.start_anytime(configs)
    refiner = Refiner(space, _paths(configs, space.goals), seed) if opts.refine else None
    if opts.guide:
        limit = _earliest(end, deadline)
        _guided_restart(search, refiner, space, opts, limit, deadline, history, stats)
    proven = False
    # Work, not time, is shared between the two, so that the sequence of incumbents
    # depends only on the seed: per round the refiner tries REFINE_STEPS
    # neighbourhoods and the search makes ``budget`` iterations, doubled after a round
    # in which the search improved the incumbent and halved after one it did not.
    budget = SEARCH_ITERATIONS
    pending = False  # the refiner holds a better plan than the search graph

    def stop() -> bool:
        return end.expired() or deadline.expired()

    while not stop():
        if not search.full:
            if pending and refiner is not None:
                search.offer(_configs(refiner.paths), refiner.cost)
                pending = False
            before = search.best
            proven = search.improve(budget if refiner is not None else 1 << 62, stop)
            if proven:
                break
            if search.best < before:
                history.append((deadline.elapsed(), search.best))
                budget = min(MAX_SEARCH_ITERATIONS, budget * 2)
                if refiner is not None and search.best < refiner.cost:
                    refiner.reset(_paths(search.plan_configs(), space.goals))
            else:
                budget = max(MIN_SEARCH_ITERATIONS, budget // 2)
        if refiner is None:
            if search.full:
                break
            continue
        best_before = min(search.best, refiner.cost)
        for _ in range(REFINE_STEPS):
            if stop():
                break
            refiner.step()
        if refiner.cost < best_before:
            history.append((deadline.elapsed(), refiner.cost))
            pending = True
    if pending and refiner is not None:
        search.offer(_configs(refiner.paths), refiner.cost)
    if refiner is not None:
        stats.update(lns_replanned=refiner.replanned, lns_accepted=refiner.accepted)
    return proven


def _guided_restart(
    search: _LaCAM,
    refiner: Refiner | None,
    space: Space,
    opts: _Options,
    deadline: Deadline,
    clock: Deadline,
    history: list[tuple[float, int]],
    stats: dict,
) -> None:
    """Guide paths, then LaCAM again with PIBT following them; keep the better plan."""
    t0 = clock.elapsed()
    paths = guide_paths(space, deadline, opts.seed)
    if paths is None:
        return
    table = guide_table(paths)
    again = _LaCAM(space, opts.seed, swap=opts.swap, guide=table)
    try:
        configs = again.first_solution(deadline)
    except Expired:
        return
    search.use_guide(table)
    if configs is None:  # pragma: no cover - the first search found a plan
        return
    soc = sum_of_costs(configs, space.goals)
    stats.update(guided_cost=soc, guide_time=clock.elapsed() - t0)
    if search.offer(configs, soc):
        history.append((clock.elapsed(), soc))
        if refiner is not None:
            refiner.reset(_paths(configs, space.goals))


def _earliest(*deadlines: Deadline) -> Deadline:
    """A deadline that expires with the first of ``deadlines``."""
    left = min(d.remaining() for d in deadlines)
    return Deadline(None if left == float("inf") else left)


def _paths(configs: Sequence[Conf], goals: Sequence[int]) -> list[list[int]]:
    """Per-agent compact paths, each cut at its final arrival."""
    n = len(goals)
    out = []
    for i in range(n):
        p = [q[i] for q in configs]
        t = len(p) - 1
        while t > 0 and p[t - 1] == p[-1]:
            t -= 1
        out.append(p[: t + 1])
    return out


def _configs(paths: Sequence[Sequence[int]]) -> list[Conf]:
    """Configurations of per-agent paths (agents wait at their last vertex)."""
    horizon = max(len(p) for p in paths)
    return [tuple(p[t] if t < len(p) else p[-1] for p in paths) for t in range(horizon)]
