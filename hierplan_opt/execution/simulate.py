"""Execution of a MAPF-POST schedule under disturbances: a discrete-event simulation.

Every robot passes the nodes of its temporal plan graph (TPG) in path order. In
``agent`` mode it moves at constant velocity between consecutive nodes (the paper's
agent simulation) and passes node ``v`` at

``t_v = max(phys_v, max over Type-2 arcs u -> v of t_u + lb)``

where ``phys_v`` is when it physically reaches ``v``'s position: not before its target
time (the schedule, or the re-solved STN) and not before its own previous nodes plus
the STN's lower bounds (slowed down by slow regions, plus any halt). A robot that
reaches a node whose Type-2 predecessors have not happened waits there (the TPG/ADG
rule): by the soundness theorem of MAPF-POST (docs/post.md) any such motion keeps
every pair ``r_i + r_j + margin`` apart. Events are processed in time order from a
heap, so the simulation is exact in continuous time; ``dt`` only sets the sampling of
the trajectories of ``robot`` mode.

Policies (``POLICIES``) and the layers they may use:

* ``slack``: follow the schedule and the TPG; delays are absorbed by slack, later
  robots wait where the TPG says (no re-computation);
* ``stn``: a robot late beyond its slack (latest time against the schedule's
  makespan and deadlines) triggers an incremental STN re-solve
  (:func:`~hierplan_opt.schedule.fix_and_propagate`: its next node's release raised,
  successors pushed in topological order); the new times become every robot's
  targets. An inconsistent STN (deadlines) is left unhandled (``layer: none``);
* ``replan`` (default; the hierarchy slack -> stn -> replan): as ``stn``, and an
  inconsistent STN or a breakdown that blocks other robots triggers a MAPF re-plan
  (:mod:`.replan`) from the robots' current positions;
* ``reorder``: as ``replan``, and before an STN re-solve it tries to switch passing
  orders at shared locations (:mod:`.reorder`, the switchable ADG);
* ``adg``: no schedule: each node as soon as its dependencies allow (action
  dependency graph);
* ``naive``: follow the clock, ignore the Type-2 dependencies (collides under delays).
"""

from __future__ import annotations

import heapq
import logging
import math
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from hierplan_opt.core.errors import InputError, OptionError
from hierplan_opt.core.instance import Instance
from hierplan_opt.execution.disturbances import (
    Breakdown,
    Disturbance,
    RandomDelays,
    Slow,
    Stop,
    as_dict,
)
from hierplan_opt.schedule.output import Schedule
from hierplan_opt.schedule.solve_graph import InconsistentSTNError, fix_and_propagate
from hierplan_opt.schedule.stn import PIECE, STN
from hierplan_opt.schedule.tpg import VERTEX, WAIT

if TYPE_CHECKING:
    from hierplan_opt.trajectory.result import Trajectories

log = logging.getLogger(__name__)

POLICIES = ("slack", "stn", "replan", "reorder", "adg", "naive")
MODES = ("agent", "robot", "physics")
LAYERS = {
    "slack": ("slack",),
    "stn": ("slack", "stn"),
    "replan": ("slack", "stn", "replan"),
    "reorder": ("slack", "reorder", "stn", "replan"),
    "adg": ("slack",),
    "naive": ("slack",),
}
#: Time tolerance (seconds).
TOL = 1e-9
#: At most this many MAPF re-plans per run.
MAX_REPLANS = 8


@dataclass(frozen=True)
class Event:
    """One disturbance (or escalation) and the layer that handled it.

    ``layer``: ``slack`` (absorbed, nothing re-computed), ``stn`` (STN re-solved),
    ``replan`` (MAPF re-plan), ``none`` (no layer could handle it, or nothing to
    handle: ``detail`` says which). ``delay`` is how late the robot's next event
    became against its target (seconds).
    """

    time: float
    agent: str
    kind: str
    layer: str
    delay: float = 0.0
    detail: str = ""

    def as_dict(self) -> dict[str, Any]:
        return {
            "time": round(self.time, 6),
            "agent": self.agent,
            "kind": self.kind,
            "layer": self.layer,
            "delay": round(self.delay, 6),
            "detail": self.detail,
        }


@dataclass(frozen=True, eq=False)
class Phase:
    """One schedule that was executed: the original one, or one after a re-plan.

    ``agents`` maps the phase's robots to the instance's indices; ``times`` is the
    executed time of every node of ``schedule.stn`` (NaN when it never happened);
    ``targets`` the last target times (the schedule, or after STN re-solves).
    """

    schedule: Schedule
    agents: tuple[int, ...]
    start: float
    times: np.ndarray
    targets: np.ndarray
    stn: STN


