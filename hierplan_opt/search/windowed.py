"""Windowed PIBT and windowed LaCAM: plan ``w`` steps from a configuration, any time.

The one-shot solvers (:mod:`.pibt`, :mod:`.lacam`) plan every agent to one goal until
all are there. Rolling-horizon planning (the lifelong loop, :mod:`hierplan_opt.
lifelong`) needs something else: from the current configuration, with each agent's
*list* of goals (errands visited in order; several agents may share one), plan ``w``
synchronous steps of *actions* -- forward, rotate clockwise / counter-clockwise, wait
(the League of Robot Runners' action model, so turning costs time) -- and give an
answer by a deadline. This module is that interface, on a grid given by its
:class:`GridLike` protocol and distance tables given by :class:`DistanceTables`.

**PIBT** (:class:`WindowedPIBT`; Okumura et al., AIJ 2022, the rule of :mod:`.pibt`):
agents choose in priority order the free neighbour (or their own cell) that is best by

    distance to the goal  +  ``turn_cost`` * turns needed to face it
    +  ``congestion`` * recent traffic there  (- a bonus for a guide path's next cell),

and an agent that wants a cell held by an undecided agent makes that agent move first.
An agent may not take the cell of an agent that is pushing it (directly or through a
chain), and rotation cycles become waits, so a step has neither swaps nor cycles,
which robots with footprints could not execute one cell at a time. An agent whose
chosen cell is not ahead turns towards it this step and stays. When an agent reaches a
goal inside the window its next goal takes over. A goal is reached by the one rule of
:func:`errand_done` (the end of a step on it, one goal per step); a step on which an
agent stays (neither moves nor turns) and reaches a goal is recorded as a wait action
``W``, so that the executor keeps the robot there for that tick too.

**LaCAM** (:class:`WindowedLaCAM`; Okumura, AAAI 2023): a depth-first search over
configurations down to depth ``w`` whose successors are PIBT steps under *constraints*
(some agents' next cells fixed, grown one agent at a time in priority order, LaCAM's
low-level search). The PIBT rollout is the first leaf; the search then keeps the leaf
with the least total distance to the goals (errands reached count first) until its
node budget or the deadline.

**Deadline** (both): ``plan(..., deadline=t)`` (a :func:`time.perf_counter` time)
returns the steps done when ``t`` comes; inside a step, the agents not yet decided stay
where they are (safe: PIBT takes an undecided agent's cell only by pushing it, which
decides it). So a call is never much later than its budget, and robots without a plan
wait, as the Start-Kit's robots do.
"""

from __future__ import annotations

import random
import sys
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any, Protocol

NIL = -1
#: The action codes (the League of Robot Runners' forward, clockwise, counter-clockwise,
#: wait).
FW, CR, CCR, W = 0, 1, 2, 3
#: How much a guide path's next cell is preferred (in steps).
GUIDE_BONUS = 0.5
#: Quarter turns between two orientations, by (want - have) mod 4.
TURNS = (0, 1, 2, 1)
#: Extra cost of a cell that needs a turn for an agent pushed out of its cell.
PUSHED_TURN = 10.0
#: Agents decided between two looks at the clock inside a step.
CLOCK_EVERY = 64


class GridLike(Protocol):
    """A 4-connected grid: ``rows`` x ``cols`` cells (linearised ``row * cols + col``),
    ``free[c]`` for passable cells, ``direction(u, v)`` of a move (0 east, 1 south,
    2 west, 3 north)."""

    rows: int
    cols: int
    n: int
    free: list[bool]

    def direction(self, u: int, v: int) -> int: ...


class DistanceTables(Protocol):
    """Distances to goals: ``table(goal)[cid[cell]]`` (None: no table, use Manhattan)."""

    cid: Any

    def table(self, goal: int) -> Any: ...


