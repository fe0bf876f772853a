"""The LoRR action model (MAPF with turnings, ``MAPF_T``) and distances on its grid.

A robot has a location (linearised ``row * cols + col``), an orientation (0 east,
1 south, 2 west, 3 north) and a counter. Each action -- forward (``FW``), rotate
clockwise (``CR``) or counter-clockwise (``CCR``) -- takes ``agentCounter`` ticks; the
location or orientation changes on the last one. Once started, an action can only be
paused (a wait) or continued, exactly as in the Start-Kit's ``ActionModelWithRotate``:
:func:`step_state` is that rule for one robot and one tick. During a forward move the
robot's square footprint (``agentSize``) slides from its cell towards the next.

:class:`Grid` holds the map and :class:`Distances` the exact travel distances to goals
(breadth-first search by scipy, cached up to a memory budget; Manhattan distance when a
table is not affordable).
"""

from __future__ import annotations

import logging
import time
from array import array
from collections import OrderedDict
from dataclasses import dataclass

import numpy as np
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import shortest_path

from hierplan_opt.search.windowed import CCR, CR, FW, W

log = logging.getLogger(__name__)

NA = 4  # no action in progress (FW, CR, CCR, W: search.windowed)
#: One letter per action in the compressed path strings.
LETTERS = "FRCWT"
CODES = {c: i for i, c in enumerate(LETTERS)}
#: The distance of unreachable cells (tables are 16-bit).
FAR = 65535


@dataclass
class RobotState:
    """One robot's state as the Start-Kit keeps it (``cur`` is the action in progress)."""

    loc: int
    ori: int = 0
    count: int = 0
    cur: int = NA


def step_state(s: RobotState, action: int, moves: tuple[int, int, int, int], k: int) -> None:
    """Apply one tick of ``action`` to ``s`` in place (the Start-Kit's ``result_state``).

    Example
    -------
    >>> s = RobotState(0)
    >>> for _ in range(3):
    ...     step_state(s, FW, (1, 4, -1, -4), 3)
    >>> s.loc, s.count, s.cur
    (1, 0, 4)
    """
    if s.count > 0 and s.cur != NA:
        if action == W:
            return
        action = s.cur
    if action == FW:
        s.count += 1
        if s.count >= k:
            s.loc += moves[s.ori]
            s.count = 0
            s.cur = NA
        else:
            s.cur = FW
    elif action in (CR, CCR):
        s.count += 1
        if s.count >= k:
            s.ori = (s.ori + (1 if action == CR else 3)) % 4
            s.count = 0
            s.cur = NA
        else:
            s.cur = action
    else:
        s.cur = s.cur if s.count > 0 else NA


class Grid:
    """The map: size, blocked cells and the four moves (east, south, west, north).

    Example
    -------
    >>> g = Grid(2, 3, np.array([0, 1, 0, 0, 0, 0], dtype=bool))
    >>> g.neighbours(0), g.direction(0, 3)
    ([3], 1)
    """

    def __init__(self, rows: int, cols: int, blocked: np.ndarray) -> None:
        self.rows = rows
        self.cols = cols
        self.n = rows * cols
        self.blocked = blocked
        self.free = (~blocked).tolist()
        self.moves = (1, cols, -1, -cols)

    def neighbours(self, v: int) -> list[int]:
        """Free 4-neighbours of cell ``v``."""
        c = self.cols
        r, col = divmod(v, c)
        free = self.free
        out = []
        if col + 1 < c and free[v + 1]:
            out.append(v + 1)
        if r + 1 < self.rows and free[v + c]:
            out.append(v + c)
        if col > 0 and free[v - 1]:
            out.append(v - 1)
        if r > 0 and free[v - c]:
            out.append(v - c)
        return out

    def direction(self, u: int, v: int) -> int:
        """The orientation of the move ``u -> v`` (neighbours)."""
        d = v - u
        return 0 if d == 1 else 1 if d == self.cols else 2 if d == -1 else 3

    def csr(self) -> tuple[csr_matrix, np.ndarray]:
        """The free cells' adjacency (compact ids) and the compact id of every cell
        (-1 for blocked cells), for breadth-first search."""
        idx = np.flatnonzero(~self.blocked)
        cid = np.full(self.n, -1, dtype=np.int32)
        cid[idx] = np.arange(len(idx), dtype=np.int32)
        r, c = np.divmod(idx, self.cols)
        rows_l, cols_l = [], []
        for dr, dc in ((0, 1), (1, 0)):
            nr, nc = r + dr, c + dc
            ok = (nr < self.rows) & (nc < self.cols)
            a = idx[ok]
            b = nr[ok] * self.cols + nc[ok]
            keep = ~self.blocked[b]
            a, b = cid[a[keep]], cid[b[keep]]
            rows_l += [a, b]
            cols_l += [b, a]
        ri = np.concatenate(rows_l)
        ci = np.concatenate(cols_l)
        m = len(idx)
        return csr_matrix((np.ones(len(ri), dtype=np.int8), (ri, ci)), shape=(m, m)), cid


