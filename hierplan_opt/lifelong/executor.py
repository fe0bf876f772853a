"""The executor: staged actions kept safe under delays by an action dependency graph.

The planner's window becomes, per robot, a queue of staged actions, and, per cell, the
order in which robots enter it (the Type-2 dependencies of the temporal plan graph /
action dependency graph of Hönig et al., RA-L 2019, reduced to cells). Every tick each
robot that is not delayed either continues the action in progress, starts its next
staged action, or waits:

* a rotation, or a staged wait (the planner holds the robot on an errand for a tick),
  may always start (the footprint stays in its cell);
* a forward move into cell ``c`` may start only when the robot is first in ``c``'s
  queue, i.e. every robot that the plan sends through ``c`` earlier has left it.

A robot *holds* its cell and, while moving, the cell it moves into; a cell is held by
at most one robot (the head of its queue), and a footprint of size at most one lies
inside the cells its robot holds, so footprints never overlap, however the delays fall.
Delays are absorbed here first: the delayed robot pauses and robots that depend on it
wait (slack where nobody depends on it); what is left is absorbed by the next
re-planning call, which plans from where the robots really are.
"""

from __future__ import annotations

from collections import deque

from hierplan_opt.lifelong.model import FW, NA, RobotState, W
from hierplan_opt.lifelong.planner import WindowPlan
from hierplan_opt.lifelong.temporal import WindowSTN