@dataclass
class WindowPlan:
    """The result of one planning call: per agent its actions and the cells it enters
    (in order), the plan's per-cell visit order (agents in order of entry), the steps
    planned and whether the deadline cut the call short."""

    actions: list[list[int]]
    enters: list[list[int]]
    order: dict[int, list[int]] = field(default_factory=dict)
    cycles_broken: int = 0
    steps: int = 0
    cut: bool = False
    nodes: int = 0


def errand_done(loc: int, errands: Sequence[int], done: int) -> bool:
    """Whether an agent that stands on ``loc`` at the end of a step (a tick) does its
    next errand, ``errands[done]`` (``done``: the errands it has done so far).

    The one definition of "errand done", the Start-Kit's
    (``TaskManager::check_finished_tasks``): an errand is done when its robot stands on
    it at the end of a timestep -- having moved in, waited or turned there -- and at
    most one errand per timestep. Standing on it when the task comes is not enough: the
    robot must still be there at the end of the next tick. The windowed planners
    advance their goals by it and the lifelong loop credits errands by it.

    Example
    -------
    >>> errand_done(4, (4, 9), 0), errand_done(4, (4, 9), 1), errand_done(9, (4, 9), 2)
    (True, False, False)
    """
    return done < len(errands) and loc == errands[done]


def turns(ori: int, want: int) -> list[int]:
    """The rotations that turn orientation ``ori`` into ``want`` (shortest way).

    Example
    -------
    >>> turns(0, 1), turns(0, 3), len(turns(0, 2)), turns(2, 2)
    ([1], [2], 2, [])
    """
    d = (want - ori) % 4
    return [] if d == 0 else [CR] if d == 1 else [CCR] if d == 3 else [CR, CR]


class _Search:
    """The state of one call: configuration, orientations, goal progress, priorities."""

    __slots__ = ("q", "o", "goal_idx", "prio", "tables")

    def __init__(self, q, o, goal_idx, prio, tables) -> None:
        self.q: list[int] = q
        self.o: list[int] = o
        self.goal_idx: list[int] = goal_idx
        self.prio: list[float] = prio
        self.tables: list[Any] = tables


