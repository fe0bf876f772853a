"""Rolling-horizon planning: windowed PIBT with turning costs and congestion guidance.

Every planning call plans ``window`` synchronous steps on the location graph with PIBT
(Okumura et al., AIJ 2022; the same rule as :mod:`hierplan_opt.search.pibt`, which plans
one-shot MAPF to the end and does not take shared goals or a step budget): agents choose
in priority order the free neighbour (or their own cell) that is best by

    distance to the goal  +  turns needed to face it  +  ``congestion`` * traffic there,

where traffic counts the robots that planned through a cell in recent calls (guidance
against congestion). An agent that wants a cell held by an undecided agent makes that
agent move first; a step is free of vertex and swap conflicts. When an agent reaches an
errand inside the window its next errand becomes its goal.

Rotations along a cycle (each agent taking the next one's cell) are legal in MAPF but
cannot be executed one cell at a time, so they are turned into waits. The steps become
per-robot action lists (turns, then a forward move) and per-cell visit orders, which the
executor (:mod:`hierplan_opt.lifelong.executor`) keeps as an action dependency graph.
"""

from __future__ import annotations

import random
import sys
from collections.abc import Sequence
from dataclasses import dataclass, field

from hierplan_opt.lifelong.model import CCR, CR, FW, Distances, Grid

NIL = -1
#: How much a guide path's next cell is preferred (in steps).
GUIDE_BONUS = 0.5
#: Quarter turns between two orientations, by (want - have) mod 4.
TURNS = (0, 1, 2, 1)
#: Extra cost of a cell that needs a turn for an agent pushed out of its cell.
PUSHED_TURN = 10.0


@dataclass
class WindowPlan:
    """The result of one planning call: per robot its actions and the cells it enters
    (in order), and the plan's per-cell visit order (robots in order of entry)."""

    actions: list[list[int]]
    enters: list[list[int]]
    order: dict[int, list[int]] = field(default_factory=dict)
    cycles_broken: int = 0


def turns(ori: int, want: int) -> list[int]:
    """The rotations that turn orientation ``ori`` into ``want`` (shortest way).

    Example
    -------
    >>> turns(0, 1), turns(0, 3), len(turns(0, 2)), turns(2, 2)
    ([1], [2], 2, [])
    """
    d = (want - ori) % 4
    return [] if d == 0 else [CR] if d == 1 else [CCR] if d == 3 else [CR, CR]


class WindowedPIBT:
    """PIBT over ``window`` steps for all robots at once (see the module doc).

    Example
    -------
    >>> import numpy as np
    >>> g = Grid(1, 4, np.zeros(4, dtype=bool))
    >>> pl = WindowedPIBT(g, Distances(g), window=3)
    >>> plan = pl.plan([0, 3], [0, 2], [[1], []], [1.0, 0.0])  # robot 1 has no task
    >>> plan.actions, plan.order
    ([[0], []], {1: [0]})
    """

    def __init__(
        self,
        grid: Grid,
        dist: Distances,
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

    # ------------------------------------------------------------------ one call
    def plan(
        self,
        locs: Sequence[int],
        oris: Sequence[int],
        errands: Sequence[Sequence[int]],
        priority: Sequence[float],
        guide: list[dict[int, int]] | None = None,
    ) -> WindowPlan:
        """Plan ``window`` steps from the robots' committed cells and orientations.

        ``errands[i]`` is robot ``i``'s remaining errands (its goal is the first; empty:
        no task, stay unless pushed); ``priority`` orders the robots (higher first);
        ``guide[i]`` maps cells to robot ``i``'s preferred next cell (from a registry
        solver's plan, :mod:`~hierplan_opt.lifelong.guidance`), favoured by
        :data:`GUIDE_BONUS`.
        """
        self.guide = guide
        n = len(locs)
        q = list(locs)
        o = list(oris)
        goal_idx = [0] * n
        tables = [self._table(errands[i], 0, q[i]) for i in range(n)]
        acts: list[list[int]] = [[] for _ in range(n)]
        enters: list[list[int]] = [[] for _ in range(n)]
        order: dict[int, list[int]] = {}
        prio = list(priority)
        broken = 0
        old_limit = sys.getrecursionlimit()
        sys.setrecursionlimit(max(old_limit, 4 * n + 1000))
        try:
            for _ in range(self.window):
                seq = sorted(range(n), key=prio.__getitem__, reverse=True)
                q_to = self._step(q, o, tables, seq)
                broken += self._break_cycles(q, q_to)
                self._turn_first(q, q_to, o, acts)
                for i in range(n):
                    u, v = q[i], q_to[i]
                    if u == v:
                        continue
                    acts[i].append(FW)
                    enters[i].append(v)
                    order.setdefault(v, []).append(i)
                    self.traffic[v] = self.traffic.get(v, 0.0) + 1.0
                q = q_to
                for i in range(n):
                    e = errands[i]
                    if goal_idx[i] < len(e) and q[i] == e[goal_idx[i]]:
                        goal_idx[i] += 1
                        tables[i] = self._table(e, goal_idx[i], q[i])
                        prio[i] = self.rng.random()  # arrived: back to a low priority
                    elif goal_idx[i] < len(e):
                        prio[i] += 1.0
        finally:
            sys.setrecursionlimit(old_limit)
        if self.traffic:  # forget old traffic slowly
            self.traffic = {v: t * 0.5 for v, t in self.traffic.items() if t > 0.25}
        return WindowPlan(acts, enters, order, broken)

    def _table(self, errands: Sequence[int], k: int, here: int):
        goal = errands[k] if k < len(errands) else here
        t = self.dist.table(goal)
        return t if t is not None else goal  # an int: Manhattan to it

    # ------------------------------------------------------------------ one step
    def _step(self, q: list[int], o: list[int], tables: list, seq: list[int]) -> list[int]:
        occ_now, occ_next = self.occ_now, self.occ_next
        q_to = [NIL] * len(q)
        for i, v in enumerate(q):
            occ_now[v] = i
        for i in seq:
            if q_to[i] == NIL:
                self._push(i, NIL, q, o, q_to, tables)
        for v in q:
            occ_now[v] = NIL
        for v in q_to:
            occ_next[v] = NIL
        return q_to

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

    def _turn_first(
        self, q: list[int], q_to: list[int], o: list[int], acts: list[list[int]]
    ) -> None:
        """Agents whose chosen cell is not ahead turn towards it and stay this step;
        agents that were to enter a cell whose agent stays wait too (recursively)."""
        want = {q_to[j]: j for j in range(len(q)) if q_to[j] != q[j]}
        stay: list[int] = []
        for i in range(len(q)):
            if q_to[i] == q[i]:
                continue
            d = self.grid.direction(q[i], q_to[i])
            if d != o[i]:
                acts[i].append(turns(o[i], d)[0])
                o[i] = (o[i] + (1 if acts[i][-1] == CR else 3)) % 4
                q_to[i] = q[i]
                stay.append(i)
        while stay:
            j = want.get(q[stay.pop()], NIL)
            if j != NIL and q_to[j] != q[j]:
                q_to[j] = q[j]
                stay.append(j)

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


__all__ = ["WindowPlan", "WindowedPIBT", "turns"]