@dataclass(frozen=True, eq=False)
class Execution:
    """Result of :func:`simulate` (read-only).

    Attributes
    ----------
    policy, mode : str
    seed : int
    agent_names : tuple of str
    trajectories : tuple of (n, 1 + dim) arrays
        Per robot the executed way-points ``(time, x, y[, z])`` in instance coordinates;
        the robot moves in a straight line at constant speed between them and stays
        at the last one.
    schedule : Schedule
        The executed way-points as a schedule (``hierplan post`` layout, replayable).
    phases : tuple of :class:`Phase`
        Executed event times per TPG node of each schedule run.
    log : tuple of :class:`Event`
    arrival : (K,) float
        When each robot reached its goal (NaN: never).
    replans : tuple of (Instance, Plan)
        The MAPF instances (broken robots as obstacles) and plans of the re-plans.
    robot_times : (N,) float or None
        Robot mode: when each robot passed each node of the first schedule's TPG.
    statistics : dict
        ``collisions``, ``min_distance``, ``guaranteed_distance``, ``distance_kept``,
        ``makespan``, ``arrival_avg``, ``arrival_max``, ``arrival_sum``, ``finished``,
        ``unfinished``, ``stn_resolves``, ``reorders``, ``replans``, ``runtime`` per
        layer, ``handled`` (events per layer).
    """

    policy: str
    mode: str
    seed: int
    agent_names: tuple[str, ...]
    trajectories: tuple[np.ndarray, ...]
    schedule: Schedule
    phases: tuple[Phase, ...]
    log: tuple[Event, ...]
    statistics: dict[str, Any] = field(default_factory=dict)
    arrival: np.ndarray = field(default_factory=lambda: np.zeros(0))
    replans: tuple[tuple[Instance, Any], ...] = ()
    robot_times: np.ndarray | None = None

    @property
    def event_times(self) -> np.ndarray:
        """Executed time of every node of the first schedule's TPG (NaN: never); in
        robot mode when the robot passed it (the agent run's times are in ``phases``)."""
        return self.phases[0].times if self.robot_times is None else self.robot_times

    def report(self) -> dict[str, Any]:
        """``{statistics, events, schedule}``: the YAML report (plain values)."""
        d = self.schedule.to_dict()
        return {
            "statistics": _plain(self.statistics),
            "events": [e.as_dict() for e in self.log],
            "schedule": d["schedule"],
        }