class Distances:
    """Exact distances to goals, cached (least recently used) up to ``max_bytes``.

    Tables cover the free cells only (``cid[cell]`` is a cell's compact id) and hold
    16-bit distances (:data:`FAR` where unreachable): ``table(goal)[cid[cell]]``.
    ``estimate(a, b)`` uses ``b``'s table when cached and the Manhattan distance
    otherwise. ``seconds_per_call`` caps the time spent on new tables in one planning
    call (:meth:`new_round` starts a call): beyond it :meth:`table` returns None and
    callers fall back to Manhattan distances, so a huge map never stalls a call.

    Example
    -------
    >>> g = Grid(1, 4, np.array([0, 1, 0, 0], dtype=bool))
    >>> d = Distances(g)
    >>> t = d.table(3)
    >>> [t[d.cid[c]] for c in (0, 2, 3)], d.estimate(0, 3)
    ([65535, 1, 0], 65535)
    """

    def __init__(
        self, grid: Grid, max_bytes: int = 1 << 30, seconds_per_call: float | None = None
    ) -> None:
        self.grid = grid
        m, cid = grid.csr()
        self._csr: csr_matrix = m
        self.cid_np = cid
        self.cid = array("i", cid.tobytes())
        self.m = int(np.count_nonzero(cid >= 0))
        self.cache: OrderedDict[int, array] = OrderedDict()
        self.max_tables = max(8, max_bytes // (2 * max(1, self.m)))
        self.seconds_per_call = seconds_per_call
        self._call_start = time.perf_counter()
        self.made_total = 0
        self.per_table = 0.0  # seconds per breadth-first table (last batch)
        self.fallbacks = 0
        self.seconds = 0.0

    def new_round(self) -> None:
        """Start a planning call (its time budget for new tables)."""
        self._call_start = time.perf_counter()

    def _over_budget(self) -> bool:
        lim = self.seconds_per_call
        return lim is not None and time.perf_counter() - self._call_start > lim

    def prefetch(self, goals: list[int], budget: float | None = None) -> None:
        """Make the tables of ``goals`` (batched; within the call's time budget, or
        within ``budget`` seconds when given)."""
        want = [g for g in dict.fromkeys(goals) if g not in self.cache][: self.max_tables]
        if not want:
            return
        t0 = time.perf_counter()
        cap = max(1, min(len(want), 16, (64 << 20) // (8 * self.m)))
        s = 0
        while s < len(want):
            # time left: this call's (or the given) budget; batches sized to fit in it
            # from the measured time per table, so a call does not overrun by a batch
            if budget is not None:
                left = budget - (time.perf_counter() - t0)
            elif self.seconds_per_call is not None:
                left = self.seconds_per_call - (time.perf_counter() - self._call_start)
            else:
                left = float("inf")
            if left <= 0:
                break
            fit = (
                1
                if self.per_table <= 0
                else cap
                if left == float("inf")
                else int(left / self.per_table)
            )
            if fit < 1:
                break
            batch = min(cap, fit)
            part = want[s : s + batch]
            s += batch
            b0 = time.perf_counter()
            d = shortest_path(self._csr, directed=False, unweighted=True, indices=self.cid_np[part])
            self.per_table = (time.perf_counter() - b0) / len(part)
            d = np.atleast_2d(d)
            d[~np.isfinite(d)] = FAR
            di = np.minimum(d, FAR).astype(np.uint16)
            for g, row in zip(part, di, strict=True):
                self._put(g, array("H", row.tobytes()))
            self.made_total += len(part)
        self.seconds += time.perf_counter() - t0

    def _put(self, g: int, t: array) -> None:
        self.cache[g] = t
        while len(self.cache) > self.max_tables:
            self.cache.popitem(last=False)

    def table(self, goal: int) -> array | None:
        """The distance table of ``goal``, or None when the call's budget is spent."""
        t = self.cache.get(goal)
        if t is not None:
            self.cache.move_to_end(goal)
            return t
        if self._over_budget():
            self.fallbacks += 1
            return None
        self.prefetch([goal])
        return self.cache.get(goal)

    def estimate(self, a: int, b: int) -> int:
        """Distance from ``a`` to ``b``: exact when ``b``'s table is cached, else Manhattan."""
        t = self.cache.get(b)
        if t is not None:
            return t[self.cid[a]]
        c = self.grid.cols
        ar, ac = divmod(a, c)
        br, bc = divmod(b, c)
        return abs(ar - br) + abs(ac - bc)


__all__ = ["CCR", "CR", "FAR", "FW", "LETTERS", "NA", "W", "Distances", "Grid", "RobotState"]