class ADGExecutor:
    """Per-robot staged actions and per-cell visit queues (see the module doc).

    Example
    -------
    >>> from hierplan_opt.lifelong.planner import WindowPlan
    >>> ex = ADGExecutor((1, 3, -1, -3))
    >>> robots = [RobotState(0), RobotState(1)]
    >>> ex.load(WindowPlan([[FW], [FW]], [[1], [2]], {1: [0], 2: [1]}), robots)
    >>> ex.command(0, robots[0]), ex.command(1, robots[1])  # 0 waits until 1 has left
    (3, 0)
    """

    def __init__(self, moves: tuple[int, int, int, int]) -> None:
        self.moves = moves
        self.staged: list[deque[int]] = []
        self.queues: dict[int, deque[int]] = {}
        self._orders: dict[int, list[int]] = {}
        self.blocked_by: list[int] = []
        self.started_n: list[int] = []
        self._window: tuple[WindowPlan, list[int], list[int], list[int], int, int] | None = None
        self._stn: WindowSTN | None = None
        self.stn_resolves = 0
        self.stn_pushed = 0.0

    def load(self, plan: WindowPlan, robots: list[RobotState], t0: int = 0, k: int = 1) -> None:
        """Replace the staged actions by a new plan made from the robots' committed
        states (``t0``: the tick it starts at; ``k``: ticks per action, for its temporal
        network)."""
        self.staged = [deque(a) for a in plan.actions]
        self.started_n = [0] * len(robots)
        into = [s.loc + self.moves[s.ori] if s.cur == FW and s.count > 0 else -1 for s in robots]
        rem = [k - s.count if s.count > 0 and s.cur != NA else 0 for s in robots]
        self._window = (plan, [s.loc for s in robots], into, rem, t0, k)
        self._stn = None
        self.blocked_by = [-1] * len(robots)
        q: dict[int, deque[int]] = {}
        # a robot leaving a cell comes before one following it in (at most one each)
        for i, s in enumerate(robots):
            q[s.loc] = deque([i])
        for i, s in enumerate(robots):
            if s.cur == FW and s.count > 0:
                q.setdefault(s.loc + self.moves[s.ori], deque()).append(i)
        for cell, who in plan.order.items():
            q.setdefault(cell, deque()).extend(who)
        self.queues = q
        self._orders = {c: list(w) for c, w in q.items()}

    def window_stn(self, cols: int) -> WindowSTN:
        """The temporal network of the loaded window (built on first use)."""
        if self._stn is None:
            assert self._window is not None, "no window loaded"
            plan, locs, into, rem, t0, k = self._window
            self._stn = WindowSTN(
                plan.actions, plan.enters, locs, into, rem, self._orders, t0=t0, k=k, cols=cols
            )
        return self._stn

    def absorb_delay(self, i: int, j: int, now: int, cols: int) -> str:
        """The layer that absorbs a delay after which robot ``i`` can start its ``j``-th
        staged action of this window at tick ``now`` at the earliest: ``adg`` (within its
        slack in the window's temporal network) or ``stn`` (the network re-solved, see
        :meth:`~hierplan_opt.lifelong.temporal.WindowSTN.absorb`)."""
        w = self.window_stn(cols)
        before = w.resolves, w.pushed
        layer = w.absorb(i, j, now)
        self.stn_resolves += w.resolves - before[0]
        self.stn_pushed += w.pushed - before[1]
        return layer

    def command(self, i: int, s: RobotState) -> int:
        """Robot ``i``'s action this tick by the cell rule alone (no following); W when
        it must wait."""
        self.blocked_by[i] = -1
        if s.count > 0 and s.cur != NA:
            return s.cur
        st = self.staged[i]
        if not st:
            return W
        a = st[0]
        if a != FW:
            return a
        head = self.queues.get(s.loc + self.moves[s.ori])
        if head and head[0] == i:
            return a
        self.blocked_by[i] = head[0] if head else -2
        return W

    def commands(self, robots: list[RobotState], delayed: list[bool], k: int) -> list[int]:
        """Every robot's action this tick, decided together.

        Besides the cell rule, a robot may *follow* the robot ahead into a cell that one
        is leaving in the same direction, as long as the follower's progress never
        passes the leader's (counter of the follower <= counter of the leader after
        the tick): the two footprints then slide in step and never overlap. A leader
        that pauses (delayed or blocked) stops its follower on the same tick.
        """
        n = len(robots)
        out = [-1] * n
        self.blocked_by = [-1] * n
        moves = self.moves

        def decide(i: int) -> int:
            if out[i] >= 0:
                return out[i]
            out[i] = W  # provisional (no dependency cycles: followers look ahead in line)
            s = robots[i]
            if delayed[i]:
                return W
            busy = s.count > 0 and s.cur != NA
            if busy and s.cur != FW:
                out[i] = s.cur
                return s.cur
            if not busy:
                st = self.staged[i]
                if not st:
                    return W
                if st[0] != FW:
                    out[i] = st[0]
                    return st[0]
            x = s.loc + moves[s.ori]
            q = self.queues.get(x)
            if q and q[0] == i:
                out[i] = FW
                return FW
            lead = q[0] if q else -2
            self.blocked_by[i] = lead
            if lead >= 0 and len(q) > 1 and q[1] == i:  # type: ignore[arg-type]
                a = robots[lead]
                in_line = a.loc == x and a.ori == s.ori and (a.cur == FW or a.count == 0)
                if in_line and decide(lead) == FW and a.count >= s.count:
                    self.blocked_by[i] = -1
                    out[i] = FW
                    return FW
            return W

        for i in range(n):
            decide(i)
        return out

    def started(self, i: int) -> None:
        """Robot ``i`` began its next staged action this tick."""
        self.staged[i].popleft()
        self.started_n[i] += 1

    def waited(self, i: int) -> None:
        """Robot ``i`` waited this tick, not delayed and with no action in progress: a
        staged wait at the head of its queue (the planner holding it on an errand, see
        :func:`~hierplan_opt.search.windowed.errand_done`) is done."""
        st = self.staged[i]
        if st and st[0] == W:
            st.popleft()
            self.started_n[i] += 1

    def left(self, i: int, cell: int) -> None:
        """Robot ``i`` finished moving out of ``cell``: the next robot may enter it."""
        q = self.queues[cell]
        if q and q[0] == i:
            q.popleft()

    def idle(self, i: int, s: RobotState) -> bool:
        """Whether robot ``i`` has nothing to do (no action in progress, none staged)."""
        return not self.staged[i] and not (s.count > 0 and s.cur != NA)


__all__ = ["ADGExecutor"]
