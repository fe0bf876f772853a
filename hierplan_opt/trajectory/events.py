"""The schedule's events as refinement sees them: an adapter over ``hierplan_opt.schedule``.

Refinement needs, for every robot, its STN events in path order (vertices, the
markers that end or begin a clearance claim, and ``wait`` events where a robot sets off
from its start) with their positions and scheduled times, the precedences *between*
robots (the Type-2 arcs), and the clearance they keep: ``r_i + r_j + margin`` for every
pair (``docs/post.md``). :class:`EventNetwork` collects exactly that from the public
parts of a :class:`~hierplan_opt.schedule.Schedule` (its ``stn``, ``times``, windows
``earliest``/``latest`` for the schedule returned, and way-points), so the rest of
:mod:`hierplan_opt.trajectory` never reads the temporal plan graph's internals.

A schedule *file* holds way-points and arrival times, and the discrete plan and
settings they came from, but not the STN. :func:`from_file` reads it with the one
reader of schedule files (:func:`hierplan_opt.schedule.files.load_schedule`), which
rebuilds the STN from the file's plan and settings and keeps the file's times.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from hierplan_opt.core.errors import InputError
from hierplan_opt.core.instance import Instance
from hierplan_opt.core.reprs import short_repr
from hierplan_opt.schedule.files import load_schedule
from hierplan_opt.schedule.stn import PRECEDENCE
from hierplan_opt.schedule.tpg import KIND_NAMES

log = logging.getLogger(__name__)


@dataclass(frozen=True, eq=False)
class EventNetwork:
    """STN events per robot and the precedences between robots (read-only arrays).

    Attributes
    ----------
    agent_names : tuple of str
    agent_ptr : (K+1,) int
        Events of robot ``j`` are ``agent_ptr[j]:agent_ptr[j+1]``, in path order.
    agent : (N,) int
        Owner of every event.
    kind : tuple of str
        ``"vertex"``, ``"leave"``, ``"enter"``, ``"marker"`` (both) or ``"wait"`` (the
        robot sets off from its start), as in the schedule.
    pos : (N, dim) float
        Position in metres.
    coord : (N, dim) float
        Position in instance coordinates (for messages).
    times : (N,) float
        Scheduled time of every event (a consistent solution of the STN).
    earliest, latest : (N,) float
        The STN's window of every event for this schedule (``latest`` against its
        makespan); both contain ``times``.
    release, deadline : (N,) float
        Node bounds of the STN.
    arc_src, arc_dst : (M,) int
        Precedences between events of *different* robots: ``lb <= t_dst - t_src <= ub``.
    arc_lb, arc_ub : (M,) float
    waypoint : (N,) int
        Index of the event among its robot's way-points in the schedule (which also
        lists the ends of turns in place).
    scale : float
        Metres per instance coordinate unit.
    radius : (K,) float
        The robots' radii (metres).
    margin : float
        Extra clearance beyond the radii (metres).
    enforced : bool
        Whether the schedule's precedences keep ``r_i + r_j + margin`` (False for a
        schedule built with ``clearance=False``).
    """

    __repr__ = short_repr  # arrays and long tuples summarised (core/reprs)

    agent_names: tuple[str, ...]
    agent_ptr: np.ndarray
    agent: np.ndarray
    kind: tuple[str, ...]
    pos: np.ndarray
    coord: np.ndarray
    times: np.ndarray
    earliest: np.ndarray
    latest: np.ndarray
    release: np.ndarray
    deadline: np.ndarray
    arc_src: np.ndarray
    arc_dst: np.ndarray
    arc_lb: np.ndarray
    arc_ub: np.ndarray
    waypoint: np.ndarray
    scale: float
    radius: np.ndarray
    margin: float
    enforced: bool
    label: Callable[[int], str]

    @property
    def num_agents(self) -> int:
        return len(self.agent_names)

    @property
    def num_events(self) -> int:
        return len(self.agent)

    @property
    def dim(self) -> int:
        return int(self.pos.shape[1])

    @property
    def makespan(self) -> float:
        return float(self.times[self.agent_ptr[1:] - 1].max()) if self.num_events else 0.0

    def required(self, i: int, j: int) -> float:
        """``r_i + r_j + margin``: the distance robots ``i`` and ``j`` must keep."""
        return float(self.radius[i] + self.radius[j] + self.margin)

    @property
    def safety_distance(self) -> float:
        """The smallest distance the schedule guarantees between any two robots
        (``min r_i + r_j + margin``; 0 when not enforced or with one robot)."""
        if not self.enforced or self.num_agents < 2:
            return 0.0
        r = np.sort(self.radius)
        return float(r[0] + r[1] + self.margin)

    def events(self, j: int) -> range:
        """Event ids of robot ``j`` in path order."""
        return range(int(self.agent_ptr[j]), int(self.agent_ptr[j + 1]))

    def where(self, v: int) -> str:
        """``agent3 way-point 5 (leave at (2, 0.25))``: a name for event ``v`` in messages."""
        j = int(self.agent[v])
        idx = int(self.waypoint[v])
        c = ", ".join(f"{x:.6g}" for x in self.coord[v])
        return f"{self.agent_names[j]} way-point {idx} ({self.kind[v]} at ({c}))"


def from_schedule(schedule: Any) -> EventNetwork:
    """The events of an in-memory :class:`~hierplan_opt.schedule.Schedule` (it must carry
    its STN).

    Example
    -------
    >>> from hierplan_opt.core.graph import Graph
    >>> from hierplan_opt.core.instance import Kinematics
    >>> from hierplan_opt.core.plan import Plan
    >>> from hierplan_opt.schedule import postprocess
    >>> g = Graph.grid(3, 3, obstacles=[(0, 0), (2, 0), (0, 2), (2, 2)])
    >>> kin = Kinematics("disc", radius=0.2)
    >>> inst = Instance.mapf(g, [(0, 1), (1, 0)], [(2, 1), (1, 2)], kinematics=kin)
    >>> plan = Plan.from_paths([[3, 4, 5], [1, 1, 4, 7]])
    >>> net = from_schedule(postprocess(inst, plan))
    >>> net.num_events, [net.where(int(v)) for v in net.arc_src], net.safety_distance
    (8, ['agent0 way-point 2 (leave at (1.7, 1))'], 0.4)
    """
    stn = getattr(schedule, "stn", None)
    if stn is None:
        raise InputError("the schedule carries no STN (read a file with from_file instead)")
    waypoint = np.zeros(stn.tpg.num_nodes, dtype=np.int64)
    for wp in schedule.waypoints:
        node = np.asarray(wp.node)
        keep = node >= 0
        waypoint[node[keep]] = np.flatnonzero(keep)
    return _from_stn(
        stn,
        np.asarray(schedule.times, dtype=float),
        np.asarray(schedule.earliest, dtype=float),
        np.asarray(schedule.latest, dtype=float),
        waypoint,
        scale=float(schedule.scale),
        names=tuple(schedule.agent_names),
    )


def _from_stn(
    stn: Any,
    times: np.ndarray,
    earliest: np.ndarray,
    latest: np.ndarray,
    waypoint: np.ndarray,
    *,
    scale: float,
    names: tuple[str, ...],
) -> EventNetwork:

    tpg = stn.tpg
    agent = np.asarray(tpg.node_agent, dtype=np.int64)
    inter = np.asarray(stn.arc_kind) == PRECEDENCE
    src = np.asarray(stn.arc_src, dtype=np.int64)[inter]
    dst = np.asarray(stn.arc_dst, dtype=np.int64)[inter]
    req = tpg.requirement
    net = EventNetwork(
        agent_names=names,
        agent_ptr=np.asarray(tpg.agent_ptr, dtype=np.int64),
        agent=agent,
        kind=tuple(KIND_NAMES[int(k)] for k in tpg.node_kind),
        pos=np.asarray(tpg.node_pos, dtype=float),
        coord=np.asarray(tpg.node_coord, dtype=float),
        times=times.copy(),
        earliest=np.minimum(earliest, times),
        latest=np.maximum(latest, times),
        release=np.asarray(stn.release, dtype=float),
        deadline=np.asarray(stn.deadline, dtype=float),
        arc_src=src,
        arc_dst=dst,
        arc_lb=np.asarray(stn.lb, dtype=float)[inter],
        arc_ub=np.asarray(stn.ub, dtype=float)[inter],
        waypoint=waypoint,
        scale=scale,
        radius=np.asarray(req.radius, dtype=float).copy(),
        margin=float(req.margin),
        enforced=bool(req.enforced),
        label=tpg.label,
    )
    for name in net.__dataclass_fields__:
        val = getattr(net, name)
        if isinstance(val, np.ndarray):
            val.setflags(write=False)
    return net


# ---------------------------------------------------------------------- files
def from_file(instance: Instance, path: str | Path) -> EventNetwork:
    """The events of a schedule file written by ``hierplan post`` (YAML, JSON or CSV).

    Read by the one reader of schedule files,
    :func:`hierplan_opt.schedule.files.load_schedule` (the file's own plan and settings,
    its times checked against every bound). Raises :class:`InputError` with one line
    naming the file when the schedule does not belong to ``instance`` or its times
    break a bound.
    """

    return from_schedule(load_schedule(path, instance))
