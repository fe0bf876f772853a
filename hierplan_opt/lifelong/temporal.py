"""The temporal network of a planning window: the STN layer of the lifelong executor.

A window's staged actions form a simple temporal network in ticks, built as the
project's own :class:`~hierplan_opt.schedule.stn.STN` over a
:class:`~hierplan_opt.schedule.tpg.TPG` so that the schedule package's solvers
(:func:`~hierplan_opt.schedule.solve_graph.earliest_times`,
:func:`~hierplan_opt.schedule.solve_graph.latest_times`,
:func:`~hierplan_opt.schedule.solve_graph.fix_and_propagate`) do the work:

* per robot a *ready* node (its action in progress ends: released at the window's
  first tick plus the ticks that action still needs), one node per staged action (its
  start) and a *final* node (its last action ends); Type-1 arcs of ``agentCounter``
  ticks between consecutive actions (one tick after a staged wait);
* Type-2 arcs from the action by which a robot leaves a cell to the forward move by
  which the next robot of that cell's visit order enters it (``agentCounter`` ticks:
  the cell is free once the move out has ended), i.e. the executor's dependency graph.

The targets are the earliest times; the *slack* of a node is how far it may slip
before the window's makespan moves (latest times against it). A delay that costs a
robot motion is put down to the dependency graph when the robot's next action is late
by no more than its slack, and otherwise to an STN re-solve: its release raised to the
tick the delay ended, successors pushed in topological order (other robots' targets
move, the window ends later). See :meth:`WindowSTN.absorb`.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping, Sequence

import numpy as np

from hierplan_opt.core.errors import InputError
from hierplan_opt.execution.state import rebound
from hierplan_opt.schedule.clearance import Requirement
from hierplan_opt.schedule.solve_graph import earliest_times, fix_and_propagate, latest_times
from hierplan_opt.schedule.stn import MOVE, PRECEDENCE, STN
from hierplan_opt.schedule.tpg import TPG, TYPE1, TYPE2, VERTEX, WAIT, _LocationNames

log = logging.getLogger(__name__)

FW, W = 0, 3  # the forward and wait actions (hierplan_opt.lifelong.model.FW, W)


class _Cells:
    """``location(v)`` of a linearised grid cell, for node labels."""

    def __init__(self, cols: int) -> None:
        self.cols = cols

    def location(self, v: int) -> tuple[int, int]:
        return divmod(int(v), self.cols)


class WindowSTN:
    """The STN of one window (see the module doc).

    ``actions[i]`` / ``enters[i]``: robot ``i``'s staged actions and the cells its forward
    moves enter; ``locs[i]``: the cell it stands on now; ``moving_into[i]``: the cell its
    forward move in progress enters (-1: none); ``remaining[i]``: ticks its action in
    progress still needs; ``queues``: per cell the robots in order of entry (the
    executor's visit orders, the present occupants first); ``t0``: the window's first
    tick; ``k``: ticks per action.

    Example
    -------
    Robot 1 waits for robot 0 to leave cell 1; robot 0's delay has no slack:

    >>> w = WindowSTN([[FW], [FW]], [[2], [1]], [1, 0], [-1, -1], [0, 0],
    ...               {1: [0, 1], 2: [0], 0: [1]}, t0=0, k=2, cols=3)
    >>> w.target(1, 0), w.target(0, 0), w.slack(0, 0)
    (2.0, 0.0, 0.0)
    >>> w.absorb(0, 0, now=3), w.target(1, 0), w.pushed
    ('stn', 5.0, 3.0)
    """

    def __init__(
        self,
        actions: Sequence[Sequence[int]],
        enters: Sequence[Sequence[int]],
        locs: Sequence[int],
        moving_into: Sequence[int],
        remaining: Sequence[int],
        queues: Mapping[int, Sequence[int]],
        *,
        t0: int,
        k: int,
        cols: int,
    ) -> None:
        n = len(actions)
        sizes = np.array([len(a) + 2 for a in actions], dtype=np.int64)
        ptr = np.zeros(n + 1, dtype=np.int64)
        np.cumsum(sizes, out=ptr[1:])
        self.ptr = ptr
        total = int(ptr[-1])
        src: list[int] = []
        dst: list[int] = []
        lb: list[float] = []
        leave: dict[tuple[int, int], tuple[int, float]] = {}  # (robot, cell) -> node, lag
        enter: dict[tuple[int, int], int] = {}
        vertex = np.zeros(total, dtype=np.int64)
        for i in range(n):
            base = int(ptr[i])
            acts = actions[i]
            for j in range(len(acts) + 1):  # ready -> a1 (0), a_j -> a_j+1 (k), ... final
                src.append(base + j)
                dst.append(base + j + 1)
                # an action takes k ticks, a staged wait one
                lb.append(0.0 if j == 0 else 1.0 if acts[j - 1] == W else float(k))
            here = locs[i]
            vertex[base : base + len(acts) + 2] = here
            if moving_into[i] >= 0:  # the move in progress leaves `here` when it ends
                leave[(i, here)] = (base, 0.0)
                here = moving_into[i]
            e = 0
            for j, a in enumerate(acts):
                node = base + 1 + j
                vertex[node] = here
                if a != FW:
                    continue
                leave.setdefault((i, here), (node, float(k)))
                here = enters[i][e]
                e += 1
                enter[(i, here)] = node
        for cell, who in queues.items():
            for a, b in zip(who, who[1:], strict=False):
                out = leave.get((a, cell))
                into = enter.get((b, cell))
                if out is None or into is None or a == b:
                    continue  # b does not enter it in this window
                src.append(out[0])
                dst.append(into)
                lb.append(out[1])
        arc_src = np.array(src, dtype=np.int64)
        arc_dst = np.array(dst, dtype=np.int64)
        agent = np.repeat(np.arange(n, dtype=np.int64), sizes)
        kind = np.full(total, VERTEX, dtype=np.int64)
        kind[ptr[:-1]] = WAIT
        zeros2 = np.zeros((total, 2))
        m = len(arc_src)
        type1 = np.zeros(m, dtype=bool)
        type1[: int(sizes.sum() - n)] = True
        tpg = TPG(
            agent_ptr=ptr,
            node_agent=agent,
            node_kind=kind,
            node_vertex=vertex,
            node_step=np.zeros(total, dtype=np.int64),
            node_pos=zeros2,
            node_coord=zeros2,
            node_s=np.zeros(total),
            node_turn=np.zeros(total),
            node_heading=np.zeros(total),
            arc_src=arc_src,
            arc_dst=arc_dst,
            arc_type=np.where(type1, TYPE1, TYPE2),
            arc_lock=np.where(type1, -1, vertex[arc_dst]),
            requirement=Requirement(np.zeros(n), ("robot",) * n, 0.0),
            regime="none",
            agent_names=tuple(f"robot{i}" for i in range(n)),
            location_names=_LocationNames(_Cells(cols)),
        )
        release = np.zeros(total)
        release[ptr[:-1]] = t0 + np.asarray(remaining, dtype=float)
        self.stn = STN(
            tpg,
            arc_src,
            arc_dst,
            np.array(lb, dtype=float),
            np.full(m, np.inf),
            np.where(type1, MOVE, PRECEDENCE),
            np.zeros(m),
            np.zeros(m),
            release,
            np.full(total, np.inf),
            np.ones(n),
        )
        self.T = earliest_times(self.stn)
        self.horizon = float(self.T.max(initial=t0))
        self.latest = latest_times(self.stn, self.horizon)
        self.resolves = 0
        self.pushed = 0.0  # ticks the window's end moved by re-solves

    def node(self, i: int, j: int) -> int:
        """The node of robot ``i``'s ``j``-th staged action (its final node past them)."""
        return int(self.ptr[i]) + 1 + min(j, int(self.ptr[i + 1] - self.ptr[i]) - 2)

    def target(self, i: int, j: int) -> float:
        """The tick at which robot ``i``'s ``j``-th staged action is to start."""
        return float(self.T[self.node(i, j)])

    def slack(self, i: int, j: int) -> float:
        """How many ticks that action may slip before the window's end moves."""
        v = self.node(i, j)
        return float(self.latest[v] - self.T[v])

    def absorb(self, i: int, j: int, now: int) -> str:
        """Robot ``i`` could start its ``j``-th staged action no earlier than ``now`` (a
        delay ended): ``adg`` when that is within its slack (the dependency graph holds
        the others back as needed), else ``stn`` after re-solving the network from that
        node (targets pushed in topological order; the latest times against the new
        end)."""
        v = self.node(i, j)
        late = now - float(self.T[v])
        if late <= float(self.latest[v] - self.T[v]) + 1e-9:
            return "adg"
        release = np.array(self.stn.release, dtype=float)
        release[v] = max(release[v], float(now))
        self.stn = rebound(self.stn, release=release)
        try:
            new_t = fix_and_propagate(self.stn, self.T, {}, changed=[v])
        except InputError as exc:  # a dependency cycle: the planner's plan is at fault
            log.warning("window STN not re-solved: %s", exc)
            return "adg"
        self.resolves += 1
        end = float(new_t.max(initial=self.horizon))
        self.pushed += end - self.horizon
        self.T = new_t
        self.horizon = end
        self.latest = latest_times(self.stn, end)
        return "stn"


__all__ = ["WindowSTN"]
