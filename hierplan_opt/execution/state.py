"""The state of one execution run as one typed object (:class:`ExecState`), and the
records it produces (:class:`Event`, :class:`Phase`, :class:`Execution`).

Bottom of :mod:`hierplan_opt.execution`: it imports no other module of the package's
execution layer except :mod:`.disturbances`, so the layers and reports that receive an
:class:`ExecState` import this module, never the event loop (no import cycles).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from hierplan_opt.core.errors import InputError
from hierplan_opt.core.instance import Instance
from hierplan_opt.execution.disturbances import (
    Breakdown,
    Disturbance,
    RandomDelays,
    Slow,
    Stop,
    on_map,
)
from hierplan_opt.io.values import plain
from hierplan_opt.schedule.output import Schedule
from hierplan_opt.schedule.stn import PIECE, STN
from hierplan_opt.schedule.tpg import VERTEX, WAIT

POLICIES = ("slack", "stn", "replan", "reorder", "adg", "naive")
#: Event kinds that are disturbances (``late``: the closed loop saw a robot late beyond
#: its slack; the others - ``replan``, ``goal``, ``trajectories``, ``horizon`` - record
#: what the layers did).
DISTURBANCE_KINDS = (
    "stop",
    "breakdown",
    "slow",
    "random",
    "late",
    "spill",
    "payload",
    "weak_motor",
    "wind",
)
MODES = ("agent", "robot", "replay", "physics")
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
        ``collisions``, ``min_distance`` (``inf`` only when ``min_distance_above``, a
        bound every pair stayed above, is set), ``guaranteed_distance``, ``distance_kept``,
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
            "statistics": plain(self.statistics, digits=9),
            "events": [e.as_dict() for e in self.log],
            "schedule": d["schedule"],
        }


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


class Structure:
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
            cells = {g.vertex(c) for c in s.cells if on_map(g, c)}
            edges = {
                (g.vertex(a), g.vertex(b)) for a, b in s.edges if on_map(g, a) and on_map(g, b)
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


# ---------------------------------------------------------------------- simulation


class ExecState:
    """Everything one execution run knows, typed: the instance and schedule, the
    disturbances, the robots' executed trajectories and events, the running phase's
    TPG/STN state (targets ``T``, executed times ``t``, physical arrivals ``phys``,
    Type-2 counts, active nodes) and what the layers did (log, counts, runtimes).

    The event loop (:class:`hierplan_opt.execution.simulate.Simulation`) advances it;
    the layers (:mod:`.layers`: slack and STN re-solve, :mod:`.reorder`,
    :mod:`.replan`) and the reports (:mod:`.statistics`, :mod:`.follow`,
    :mod:`.robot`) receive it explicitly and never import the loop.
    """

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
            d for d in disturbances if isinstance(d, (Stop, Breakdown)) and d.at_time is not None
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
        #: Per re-plan: when, robots, solver and seconds of frontier, solve, post,
        #: hand-over and the whole layer (frontier to new schedule).
        self.replan_timing: list[dict[str, Any]] = []
        #: The margin of each re-planned schedule (smaller than the first one's when
        #: point robots fell back to margin 0).
        self.replan_margins: list[float] = []
        self.frontier_time = 0.0
        self.front: list[int] = []
        #: Hand-over waits of each re-planned phase (robot mode keeps them as events):
        #: ``("depart", g, -1, g_a)``: ``g`` leaves its held place after ``g_a`` reached
        #: its new start; ``("node", g, v, g_a)``: node ``v`` of the new STN after that.
        self.handover: dict[int, list[tuple[str, int, int, int]]] = {}
        self.radius = np.array([a.kinematics.radius for a in instance.agents], dtype=float)
        self.margin = float(schedule.margin)
        #: Per robot (phase index) the first node it may not reach: a broken robot
        #: stands in its way (reset with every phase).
        self.geo_block: dict[int, int] = {}
        #: Robots whose goal a re-plan replaced: ``gid -> (goal, substitute)`` (vertices).
        self.substituted: dict[int, tuple[int, int]] = {}

        # ------------------------------------------------------------ phases

        # The running phase (set by ``start_phase``): its STN and per-node arrays.
        self.S: Structure
        self.stn: STN
        self.gid: tuple[int, ...] = ()
        empty = np.zeros(0)
        self.T = empty  # target times
        self.T0 = empty  # the phase's first targets
        self.t = empty  # executed times (NaN: not yet)
        self.phys = empty  # when the robot physically gets to the node
        self.latest = empty
        self.locks = np.zeros(0, dtype=np.int64)
        self.seg_start = empty
        self.piece_lb = empty
        self.rate = empty
        self.piece_dur: np.ndarray | None = None
        self.remaining = np.zeros(0, dtype=np.int64)
        self.version = np.zeros(0, dtype=np.int64)
        self.in_heap = np.zeros(0, dtype=bool)
        self.active = np.zeros(0, dtype=bool)
        self.heap: list[tuple[float, int, int, int, int]] = []
        self.dist_queue: list[Stop | Breakdown] = []
        #: Late nodes waiting for a batched STN re-solve (large STNs), and whether the
        #: re-solve is queued: ``(robot, node, kind, detail, lateness, when)``.
        self.stn_pending: list[tuple[int, int, str, str, float, float]] = []
        self.stn_flush_queued = False

    def start_phase(
        self,
        sched: Schedule,
        stn: STN,
        gid: tuple[int, ...],
        targets: np.ndarray,
        start: float,
        locks: np.ndarray,
        latest: np.ndarray,
    ) -> None:
        """Make ``sched`` (its STN ``stn``, robots ``gid``, target times) the running
        phase from time ``start``: fresh per-node arrays, nothing queued yet.
        ``locks`` are the STN's switchable arcs (:func:`.reorder.arc_locks`), ``latest``
        how late each node may be before the STN layer acts (:func:`.layers.latest_times`).
        """
        S = Structure(stn, self.instance, self.slows)
        self.S = S
        self.stn = stn
        self.gid = gid
        n = stn.num_nodes
        self.T = targets.copy()
        self.T0 = targets.copy()
        self.locks = locks
        self.latest = np.asarray(latest, dtype=float)
        self.t = np.full(n, np.nan)
        self.phys = np.full(n, np.nan)
        self.seg_start = np.full(n, np.nan)  # when the robot set off towards the node
        self.piece_lb = np.zeros(n)
        self.rate = np.ones(n)  # slow factor of each piece (trajectory following)
        # Duration of each piece on the refined trajectory (first phase only).
        self.piece_dur = None
        follow = self.follows.get(len(self.phases))
        if follow is not None:
            self.piece_dur = np.zeros(n)
            ev = np.concatenate([r.event_times for r in follow.robots]).astype(float)
            self.piece_dur[1:] = np.diff(ev)
            self.rates[len(self.phases)] = self.rate
            if not self.phases:
                self.rate0 = self.rate
        self.remaining = S.cross_count.copy()
        self.geo_block = {}
        self.version = np.zeros(n, dtype=np.int64)
        self.in_heap = np.zeros(n, dtype=bool)
        self.active = np.ones(n, dtype=bool)
        self.heap = []
        phase = Phase(sched, gid, start, self.t, self.T, stn)
        self.phases.append(phase)

    def agent_of(self, v: int) -> int:
        return int(self.S.tpg.node_agent[v])

    def pos(self, v: int) -> np.ndarray:
        return self.S.tpg.node_coord[v]

    def record(self, g: int, when: float, pos: np.ndarray) -> None:
        tr = self.traj[g]
        if tr and when < tr[-1][0] - TOL:
            when = tr[-1][0]
        tr.append((float(when), np.array(pos, dtype=float)))

    def log_event(
        self, when: float, agent: str, kind: str, layer: str, delay: float, detail: str
    ) -> None:
        self.log.append(Event(float(when), agent, kind, layer, float(delay), detail))

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
            return self.pos(last), -1
        n = last + 1
        return self.traj_pos(g, now, n), n

    def traj_pos(self, g: int, now: float, n: int | None = None) -> np.ndarray:
        tr = self.traj[g]
        if not tr:
            j = self.gid.index(g)
            return self.pos(int(self.S.tpg.agent_ptr[j]))
        t_last, p_last = tr[-1]
        if n is None or np.isnan(self.phys[n]) or now <= t_last:
            return p_last
        arrive = float(self.phys[n])
        if now >= arrive:
            return self.pos(n)
        f = (now - t_last) / max(arrive - t_last, 1e-12)
        return p_last + f * (self.pos(n) - p_last)

    def last_happened(self, j: int) -> int:
        """Robot ``j``'s (phase index) last node that happened (its first - 1: none)."""
        nodes = self.S.tpg.agent_nodes(j)
        done = np.flatnonzero(~np.isnan(self.t[nodes.start : nodes.stop]))
        return nodes.start + int(done[-1]) if len(done) else nodes.start - 1


def segment_distance(a: np.ndarray, b: np.ndarray, p: np.ndarray) -> np.ndarray:
    """Distance from point ``p`` to each segment ``a[k] -> b[k]``."""
    ab = b - a
    L = np.einsum("ij,ij->i", ab, ab)
    f = np.clip(np.einsum("ij,ij->i", p - a, ab) / np.where(L > 0, L, 1.0), 0.0, 1.0)
    return np.linalg.norm(a + f[:, None] * ab - p, axis=1)


def descendants(stn: STN, roots: Sequence[int]) -> set[int]:
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
