"""The schedule's events as refinement sees them: an adapter over ``hierplan_opt.schedule``.

Refinement needs, for every robot, its STN events in path order (vertices, the
markers that end or begin a clearance claim, and ``wait`` events where a robot sets off
from its start) with their positions and scheduled times, the precedences *between*
robots (the Type-2 arcs), and the clearance they keep: ``r_i + r_j + margin`` for every
pair (``docs/post.md``). :class:`EventNetwork` collects exactly that from the public
parts of a :class:`~hierplan_opt.schedule.Schedule` (its ``stn``, ``times``, windows
``earliest``/``latest`` for the schedule returned, and way-points), so the rest of
:mod:`hierplan_opt.trajectory` never reads the temporal plan graph's internals.

A schedule *file* holds way-points and arrival times but not the STN. :func:`from_file`
rebuilds it: the order in which robots visit every location is the order of their
arrival times there (a precedence makes the later robot arrive strictly later), which
is all the temporal plan graph uses. A discrete plan with these visit orders follows
from the difference constraints "one step per move" and "a robot enters a location no
earlier than the previous visitor enters its next one", solved by longest paths. The
plan is validated and post-processed again with the file's ``margin`` (and without
clearance if the file says it had none); the file's arrival times then replace the
recomputed ones, after a check that the way-points match and that the times respect
every precedence.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from hierplan_opt.core.errors import InputError
from hierplan_opt.core.instance import Instance
from hierplan_opt.core.reprs import short_repr

log = logging.getLogger(__name__)

#: Tolerance (seconds, metres) for matching a file against the rebuilt schedule.
MATCH_TOL = 1e-5


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
    from hierplan_opt.schedule.stn import PRECEDENCE
    from hierplan_opt.schedule.tpg import KIND_NAMES

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
def _margin_of(stats: dict, path: Path) -> float:
    """The file's margin (``delta`` in files of earlier versions)."""
    margin = stats.get("margin", stats.get("delta"))
    if (
        margin is None
        or isinstance(margin, bool)
        or not isinstance(margin, (int, float))
        or not math.isfinite(margin)
        or margin < 0
    ):
        raise InputError(f"{path}: statistics.margin is missing (write it with hierplan post)")
    return float(margin)


def _clearance_of(stats: dict) -> bool:
    """False when the file says a pair needing a distance had no guarantee."""
    rows = stats.get("clearance")
    if not isinstance(rows, list):
        return True
    return not any(isinstance(row, dict) and row.get("guaranteed") is False for row in rows)


def _read_rows(
    path: Path, sched: Any, names: list[str], dim: int
) -> tuple[list[np.ndarray], list[np.ndarray]]:
    if not isinstance(sched, dict):
        raise InputError(f"{path}: 'schedule' must map agent names to way-point lists")
    missing = [n for n in names if n not in sched]
    extra = [n for n in sched if n not in names]
    if missing or extra:
        what = f"no way-points for {missing[0]!r}" if missing else f"unknown agent {extra[0]!r}"
        raise InputError(f"{path}: {what} (the schedule does not belong to this instance)")
    axes = ("x", "y", "z")[:dim]
    rows: list[np.ndarray] = []
    arrivals: list[np.ndarray] = []
    for name in names:
        wps = sched[name]
        if not isinstance(wps, list) or not wps:
            raise InputError(f"{path}: agent {name!r} has no way-points")
        try:
            c = np.array([[float(w[a]) for a in axes] for w in wps], dtype=float)
            t = np.array([float(w["arrival"]) for w in wps], dtype=float)
        except (KeyError, TypeError, ValueError) as exc:
            raise InputError(f"{path}: agent {name!r}: bad way-point ({exc})") from None
        if not (np.isfinite(c).all() and np.isfinite(t).all()):
            raise InputError(f"{path}: agent {name!r}: non-finite coordinate or time")
        rows.append(c)
        arrivals.append(t)
    return rows, arrivals