class WindowedPIBT:
    """PIBT over ``window`` steps for all agents at once (see the module doc).

    Example
    -------
    >>> from hierplan_opt.lifelong.model import Distances, Grid
    >>> import numpy as np
    >>> g = Grid(1, 4, np.zeros(4, dtype=bool))
    >>> pl = WindowedPIBT(g, Distances(g), window=3)
    >>> plan = pl.plan([0, 3], [0, 2], [[1], []], [1.0, 0.0])  # agent 1 has no goal
    >>> plan.actions, plan.order, plan.steps
    ([[0], []], {1: [0]}, 3)
    """

    def __init__(
        self,
        grid: GridLike,
        dist: DistanceTables,
        *,
        window: int = 4,
        seed: int = 0,
        congestion: float = 0.0,
        turn_cost: float = 1.0,
    ) -> None:
        self.grid = grid
        self.dist = dist
        self.window = window
        self.rng = random.Random(seed)
        self.congestion = congestion
        self.turn_cost = turn_cost
        self.occ_now = [NIL] * grid.n
        self.occ_next = [NIL] * grid.n
        self.traffic: dict[int, float] = {}
        self.on_stack: set[int] = set()
        self.guide: list[dict[int, int]] | None = None
        self.cid = dist.cid
        self._deadline: float | None = None

    # ------------------------------------------------------------------ one call
    def plan(
        self,
        locs: Sequence[int],
        oris: Sequence[int],
        errands: Sequence[Sequence[int]],
        priority: Sequence[float],
        guide: list[dict[int, int]] | None = None,
        *,
        deadline: float | None = None,
    ) -> WindowPlan:
        """Plan ``window`` steps from the agents' cells and orientations.

        ``errands[i]`` is agent ``i``'s remaining goals (the first is its goal; empty:
        none, it stays unless pushed); ``priority`` orders the agents (higher first);
        ``guide[i]`` maps cells to agent ``i``'s preferred next cell (e.g. from a
        registry solver's plan), favoured by :data:`GUIDE_BONUS`; ``deadline`` (a
        :func:`time.perf_counter` time) ends the call early with the steps done.
        """
        self.guide = guide
        self._deadline = deadline
        st = self._start(locs, oris, errands, priority)
        with _deep_recursion(len(locs)):
            plan = self._search(st, errands)
        self._forget()
        return plan

    def _search(self, st: _Search, errands: Sequence[Sequence[int]]) -> WindowPlan:
        """PIBT's answer: one step after another from ``st`` (see the module doc)."""
        n = len(st.q)
        acts: list[list[int]] = [[] for _ in range(n)]
        enters: list[list[int]] = [[] for _ in range(n)]
        order: dict[int, list[int]] = {}
        broken = steps = 0
        cut = False
        for _ in range(self.window):
            if self._expired():
                cut = True
                break
            res = self._one_step(st, errands, None)
            assert res is not None  # no constraints: every step is complete
            new, moved, turned, b, partial = res
            broken += b
            self._record(st, new, moved, turned, acts, enters, order)
            st = new
            steps += 1
            if partial:
                cut = True
                break
        return WindowPlan(acts, enters, order, broken, steps, cut)

    # ------------------------------------------------------------------ shared parts
    def _start(self, locs, oris, errands, priority) -> _Search:
        n = len(locs)
        q = list(locs)
        return _Search(
            q,
            list(oris),
            [0] * n,
            list(priority),
            [self._table(errands[i], 0, q[i]) for i in range(n)],
        )

    def _expired(self) -> bool:
        return self._deadline is not None and time.perf_counter() >= self._deadline

    def _forget(self) -> None:
        if self.traffic:  # forget old traffic slowly
            self.traffic = {v: t * 0.5 for v, t in self.traffic.items() if t > 0.25}

    def _record(self, st: _Search, new: _Search, moved, turned, acts, enters, order) -> None:
        """Append the step ``st -> new`` to the plan: rotations, forward moves, and a
        wait ``W`` for an agent that stays in place and does an errand by staying."""
        q, q_to = st.q, new.q
        for i, a in turned.items():
            acts[i].append(a)
        for i, (g0, g1) in enumerate(zip(st.goal_idx, new.goal_idx, strict=True)):
            if g1 > g0 and q_to[i] == q[i] and i not in turned:
                acts[i].append(W)
        for i in moved:
            v = q_to[i]
            acts[i].append(FW)
            enters[i].append(v)
            order.setdefault(v, []).append(i)
            self.traffic[v] = self.traffic.get(v, 0.0) + 1.0

    def _one_step(self, st: _Search, errands, fixed: dict[int, int] | None):
        """One synchronous step from ``st`` (``fixed``: agents' next cells imposed).

        Returns ``(new state, agents that moved, {agent: rotation}, cycles broken,
        cut by the deadline)``, or None when the constraints admit no step."""
        q = st.q
        n = len(q)
        prio = st.prio
        seq = sorted(range(n), key=prio.__getitem__, reverse=True)
        got = self._step(q, st.o, st.tables, seq, fixed)
        if got is None:
            return None
        q_to, partial = got
        broken = self._break_cycles(q, q_to)
        o = list(st.o)
        turned = self._turn_first(q, q_to, o)
        moved = [i for i in range(n) if q_to[i] != q[i]]
        goal_idx = list(st.goal_idx)
        tables = list(st.tables)
        prio = list(prio)
        for i in range(n):
            e = errands[i]
            if errand_done(q_to[i], e, goal_idx[i]):
                goal_idx[i] += 1
                tables[i] = self._table(e, goal_idx[i], q_to[i])
                prio[i] = self.rng.random()  # arrived: back to a low priority
            elif goal_idx[i] < len(e):
                prio[i] += 1.0
        return _Search(q_to, o, goal_idx, prio, tables), moved, turned, broken, partial

    def _table(self, errands: Sequence[int], k: int, here: int):
        goal = errands[k] if k < len(errands) else here
        t = self.dist.table(goal)
        return t if t is not None else goal  # an int: Manhattan to it

    def _h(self, v: int, t) -> int:
        if not isinstance(t, int):
            return t[self.cid[v]]
        cols = self.grid.cols
        r, c = divmod(v, cols)
        tr, tc = divmod(t, cols)
        return abs(r - tr) + abs(c - tc)

    # ------------------------------------------------------------------ one step
    def _step(
        self, q: list[int], o: list[int], tables: list, seq: list[int], fixed
    ) -> tuple[list[int], bool] | None:
        occ_now, occ_next = self.occ_now, self.occ_next
        q_to = [NIL] * len(q)
        for i, v in enumerate(q):
            occ_now[v] = i
        ok = True
        if fixed:
            for i, v in fixed.items():
                if occ_next[v] != NIL:
                    ok = False
                q_to[i] = v
                occ_next[v] = i
        partial = False
        deadline = self._deadline
        clock = time.perf_counter
        for k, i in enumerate(seq):
            if not ok:
                break
            if q_to[i] != NIL:
                continue
            if deadline is not None and k % CLOCK_EVERY == 0 and clock() >= deadline:
                partial = True
                break
            self._push(i, NIL, q, o, q_to, tables)
        if partial:  # the undecided agents stay (nobody took their cells)
            for i, v in enumerate(q):
                if q_to[i] == NIL:
                    if occ_next[v] != NIL:
                        ok = False
                    q_to[i] = v
                    occ_next[v] = i
        for v in q:
            occ_now[v] = NIL
        for v in q_to:
            if v != NIL:
                occ_next[v] = NIL
        if not ok or NIL in q_to or len(set(q_to)) < len(q_to):
            return None
        return q_to, partial

    def _candidates(self, i: int, v: int, o: list[int], t, pushed: bool) -> list[int]:
        """Agent ``i``'s cells, best first, by steps to the goal: turns to face a cell,
        the move and the cell's distance; waiting costs a step more than the best move
        (unless the agent is at its goal and not pushed)."""
        grid = self.grid
        cols = grid.cols
        free = grid.free
        r, col = divmod(v, cols)
        oi = o[i]
        table = not isinstance(t, int)
        cid = self.cid
        if not table:
            tr, tc = divmod(t, cols)
        rnd = self.rng.random
        tc_ = self.turn_cost
        cong = self.congestion
        traffic = self.traffic
        keyed: list[tuple[float, int]] = []
        # east, south, west, north (the orientation codes)
        for dirn, ok, c in (
            (0, col + 1 < cols, v + 1),
            (1, r + 1 < grid.rows, v + cols),
            (2, col > 0, v - 1),
            (3, r > 0, v - cols),
        ):
            if not ok or not free[c]:
                continue
            if table:
                d = t[cid[c]]
            else:
                cr, cc = divmod(c, cols)
                d = abs(cr - tr) + abs(cc - tc)
            n_turns = TURNS[(dirn - oi) & 3]
            k = d + 1 + tc_ * n_turns
            if n_turns and pushed:
                k += PUSHED_TURN  # it could not make room this step
            if cong:
                k += cong * traffic.get(c, 0.0)
            keyed.append((k + rnd() * 1e-3, c))
        dv = t[cid[v]] if table else abs(r - tr) + abs(col - tc)
        stay = 0.0
        if (dv > 0 or pushed) and keyed:
            stay = 1 + min(keyed)[0]
        keyed.append((stay, v))
        if self.guide is not None:
            g = self.guide[i].get(v)
            if g is not None:
                keyed = [(k - GUIDE_BONUS if c == g else k, c) for k, c in keyed]
        keyed.sort()
        return [c for _, c in keyed]

    def _turn_first(self, q: list[int], q_to: list[int], o: list[int]) -> dict[int, int]:
        """Agents whose chosen cell is not ahead turn towards it and stay this step
        (returned: agent -> rotation; ``o`` updated); agents that were to enter a cell
        whose agent stays wait too (recursively)."""
        want = {q_to[j]: j for j in range(len(q)) if q_to[j] != q[j]}
        stay: list[int] = []
        turned: dict[int, int] = {}
        for i in range(len(q)):
            if q_to[i] == q[i]:
                continue
            d = self.grid.direction(q[i], q_to[i])
            if d != o[i]:
                a = turns(o[i], d)[0]
                turned[i] = a
                o[i] = (o[i] + (1 if a == CR else 3)) % 4
                q_to[i] = q[i]
                stay.append(i)
        while stay:
            j = want.get(q[stay.pop()], NIL)
            if j != NIL and q_to[j] != q[j]:
                q_to[j] = q[j]
                stay.append(j)
        return turned

    def _push(self, i: int, parent: int, q, o, q_to: list[int], tables) -> bool:
        v = q[i]
        cands = self._candidates(i, v, o, tables[i], parent != NIL)
        on_stack = self.on_stack
        on_stack.add(v)
        try:
            return self._try(i, v, cands, parent, q, o, q_to, tables)
        finally:
            on_stack.discard(v)

    def _try(self, i: int, v: int, cands: list[int], parent: int, q, o, q_to, tables) -> bool:
        occ_now, occ_next, on_stack = self.occ_now, self.occ_next, self.on_stack
        for c in cands:
            if occ_next[c] != NIL:
                continue
            if c != v and c in on_stack:
                continue  # the cell of an agent pushing this one: a swap or a rotation cycle
            j = occ_now[c]
            if j != NIL and j != i and q_to[j] == v:
                continue  # swap
            q_to[i] = c
            occ_next[c] = i
            if j != NIL and j != i and q_to[j] == NIL and not self._push(j, i, q, o, q_to, tables):
                occ_next[c] = NIL
                q_to[i] = NIL
                continue
            return True
        if occ_next[v] == NIL or occ_next[v] == i:
            q_to[i] = v
            occ_next[v] = i
        return False

    def _break_cycles(self, q: list[int], q_to: list[int]) -> int:
        """Rotation cycles (every agent entering the next one's cell) become waits."""
        where = {v: i for i, v in enumerate(q)}
        state = [0] * len(q)  # 0 unseen, 1 on the current walk, 2 done
        broken = 0
        for s in range(len(q)):
            if state[s]:
                continue
            walk = []
            i = s
            while i != NIL and state[i] == 0 and q_to[i] != q[i]:
                state[i] = 1
                walk.append(i)
                i = where.get(q_to[i], NIL)
            if i != NIL and state[i] == 1:  # a cycle from i
                k = walk.index(i)
                for a in walk[k:]:
                    q_to[a] = q[a]
                broken += 1
            for a in walk:
                state[a] = 2
        return broken