def _plain(x: Any) -> Any:
    if isinstance(x, dict):
        return {str(k): _plain(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_plain(v) for v in x]
    if isinstance(x, (np.integer,)):
        return int(x)
    if isinstance(x, (float, np.floating)):
        f = float(x)
        return round(f, 9) if math.isfinite(f) else None
    return x


# ---------------------------------------------------------------------- helpers
def rebound(
    stn: STN, *, release: np.ndarray | None = None, deadline: np.ndarray | None = None
) -> STN:
    """``stn.with_bounds(...)`` that keeps the cached topological order and CSR arcs
    (node bounds do not change the graph), so an incremental re-solve stays cheap."""
    new = stn.with_bounds(release=release, deadline=deadline)
    for key in ("topo", "_in", "_out"):
        if key in stn.__dict__:
            new.__dict__[key] = stn.__dict__[key]
    return new


class _Structure:
    """Per-node data of one phase's STN needed by the event loop."""

    def __init__(self, stn: STN, instance: Instance, slows: Sequence[Slow]) -> None:
        tpg = stn.tpg
        self.stn = stn
        self.tpg = tpg
        n = tpg.num_nodes
        agent = tpg.node_agent
        src, dst = stn.arc_src, stn.arc_dst
        cross = agent[src] != agent[dst]
        self.cross_count = np.bincount(dst[cross], minlength=n).astype(np.int64)
        order = np.argsort(src, kind="stable")
        self.out_ptr = np.zeros(n + 1, dtype=np.int64)
        np.cumsum(np.bincount(src, minlength=n), out=self.out_ptr[1:])
        self.out_arcs = order
        order_in = np.argsort(dst, kind="stable")
        self.in_ptr = np.zeros(n + 1, dtype=np.int64)
        np.cumsum(np.bincount(dst, minlength=n), out=self.in_ptr[1:])
        self.in_arcs = order_in
        self.cross = cross
        self.is_piece = stn.arc_kind == PIECE
        self.final = np.zeros(n, dtype=bool)
        self.final[tpg.final_nodes()] = True
        self.first = np.zeros(n, dtype=bool)
        self.first[tpg.start_nodes()] = True
        kind = tpg.node_kind
        self.is_vertex = (kind == VERTEX) | (kind == WAIT)
        # The move each piece (v-1 -> v) belongs to: from the last vertex node before v
        # to the first vertex node at or after v.
        idx = np.arange(n)
        last_v = np.where(self.is_vertex, idx, -1)
        last_v = np.maximum.accumulate(last_v)
        next_v = np.where(self.is_vertex, idx, n)
        next_v = np.minimum.accumulate(next_v[::-1])[::-1]
        self.last_vertex = last_v
        self.next_vertex = next_v
        vert = tpg.node_vertex
        self.move_from = np.where(idx > 0, vert[last_v[np.maximum(idx - 1, 0)]], vert)
        self.move_to = vert[np.minimum(next_v, n - 1)]
        # Slow factor lookup per (vertex pair).
        g = instance.graph
        self.slows: list[tuple[Slow, set[int], set[tuple[int, int]]]] = []
        for s in slows:
            cells = {g.vertex(c) for c in s.cells if _on_map(g, c)}
            edges = {
                (g.vertex(a), g.vertex(b)) for a, b in s.edges if _on_map(g, a) and _on_map(g, b)
            }
            edges |= {(b, a) for a, b in edges}
            self.slows.append((s, cells, edges))

    def slow_factor(self, v: int, t_depart: float) -> tuple[float, Slow | None]:
        """Speed factor of the piece into ``v`` started at ``t_depart``."""
        best, which = 1.0, None
        a, b = int(self.move_from[v]), int(self.move_to[v])
        for s, cells, edges in self.slows:
            hit = a in cells or b in cells or (a, b) in edges
            if hit and s.start <= t_depart < s.end and s.factor < best:
                best, which = s.factor, s
        return best, which


def _on_map(g: Any, c: tuple[int, ...]) -> bool:
    try:
        g.vertex(c)
    except InputError:
        return False
    return True


# ---------------------------------------------------------------------- simulation
class _Sim:
    """The event loop over the phases of one run."""

    def __init__(
        self,
        instance: Instance,
        schedule: Schedule,
        disturbances: Sequence[Disturbance],
        policy: str,
        seed: int,
        solver: str,
        replan_time_limit: float,
        follow: Any = None,
    ) -> None:
        self.instance = instance
        #: Refined trajectories followed in the first phase (None: constant velocity).
        self.follow = follow
        self.holds: list[list[tuple[float, float]]] = [[] for _ in range(len(schedule.agent_names))]
        self.rate0: np.ndarray | None = None
        #: Refined trajectories followed per phase (0: ``follow``; later: refined again
        #: after a re-plan), and the slow factors of their pieces.
        self.follows: dict[int, Any] = {0: follow} if follow is not None else {}
        self.rates: dict[int, np.ndarray] = {}
        self.schedule0 = schedule
        self.policy = policy
        self.layers = LAYERS[policy]
        self.solver = solver
        self.replan_time_limit = replan_time_limit
        self.names = schedule.agent_names
        self.K = len(self.names)
        self.index = {n: i for i, n in enumerate(self.names)}
        for d in disturbances:
            if isinstance(d, (Stop, Breakdown)) and d.agent not in self.index:
                raise InputError(f"disturbance names robot {d.agent!r}, not in the schedule")
        self.slows = [d for d in disturbances if isinstance(d, Slow)]
        self.randoms = [
            (d, np.random.default_rng(d.seed if d.seed is not None else [seed, k]))
            for k, d in enumerate(disturbances)
            if isinstance(d, RandomDelays)
        ]
        self.timed: list[Stop | Breakdown] = [
            d for d in disturbances if isinstance(d, (Stop, Breakdown)) and _timed(d)
        ]
        self.at_wp: dict[int, list[Stop]] = {}
        for d in disturbances:
            if isinstance(d, Stop) and d.at_waypoint is not None:
                self.at_wp.setdefault(self.index[d.agent], []).append(d)
        self.scale = schedule.scale
        self.traj: list[list[tuple[float, np.ndarray]]] = [[] for _ in range(self.K)]
        self.broken = np.zeros(self.K, dtype=bool)
        self.arrival = np.full(self.K, np.nan)
        self.log: list[Event] = []
        self.runtime = {
            "slack": 0.0,
            "reorder": 0.0,
            "stn": 0.0,
            "replan": 0.0,
            "simulation": 0.0,
        }
        self.counts = {"stn_resolves": 0, "replans": 0, "reorders": 0}
        self.phases: list[Phase] = []
        self.replan_at: float | None = None
        self.replan_reason = ""
        self.pending: list[Stop | Breakdown] = []
        self.seq = 0
        self.replans: list[Any] = []
        self.front: list[int] = []
        #: Hand-over waits of each re-planned phase (robot mode keeps them as events):
        #: ``("depart", g, -1, g_a)``: ``g`` leaves its held place after ``g_a`` reached
        #: its new start; ``("node", g, v, g_a)``: node ``v`` of the new STN after that.
        self.handover: dict[int, list[tuple[str, int, int, int]]] = {}

    # ------------------------------------------------------------ phases
    def run(self) -> None:
        t0 = time.perf_counter()
        sched = self.schedule0
        assert sched.stn is not None
        gid = tuple(range(self.K))
        targets = np.array(sched.times, dtype=float)
        if self.follow is not None:
            targets = np.concatenate([r.event_times for r in self.follow.robots]).astype(float)
        if self.policy == "adg":
            targets = np.zeros_like(targets)
        stn = sched.stn
        self._phase(sched, stn, gid, targets, 0.0)
        attempts = 0
        while self.replan_at is not None and attempts < MAX_REPLANS:
            from hierplan_opt.execution.replan import replan

            attempts += 1
            t_r = self.replan_at
            tr = time.perf_counter()
            out = replan(self, t_r)
            self.runtime["replan"] += time.perf_counter() - tr
            self.replan_at = None
            if out is None:
                self._resume()
                continue
            sched, stn, gid, targets = out
            self.counts["replans"] += 1
            if self.follow is not None:
                again = self._refine_again(sched, t_r)
                if again is not None:
                    self.follows[len(self.phases)] = again
                    targets = np.concatenate([r.event_times for r in again.robots]).astype(float)
            self._phase(sched, stn, gid, targets, t_r)
        self.runtime["simulation"] = time.perf_counter() - t0 - self.runtime["replan"]

    def _refine_again(self, sched: Schedule, t_r: float) -> Any:
        """Refined trajectories of a re-planned schedule (as the first ones were made),
        or None (logged): then it is followed at constant velocity."""
        from hierplan_opt.core.errors import HierplanError
        from hierplan_opt.trajectory import refine

        t0 = time.perf_counter()
        try:
            out = refine(self.replans[-1][0], sched, mode=self.follow.mode, stretch="auto")
        except HierplanError as exc:
            out = None
            why = f"the re-planned schedule is followed at constant velocity ({exc})"
        else:
            why = f"the re-planned schedule is refined again (stretch {out.stretch:.3g})"
        self.runtime["refine"] = self.runtime.get("refine", 0.0) + time.perf_counter() - t0
        self._log(t_r, "*", "trajectories", "replan", 0.0, why)
        return out

    def _phase(
        self, sched: Schedule, stn: STN, gid: tuple[int, ...], targets: np.ndarray, start: float
    ) -> None:
        S = _Structure(stn, self.instance, self.slows)
        self.S = S
        self.stn = stn
        self.gid = gid
        n = stn.num_nodes
        self.T = targets.copy()
        self.T0 = targets.copy()
        from hierplan_opt.execution.reorder import arc_locks

        self.locks = arc_locks(stn)
        self.latest = (
            np.maximum(sched.latest, self.T) if self.policy != "adg" else np.full(n, np.inf)
        )
        self.t = np.full(n, np.nan)
        self.phys = np.full(n, np.nan)
        self.seg_start = np.full(n, np.nan)  # when the robot set off towards the node
        self.piece_lb = np.zeros(n)
        self.rate = np.ones(n)  # slow factor of each piece (trajectory following)
        # Duration of each piece on the refined trajectory (first phase only).
        self.piece_dur: np.ndarray | None = None
        follow = self.follows.get(len(self.phases))
        if follow is not None:
            self.piece_dur = np.zeros(n)
            ev = np.concatenate([r.event_times for r in follow.robots]).astype(float)
            self.piece_dur[1:] = np.diff(ev)
            self.rates[len(self.phases)] = self.rate
            if not self.phases:
                self.rate0 = self.rate
        self.remaining = S.cross_count.copy()
        self.version = np.zeros(n, dtype=np.int64)
        self.in_heap = np.zeros(n, dtype=bool)
        self.active = np.ones(n, dtype=bool)
        self.heap: list[tuple[float, int, int, int, int]] = []
        phase = Phase(sched, gid, start, self.t, self.T, stn)
        self.phases.append(phase)
        # Start nodes: robots are at their starts (targets = release).
        for j in range(len(gid)):
            v = int(S.tpg.agent_ptr[j])
            self.phys[v] = max(self.T[v], start)
            self.seg_start[v] = self.phys[v]
            self._try_push(v)
        for d in self.timed:
            self._push_disturbance(d)
        pend, self.pending = self.pending, []
        for d in pend:
            self._push_disturbance(d)
        self.timed = []
        self._loop()
        self.phases[-1] = Phase(sched, gid, start, self.t.copy(), self.T.copy(), self.stn)

    def _resume(self) -> None:
        """A re-plan failed: the robots go on with the running schedule (those that
        wait for a broken robot wait for good)."""
        S = self.S
        self.active[:] = True
        for j, g in enumerate(self.gid):
            nodes = S.tpg.agent_nodes(j)
            if self.broken[g]:
                continue
            done = np.flatnonzero(~np.isnan(self.t[nodes.start : nodes.stop]))
            if not len(done) or int(done[-1]) == len(nodes) - 1:
                continue
            last = nodes.start + int(done[-1])
            if np.isnan(self.phys[last + 1]):
                self._depart(last + 1, float(self.t[last]), 0.0)
            else:
                self._try_push(last + 1)
        ph = self.phases[-1]
        self._loop()
        self.phases[-1] = Phase(
            ph.schedule, ph.agents, ph.start, self.t.copy(), self.T.copy(), self.stn
        )

    def _loop(self) -> None:
        while self.heap:
            when, order, _, key, ver = heapq.heappop(self.heap)
            if order == 0:
                if ver != self.version[key] or not self.active[key]:
                    continue
                self._happen(key, when)
            else:
                self._disturb(self._dist[key], when)

    # ------------------------------------------------------------ heap
    def _push_disturbance(self, d: Stop | Breakdown) -> None:
        if not hasattr(self, "_dist"):
            self._dist: list[Stop | Breakdown] = []
        self._dist.append(d)
        self.seq += 1
        assert d.at_time is not None
        heapq.heappush(self.heap, (float(d.at_time), 1, self.seq, len(self._dist) - 1, 0))

    def _ready_time(self, v: int) -> float:
        when = float(self.phys[v])
        if self.policy != "naive":
            S = self.S
            arcs = S.in_arcs[S.in_ptr[v] : S.in_ptr[v + 1]]
            arcs = arcs[S.cross[arcs]]
            if len(arcs):
                when = max(when, float(np.max(self.t[self.stn.arc_src[arcs]] + self.stn.lb[arcs])))
        return when

    def _try_push(self, v: int) -> None:
        if not self.active[v] or math.isnan(self.phys[v]):
            return
        if self.policy != "naive" and self.remaining[v] > 0:
            return
        self.version[v] += 1
        self.in_heap[v] = True
        self.seq += 1
        heapq.heappush(self.heap, (self._ready_time(v), 0, self.seq, v, int(self.version[v])))

    # ------------------------------------------------------------ node events
    def _agent_of(self, v: int) -> int:
        return int(self.S.tpg.node_agent[v])

    def _pos(self, v: int) -> np.ndarray:
        return self.S.tpg.node_coord[v]

    def _record(self, g: int, when: float, pos: np.ndarray) -> None:
        tr = self.traj[g]
        if tr and when < tr[-1][0] - TOL:
            when = tr[-1][0]
        tr.append((float(when), np.array(pos, dtype=float)))

    def _happen(self, v: int, when: float) -> None:
        S = self.S
        j = self._agent_of(v)
        g = self.gid[j]
        if self.broken[g]:
            return
        self.in_heap[v] = False
        self.t[v] = when
        pos = self._pos(v)
        if self.phys[v] < when - TOL:
            self._record(g, float(self.phys[v]), pos)
        self._record(g, when, pos)
        # Type-2 successors.
        arcs = S.out_arcs[S.out_ptr[v] : S.out_ptr[v + 1]]
        for k in arcs[S.cross[arcs]].tolist():
            w = int(self.stn.arc_dst[k])
            self.remaining[w] -= 1
            if self.remaining[w] == 0:
                self._try_push(w)
        if S.final[v]:
            if not (S.first[v] and not np.isnan(self.arrival[g])):
                self.arrival[g] = when  # (a robot that only stays keeps its arrival)
            return
        # Halts at this node: way-point stops, random delays at vertices.
        extra = 0.0
        events: list[tuple[str, str]] = []
        stops = self.at_wp.get(g, [])
        wp_index = self._waypoint_index(j, v) if stops else None
        for d in stops:
            if wp_index is not None and d.at_waypoint == wp_index and self.phases[-1].start == 0:
                extra += d.duration
                events.append(("stop", f"halts {d.duration:g} s at way-point {d.at_waypoint}"))
        if S.is_vertex[v] and self.randoms:
            for d, rng in self.randoms:
                if rng.random() < d.probability:
                    x = d.draw(rng)
                    if x > 0:
                        extra += x
                        events.append(("random", f"delayed {x:.3g} s"))
        self._depart(v + 1, when, extra)
        if np.isnan(self.phys[v + 1]):  # beyond a re-planning frontier
            for kind, detail in events:
                self._log(
                    when, self.names[g], kind, "replan", extra, detail + "; re-plan under way"
                )
            return
        for kind, detail in events:
            self._react(g, v + 1, kind, detail, when)

    def _waypoint_index(self, j: int, v: int) -> int | None:
        wp = self.phases[-1].schedule.waypoints[j]
        hit = np.flatnonzero(wp.node == v)
        return int(hit[0]) if len(hit) else None

    def _depart(self, n: int, when: float, extra: float) -> None:
        """The robot left the node before ``n`` at ``when`` (halting ``extra`` first)."""
        S = self.S
        if not self.active[n]:
            return
        arcs = S.in_arcs[S.in_ptr[n] : S.in_ptr[n + 1]]
        arcs = arcs[~S.cross[arcs]]
        if self.piece_dur is not None:
            # Following a refined trajectory: its own timing replaces the STN's bounds
            # between a robot's events (it need not stop at every vertex).
            arcs = arcs[S.is_piece[arcs] & (self.stn.arc_src[arcs] == n - 1)]
        base = -math.inf
        slow_hit = None
        for k in arcs.tolist():
            u = int(self.stn.arc_src[k])
            lb = float(self.stn.lb[k])
            if S.is_piece[k] and u == n - 1:
                if self.piece_dur is not None:
                    lb = float(self.piece_dur[n])  # the refined motion, not the STN bound
                f, s = S.slow_factor(n, when + extra)
                if s is not None:
                    slow_hit = s
                lb /= f
                self.rate[n] = f
                self.piece_lb[n] = lb
            base = max(base, float(self.t[u]) + lb + extra)
        if not arcs.size:
            base = when + extra
        target = self.T[n]
        self.seg_start[n] = when + extra
        self.phys[n] = max(float(target), base)
        if extra > 0:
            g = self.gid[self._agent_of(n)]
            self._record(g, when + extra, self._pos(n - 1))
            self.holds[g].append((when, when + extra))
        if slow_hit is not None:
            g = self.gid[self._agent_of(n)]
            self._react(
                g, n, "slow", f"slowed to {slow_hit.factor:g} of its speed", when, quiet=True
            )
        self._try_push(n)

    # ------------------------------------------------------------ reactions
    def _react(
        self, g: int, n: int, kind: str, detail: str, now: float, quiet: bool = False
    ) -> None:
        """Robot ``g``'s next node ``n`` may now be late: pick the layer that handles it."""
        t0 = time.perf_counter()
        late = float(self.phys[n] - self.T[n])
        slack = float(self.latest[n] - self.T[n])
        name = self.names[g]
        if late <= TOL * max(1.0, abs(self.T[n])):
            if not quiet:
                self._log(now, name, kind, "slack", 0.0, detail + "; on time")
            self.runtime["slack"] += time.perf_counter() - t0
            return
        if self.policy in ("adg", "naive") or late <= slack + TOL or "stn" not in self.layers:
            ok = late <= slack + TOL
            note = "absorbed by slack" if ok else f"not absorbed ({late - slack:.3g} s past slack)"
            if self.policy in ("adg", "naive"):
                note = "no schedule to repair" if self.policy == "adg" else "clock followed"
            self._log(now, name, kind, "slack", late, f"{detail}; {note}")
            self.runtime["slack"] += time.perf_counter() - t0
            return
        self.runtime["slack"] += time.perf_counter() - t0
        if "reorder" in self.layers:
            from hierplan_opt.execution.reorder import try_reorder

            t1 = time.perf_counter()
            switched = try_reorder(self, now)
            self.runtime["reorder"] += time.perf_counter() - t1
            if switched:
                self._log(
                    now,
                    name,
                    kind,
                    "reorder",
                    late,
                    f"{detail}; {switched} passing order(s) switched",
                )
                return
        t1 = time.perf_counter()
        try:
            self._resolve(n, now)
        except InconsistentSTNError as exc:
            self.runtime["stn"] += time.perf_counter() - t1
            if "replan" in self.layers:
                self._log(now, name, kind, "replan", late, f"{detail}; STN inconsistent: {exc}")
                self._request_replan(now, f"STN inconsistent after {name} {detail}")
            else:
                self._log(now, name, kind, "none", late, f"{detail}; STN inconsistent: {exc}")
            return
        self.runtime["stn"] += time.perf_counter() - t1
        self._log(now, name, kind, "stn", late, f"{detail}; STN re-solved")

    def _resolve(self, n: int, now: float) -> None:
        """Incremental STN re-solve: ``n``'s release raised to when the robot can be
        there, executed events fixed, successors pushed (topological order)."""
        stn = self.stn
        release = np.array(stn.release, dtype=float)
        release[n] = max(release[n], float(self.phys[n]))
        new_stn = rebound(stn, release=release)
        times = np.where(np.isnan(self.t), self.T, self.t)
        fixed = {n - 1: float(self.t[n - 1])} if not np.isnan(self.t[n - 1]) else {}
        new_T = fix_and_propagate(new_stn, times, fixed, changed=[n])
        self.counts["stn_resolves"] += 1
        changed = np.flatnonzero((new_T > self.T + TOL) & np.isnan(self.t))
        self.stn = new_stn
        self.T = np.where(np.isnan(self.t), new_T, self.T)
        # Robots heading to a node whose target moved slow down from now on.
        for v in changed.tolist():
            if not np.isnan(self.phys[v]) and self.T[v] > self.phys[v]:
                g = self.gid[self._agent_of(v)]
                if self.traj[g] and self.traj[g][-1][0] < now < self.phys[v]:
                    self._record(g, now, self.traj_pos(g, now, v))
                self.phys[v] = float(self.T[v])
                if self.in_heap[v]:
                    self._try_push(v)

    def install(self, stn: STN, locks: np.ndarray, targets: np.ndarray, now: float) -> None:
        """Run on with another STN of the same nodes (switched passing orders) and new
        targets: Type-2 counts are rebuilt from the events that happened; robots on
        their way change speed from ``now`` on."""
        self.stn = stn
        self.locks = locks
        self.S = _Structure(stn, self.instance, self.slows)
        happened = ~np.isnan(self.t)
        cross = self.S.cross & ~happened[stn.arc_src]
        self.remaining = np.bincount(stn.arc_dst[cross], minlength=stn.num_nodes).astype(np.int64)
        old_T = self.T
        self.T = np.where(happened, self.T, targets)
        for v in np.flatnonzero(~happened & ~np.isnan(self.phys)).tolist():
            arrive = float(self.phys[v])
            if now < arrive and self.T[v] != old_T[v]:
                g = self.gid[self._agent_of(v)]
                t_last = self.traj[g][-1][0] if self.traj[g] else now
                depart = max(now, t_last)
                here = self.traj_pos(g, depart, v)
                if now > t_last:
                    self._record(g, now, here)
                piece = float(np.linalg.norm(self._pos(v) - self._pos(v - 1)))
                left = float(np.linalg.norm(self._pos(v) - here))
                rest = left / piece if piece > 0 else 0.0
                fastest = depart + rest * float(self.piece_lb[v])
                self.phys[v] = max(float(self.T[v]), fastest)
            self.version[v] += 1
            self.in_heap[v] = False
            self._try_push(v)

    def _request_replan(self, now: float, reason: str) -> None:
        if self.replan_at is None:
            self.replan_at = now
            self.replan_reason = reason
            from hierplan_opt.execution.replan import restrict_to_frontier

            restrict_to_frontier(self, now)

    def _log(
        self, when: float, agent: str, kind: str, layer: str, delay: float, detail: str
    ) -> None:
        self.log.append(Event(float(when), agent, kind, layer, float(delay), detail))

    # ------------------------------------------------------------ timed disturbances
    def position(self, j: int, now: float) -> tuple[np.ndarray, int]:
        """Robot ``j``'s (phase index) position at ``now`` and its next node (or -1)."""
        S = self.S
        nodes = S.tpg.agent_nodes(j)
        done = np.flatnonzero(~np.isnan(self.t[nodes.start : nodes.stop]))
        g = self.gid[j]
        if not len(done):
            return self.traj_pos(g, now), nodes.start
        last = nodes.start + int(done[-1])
        if last == nodes.stop - 1:
            return self._pos(last), -1
        n = last + 1
        return self.traj_pos(g, now, n), n

    def traj_pos(self, g: int, now: float, n: int | None = None) -> np.ndarray:
        tr = self.traj[g]
        if not tr:
            j = self.gid.index(g)
            return self._pos(int(self.S.tpg.agent_ptr[j]))
        t_last, p_last = tr[-1]
        if n is None or np.isnan(self.phys[n]) or now <= t_last:
            return p_last
        arrive = float(self.phys[n])
        if now >= arrive:
            return self._pos(n)
        f = (now - t_last) / max(arrive - t_last, 1e-12)
        return p_last + f * (self._pos(n) - p_last)

    def _disturb(self, d: Stop | Breakdown, now: float) -> None:
        g = self.index[d.agent]
        if self.broken[g] or g not in self.gid:
            self._log(now, d.agent, _kind(d), "none", 0.0, "robot already broken down")
            return
        j = self.gid.index(g)
        pos, n = self.position(j, now)
        if n >= 0 and not self.active[n]:
            self.pending.append(_shift(d, now))  # at its frontier: next schedule
            return
        if isinstance(d, Breakdown):
            if self.piece_dur is not None:  # where its refined trajectory has got to
                from hierplan_opt.execution.follow import refined_position

                pos = refined_position(self, j, now)
            self._record(g, now, pos)
            self.broken[g] = True
            if n >= 0:
                self.version[n] += 1
                self.active[n] = False
            self._breakdown(g, j, now)
            return
        if n < 0:
            self._log(now, d.agent, "stop", "none", 0.0, "robot already at its goal")
            return
        arrive = float(self.phys[n])
        if now < arrive:
            t_last = self.traj[g][-1][0] if self.traj[g] else now
            frac = (arrive - now) / max(arrive - t_last, 1e-12)
            self._record(g, now, pos)
            self._record(g, now + d.duration, pos)
            self.holds[g].append((now, now + d.duration))
            rest = frac * float(self.piece_lb[n] or 0.0)
            self.phys[n] = max(arrive, now + d.duration + rest)
        else:
            self.phys[n] = max(arrive, now + d.duration)
        if self.in_heap[n]:
            self._try_push(n)
        self._react(g, n, "stop", f"halts {d.duration:g} s", now)

    def _breakdown(self, g: int, j: int, now: float) -> None:
        name = self.names[g]
        S = self.S
        nodes = S.tpg.agent_nodes(j)
        pending = [v for v in nodes if np.isnan(self.t[v])]
        blocked = _descendants(self.stn, pending) - set(pending)
        others = {self.gid[int(S.tpg.node_agent[v])] for v in blocked}
        if not others:
            self._log(now, name, "breakdown", "none", math.inf, "no other robot depends on it")
            return
        who = ", ".join(self.names[x] for x in sorted(others)[:3])
        more = f" and {len(others) - 3} more" if len(others) > 3 else ""
        if "replan" in self.layers:
            self._log(now, name, "breakdown", "replan", math.inf, f"blocks {who}{more}")
            self._request_replan(now, f"{name} broke down")
        else:
            self._log(now, name, "breakdown", "none", math.inf, f"blocks {who}{more} for good")


def _timed(d: Stop | Breakdown) -> bool:
    return d.at_time is not None


def _kind(d: Disturbance) -> str:
    return str(as_dict(d)["kind"])


def _shift(d: Stop | Breakdown, now: float) -> Stop | Breakdown:
    return d


def _descendants(stn: STN, roots: Sequence[int]) -> set[int]:
    seen = set(int(r) for r in roots)
    stack = list(seen)
    while stack:
        v = stack.pop()
        for w in stn.arc_dst[stn.out_arcs(v)].tolist():
            if w not in seen:
                seen.add(w)
                stack.append(w)
    return seen


# ---------------------------------------------------------------------- front door
def simulate(
    instance: Instance,
    schedule: Schedule,
    *,
    disturbances: Sequence[Disturbance] = (),
    policy: str = "replan",
    mode: str = "agent",
    seed: int = 0,
    dt: float = 0.1,
    solver: str = "ecbs",
    replan_time_limit: float = 30.0,
    trajectories: Trajectories | None = None,
) -> Execution:
    """Execute ``schedule`` under ``disturbances`` with an execution ``policy``.

    Parameters
    ----------
    instance : Instance
        The instance the schedule was made for (radii, kinematics, map).
    schedule : Schedule
        From :func:`hierplan_opt.schedule.postprocess` (it carries its STN).
    disturbances : sequence
        :class:`~.disturbances.Stop`, :class:`~.disturbances.Breakdown`,
        :class:`~.disturbances.Slow`, :class:`~.disturbances.RandomDelays`.
    policy : {"slack", "stn", "replan", "reorder", "adg", "naive"}
        ``replan`` (default) is the hierarchy slack -> stn -> replan.
    mode : {"agent", "robot"}
        ``agent``: constant velocity between way-points; ``robot``: bounded
        acceleration and turning in place (see :mod:`.robot`).
    seed : int
        Seeds random delays that give no seed of their own.
    dt : float
        Sampling step of ``robot`` mode trajectories (seconds).
    solver : str
        Registered MAPF solver for re-plans (default ECBS).
    trajectories : Trajectories, optional
        Refined trajectories of this schedule (:func:`hierplan_opt.trajectory.refine`):
        every robot follows its refined timing instead of constant velocity, holding
        (an instantaneous stop, then the rest of its trajectory time-shifted) where a
        disturbance halts it or a Type-2 predecessor is late; distances are checked
        against ``trajectories.required(i, j)``. A re-planned schedule is followed at
        constant velocity (see :mod:`.follow`). In robot mode the refined event times
        pace the robots (bounded acceleration along the polylines).

    Example
    -------
    >>> from hierplan_opt import Graph, Instance, Plan
    >>> from hierplan_opt.schedule import postprocess
    >>> from hierplan_opt.execution.disturbances import Stop
    >>> inst = Instance.mapf(Graph.grid(4, 1), [(1, 0), (0, 0)], [(3, 0), (2, 0)])
    >>> s = postprocess(inst, Plan.from_paths([[1, 2, 3], [0, 1, 2]]))
    >>> ex = simulate(inst, s, disturbances=[Stop("agent0", 1.5, at_time=0.5)])
    >>> ex.arrival.tolist(), ex.statistics["collisions"], [e.layer for e in ex.log]
    ([3.5, 2.5], 0, ['stn'])
    """
    if policy not in POLICIES:
        raise OptionError(f"unknown policy {policy!r} (use {', '.join(POLICIES)})")
    if mode not in MODES:
        raise OptionError(f"unknown mode {mode!r} (use {', '.join(MODES)})")
    if mode == "physics":
        return _physics(instance, schedule, disturbances, policy, seed, solver, replan_time_limit)
    if not (isinstance(dt, (int, float)) and math.isfinite(dt) and dt > 0):
        raise OptionError(f"dt must be a positive number of seconds, got {dt!r}")
    if schedule.stn is None:
        raise InputError("the schedule has no STN (make it with postprocess, not from a file)")
    if schedule.num_agents != instance.num_agents:
        raise InputError(
            f"the schedule has {schedule.num_agents} robots, the instance {instance.num_agents}"
        )
    if trajectories is not None:
        from hierplan_opt.execution.follow import check_trajectories

        check_trajectories(schedule, trajectories, mode)
    sim = _Sim(
        instance, schedule, disturbances, policy, seed, solver, replan_time_limit, trajectories
    )
    sim.run()
    from hierplan_opt.execution.statistics import finish

    return finish(sim, instance, schedule, policy, mode, seed, dt)


def _physics(
    instance: Instance,
    schedule: Schedule,
    disturbances: Sequence[Disturbance],
    policy: str,
    seed: int,
    solver: str,
    replan_time_limit: float,
) -> Execution:
    """``mode="physics"``: the run in MuJoCo (:func:`hierplan_opt.physics.loop.closed_loop`)
    as an :class:`Execution` (trajectories sampled every control step)."""
    from hierplan_opt.physics.loop import closed_loop  # heavy module (MuJoCo)

    pol = {"slack": "slack", "stn": "stn"}.get(policy, "replan")
    if policy not in ("slack", "stn", "replan"):
        log.warning("physics mode runs policy %s as %s", policy, pol)
    run, events = closed_loop(
        instance,
        schedule,
        disturbances,
        policy=pol,
        seed=seed,
        solver="auto" if solver == "ecbs" else solver,
        replan_time_limit=replan_time_limit,
    )
    st = dict(run.statistics)
    names = run.names
    arrival = np.array([r[-1] if len(r) else np.nan for r in run.reach])
    ok = arrival[~np.isnan(arrival)]
    handled = {"slack": 0, "stn": 0, "replan": 0, "none": 0, **st["handled"]}
    st.update(
        collisions=st["contacts"],
        arrival_avg=float(ok.mean()) if len(ok) else math.nan,
        arrival_max=float(ok.max()) if len(ok) else math.nan,
        arrival_sum=float(ok.sum()),
        unfinished=[n for n, a in zip(names, arrival, strict=True) if np.isnan(a)],
        handled=handled,
        runtime={"stn": 0.0, "replan": 0.0, "simulation": st["wall"]},
        reorders=0,
    )
    scale = float(schedule.scale)
    dim = schedule.dim
    traj = tuple(
        np.column_stack([run.samples_t, run.samples_p[:, i, :dim] / scale])
        for i in range(len(names))
    )
    log_ = tuple(Event(e.time, e.agent, e.kind, e.layer, e.delay, e.detail) for e in events)
    return Execution(policy, "physics", seed, names, traj, schedule, (), log_, st, arrival)