def from_file(instance: Instance, path: str | Path) -> EventNetwork:
    """The events of a schedule file written by ``hierplan post`` (YAML, JSON or CSV).

    Raises :class:`InputError` with one line naming the file when the schedule does
    not belong to ``instance`` or its times break a precedence.
    """
    from hierplan_opt.core.plan import Plan
    from hierplan_opt.schedule import postprocess, read_schedule, windows
    from hierplan_opt.schedule.stn import PRECEDENCE

    path = Path(path)
    data = read_schedule(path)
    stats = data.get("statistics") or {}
    g = instance.graph
    names = [a.name for a in instance.agents]
    rows, arrivals = _read_rows(path, data["schedule"], names, g.dim)
    lookup = {tuple(np.round(c, 6).tolist()): v for v, c in enumerate(g.coords)}

    # ---- the discrete plan: visit orders from arrival times, steps by longest paths ----
    visits: list[list[tuple[int, float]]] = []
    for name, c, t in zip(names, rows, arrivals, strict=True):
        if lookup.get(tuple(np.round(c[0], 6).tolist())) is None:
            raise InputError(
                f"{path}: the first way-point of {name!r} is not a vertex of the map "
                "(the schedule does not belong to this instance)"
            )
        seq: list[tuple[int, float]] = []
        for k in range(len(t)):
            v = lookup.get(tuple(np.round(c[k], 6).tolist()))
            if v is None:
                continue  # a marker between two vertices
            if seq and seq[-1][0] == v:
                continue  # the end of a turn in place, or where a robot sets off
            seq.append((v, float(t[k])))
        visits.append(seq)
    paths = _plan_from_visits(visits, names, path)
    horizon = max(len(p) for p in paths)
    for p in paths:
        p.extend([p[-1]] * (horizon - len(p)))
    plan = Plan.from_paths(paths)
    margin = _margin_of(stats, path)
    try:
        rebuilt = postprocess(
            instance, plan, "makespan", margin=margin, clearance=_clearance_of(stats)
        )
    except InputError as exc:
        raise InputError(f"{path}: the way-points do not form a valid plan: {exc}") from None
    stn = rebuilt.stn
    assert stn is not None
    tpg = stn.tpg

    # ---- the file's times on the rebuilt events ----------------------------------------
    times = np.zeros(tpg.num_nodes)
    waypoint = np.zeros(tpg.num_nodes, dtype=np.int64)
    for name, c, t, wp in zip(names, rows, arrivals, rebuilt.waypoints, strict=True):
        if len(c) != len(wp) or not np.allclose(c, wp.coords, atol=MATCH_TOL):
            raise InputError(
                f"{path}: the way-points of {name!r} do not match the plan rebuilt from "
                f"them with margin {margin:g} (was the file written by hierplan post "
                "for this instance?)"
            )
        node = np.asarray(wp.node)
        keep = np.flatnonzero(node >= 0)
        times[node[keep]] = t[keep]
        waypoint[node[keep]] = keep
    prec = np.asarray(stn.arc_kind) == PRECEDENCE
    gap = times[stn.arc_dst] - times[stn.arc_src]
    bad = prec & (gap < stn.lb - MATCH_TOL)
    if np.any(bad):
        k = int(np.flatnonzero(bad)[0])
        raise InputError(
            f"{path}: the times break the precedence {tpg.label(int(stn.arc_src[k]))} -> "
            f"{tpg.label(int(stn.arc_dst[k]))}"
        )
    early, late = windows(stn, times)
    return _from_stn(
        stn, times, early, late, waypoint, scale=float(rebuilt.scale), names=tuple(names)
    )


def _plan_from_visits(
    visits: list[list[tuple[int, float]]], names: list[str], path: Path
) -> list[list[int]]:
    """Paths (one vertex per step) whose visit orders are those of the arrival times."""
    import networkx as nx

    G = nx.DiGraph()
    for j, seq in enumerate(visits):
        G.add_node((j, 0))
        for i in range(1, len(seq)):
            G.add_edge((j, i - 1), (j, i), w=1)
    at: dict[int, list[tuple[float, int, int]]] = {}
    for j, seq in enumerate(visits):
        for i, (v, t) in enumerate(seq):
            at.setdefault(v, []).append((t, j, i))
    for v, lst in at.items():
        lst.sort()
        for (_, j, i), (_, k, i2) in zip(lst[:-1], lst[1:], strict=True):
            if j == k:
                continue
            if i + 1 >= len(visits[j]):
                raise InputError(
                    f"{path}: {names[k]!r} reaches the goal of {names[j]!r} after it parked "
                    f"there (vertex {v})"
                )
            G.add_edge((j, i + 1), (k, i2), w=0)
    try:
        order = list(nx.topological_sort(G))
    except nx.NetworkXUnfeasible:
        raise InputError(f"{path}: the arrival times order the robots in a cycle") from None
    step = dict.fromkeys(G.nodes, 0)
    for u in order:
        for _, w, d in G.out_edges(u, data=True):
            step[w] = max(step[w], step[u] + d["w"])
    paths = []
    for j, seq in enumerate(visits):
        p: list[int] = []
        for i, (v, _) in enumerate(seq):
            st = step[(j, i)]
            while len(p) < st:
                p.append(p[-1] if p else v)
            p.append(v)
        paths.append(p)
    return paths