class _Node:
    """A LaCAM high-level node: a state at some depth, the step that led to it, and its
    low-level constraint tree (a queue of ``{agent: cell}`` constraints)."""

    __slots__ = ("st", "depth", "parent", "moved", "turned", "cons", "order", "broken")

    def __init__(self, st: _Search, depth: int, parent, moved, turned, broken: int) -> None:
        self.st = st
        self.depth = depth
        self.parent: _Node | None = parent
        self.moved: list[int] = moved
        self.turned: dict[int, int] = turned
        self.broken = broken
        self.cons: list[dict[int, int]] = [{}]
        self.order: list[int] = []


class WindowedLaCAM(WindowedPIBT):
    """LaCAM's configuration search down to depth ``window`` (see the module doc),
    at most ``max_nodes`` high-level expansions per call.

    Example
    -------
    >>> from hierplan_opt.lifelong.model import Distances, Grid
    >>> import numpy as np
    >>> g = Grid(1, 4, np.zeros(4, dtype=bool))
    >>> pl = WindowedLaCAM(g, Distances(g), window=3)
    >>> plan = pl.plan([0, 3], [0, 2], [[1], []], [1.0, 0.0])
    >>> plan.actions, plan.steps, plan.nodes > 1
    ([[0], []], 3, True)
    """

    def __init__(self, grid: GridLike, dist: DistanceTables, *, max_nodes: int = 200, **kw):
        super().__init__(grid, dist, **kw)
        self.max_nodes = max_nodes

    def _search(self, st: _Search, errands: Sequence[Sequence[int]]) -> WindowPlan:
        """LaCAM's answer: the best leaf of the configuration search from ``st``."""
        n = len(st.q)
        root = _Node(st, 0, None, [], {}, 0)
        root.order = sorted(range(n), key=root.st.prio.__getitem__, reverse=True)
        stack = [root]
        seen = {(tuple(root.st.q), tuple(root.st.o), 0)}
        best: _Node = root
        best_key = self._score(root)
        expanded = 0
        cut = False
        last = 0.0  # seconds of the last expansion: none starts that could not end in time
        clock = time.perf_counter
        while stack and expanded < self.max_nodes:
            t0 = clock()
            if self._deadline is not None and t0 + last >= self._deadline:
                cut = True
                break
            node = stack[-1]
            if node.depth >= self.window or not node.cons:
                stack.pop()
                continue
            cons = node.cons.pop(0)
            self._grow(node, cons)
            res = self._one_step(node.st, errands, cons)
            expanded += 1
            last = clock() - t0
            if res is None:
                continue
            new, moved, turned, b, partial = res
            key = (tuple(new.q), tuple(new.o), node.depth + 1)
            if key in seen and not partial:
                continue
            seen.add(key)
            child = _Node(new, node.depth + 1, node, moved, turned, node.broken + b)
            child.order = sorted(range(n), key=new.prio.__getitem__, reverse=True)
            score = self._score(child)
            if score < best_key:
                best, best_key = child, score
            if partial:
                cut = True
                break
            stack.append(child)
        chain: list[_Node] = []
        node: _Node | None = best
        while node is not None and node.parent is not None:
            chain.append(node)
            node = node.parent
        acts: list[list[int]] = [[] for _ in range(n)]
        enters: list[list[int]] = [[] for _ in range(n)]
        order: dict[int, list[int]] = {}
        prev = root
        for nd in reversed(chain):
            self._record(prev.st, nd.st, nd.moved, nd.turned, acts, enters, order)
            prev = nd
        return WindowPlan(acts, enters, order, best.broken, best.depth, cut, expanded)

    def _score(self, node: _Node) -> tuple[int, int, int]:
        """Deeper first (a full window), then more goals reached, then less distance."""
        st = node.st
        h = sum(self._h(v, t) for v, t in zip(st.q, st.tables, strict=True))
        return (-node.depth, -sum(st.goal_idx), h)

    def _grow(self, node: _Node, cons: dict[int, int]) -> None:
        """LaCAM's low level: children of constraint ``cons`` fix the next agent (in the
        node's priority order) to each of its cells."""
        k = len(cons)
        if k >= len(node.order):
            return
        i = node.order[k]
        st = node.st
        for c in self._candidates(i, st.q[i], st.o, st.tables[i], False):
            node.cons.append({**cons, i: c})


class _deep_recursion:
    """PIBT's pushes recurse as deep as the chain of agents: a higher recursion limit."""

    def __init__(self, n: int) -> None:
        self.n = n
        self.old = 0

    def __enter__(self) -> None:
        self.old = sys.getrecursionlimit()
        sys.setrecursionlimit(max(self.old, 4 * self.n + 1000))

    def __exit__(self, *exc: object) -> None:
        sys.setrecursionlimit(self.old)


__all__ = [
    "CCR",
    "CR",
    "FW",
    "W",
    "DistanceTables",
    "GridLike",
    "WindowPlan",
    "WindowedLaCAM",
    "WindowedPIBT",
    "errand_done",
    "turns",
]
