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
from typing import TYPE_CHECKING, Any

import numpy as np

from hierplan_opt.core.errors import HierplanError, InputError, OptionError
from hierplan_opt.core.instance import Instance
from hierplan_opt.execution import layers
from hierplan_opt.execution.closed_loop import ClosedLoop
from hierplan_opt.execution.disturbances import (
    Breakdown,
    Disturbance,
    Stop,
    as_dict,
    check_disturbances,
)
from hierplan_opt.execution.follow import check_trajectories, refined_position
from hierplan_opt.execution.kinematic import kinematic_plant
from hierplan_opt.execution.reorder import arc_locks, try_reorder
from hierplan_opt.execution.replan import replan, restrict_to_frontier
from hierplan_opt.execution.state import (
    DISTURBANCE_KINDS,
    LAYERS,
    MAX_REPLANS,
    MODES,
    POLICIES,
    TOL,
    Event,
    ExecState,
    Execution,
    Phase,
    Structure,
    descendants,
    rebound,
    segment_distance,
)
from hierplan_opt.execution.statistics import finish
from hierplan_opt.schedule.output import Schedule
from hierplan_opt.schedule.solve_graph import InconsistentSTNError
from hierplan_opt.schedule.stn import STN
from hierplan_opt.trajectory import refine

if TYPE_CHECKING:
    from hierplan_opt.trajectory.result import Trajectories

log = logging.getLogger(__name__)

#: STNs with at least this many nodes batch their re-solves ...
BATCH_NODES = 20_000
#: ... over this many simulated seconds (one re-solve for every delay in the window).
STN_BATCH = 1.0

__all__ = [
    "DISTURBANCE_KINDS",
    "LAYERS",
    "MODES",
    "POLICIES",
    "Event",
    "ExecState",
    "Execution",
    "Phase",
    "Simulation",
    "rebound",
    "simulate",
]


class Simulation(ExecState):
    """The event loop over the phases of one run (it advances an :class:`ExecState`)."""

    def run(self) -> None:
        t0 = time.perf_counter()
        sched = self.schedule0
        assert sched.stn is not None
        gid = tuple(range(self.K))
        targets = np.array(sched.times, dtype=float)
        if self.follow is not None:
            targets = np.concatenate([r.event_times for r in self.follow.robots]).astype(float)
        targets = layers.initial_targets(self.policy, targets)
        stn = sched.stn
        self._phase(sched, stn, gid, targets, 0.0)
        attempts = 0
        while self.replan_at is not None and attempts < MAX_REPLANS:
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

        t0 = time.perf_counter()
        try:
            out = refine(self.replans[-1][0], sched, mode=self.follow.mode, stretch="auto")
        except HierplanError as exc:
            out = None
            why = f"the re-planned schedule is followed at constant velocity ({exc})"
        else:
            why = f"the re-planned schedule is refined again (stretch {out.stretch:.3g})"
        self.runtime["refine"] = self.runtime.get("refine", 0.0) + time.perf_counter() - t0
        self.log_event(t_r, "*", "trajectories", "replan", 0.0, why)
        return out

    def _phase(
        self, sched: Schedule, stn: STN, gid: tuple[int, ...], targets: np.ndarray, start: float
    ) -> None:
        latest = layers.latest_times(self.policy, sched.latest, targets)
        self.start_phase(sched, stn, gid, targets, start, arc_locks(stn), latest)
        S = self.S
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
        self._hold_before(self.geo_block)  # nobody drives into a broken robot
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
            elif order == 1:
                self._disturb(self.dist_queue[key], when)
            else:
                self._flush_stn(when)

    # ------------------------------------------------------------ heap
    def _push_disturbance(self, d: Stop | Breakdown) -> None:
        self.dist_queue.append(d)
        self.seq += 1
        assert d.at_time is not None
        heapq.heappush(self.heap, (float(d.at_time), 1, self.seq, len(self.dist_queue) - 1, 0))

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
    def _happen(self, v: int, when: float) -> None:
        S = self.S
        j = self.agent_of(v)
        g = self.gid[j]
        if self.broken[g]:
            return
        self.in_heap[v] = False
        self.t[v] = when
        pos = self.pos(v)
        if self.phys[v] < when - TOL:
            if S.tpg.regime == "none" and not S.first[v] and not math.isnan(self.seg_start[v]):
                # Plain TPG: nodes are the vertices themselves, no place to wait at:
                # the robot waits where it was and sets off so as to arrive at ``when``.
                travel = float(self.phys[v] - self.seg_start[v])
                self.record(g, when - travel, self.pos(v - 1))
            else:  # it waits at the node (a marker on its claim's boundary)
                self.record(g, float(self.phys[v]), pos)
        self.record(g, when, pos)
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
                self.log_event(
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
            g = self.gid[self.agent_of(n)]
            self.record(g, when + extra, self.pos(n - 1))
            self.holds[g].append((when, when + extra))
        if slow_hit is not None:
            g = self.gid[self.agent_of(n)]
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
        name = self.names[g]
        verdict, late, note = layers.slack_decision(self, n)
        if verdict != "escalate":
            if verdict == "absorbed" or not quiet:
                self.log_event(now, name, kind, "slack", late, f"{detail}; {note}")
            self.runtime["slack"] += time.perf_counter() - t0
            return
        self.runtime["slack"] += time.perf_counter() - t0
        if "reorder" in self.layers:
            t1 = time.perf_counter()
            out = try_reorder(self, now)
            switched = 0
            if out is not None:
                stn, locks, targets, switched = out
                self.install(stn, locks, targets, now)
                self.counts["reorders"] += switched
            self.runtime["reorder"] += time.perf_counter() - t1
            if switched:
                self.log_event(
                    now,
                    name,
                    kind,
                    "reorder",
                    late,
                    f"{detail}; {switched} passing order(s) switched",
                )
                return
        if self.stn.num_nodes >= BATCH_NODES:
            # Large STNs: the delays of the next STN_BATCH seconds share one re-solve
            # (the TPG keeps the robots apart meanwhile; only targets wait).
            self.stn_pending.append((g, n, kind, detail, late, now))
            if not self.stn_flush_queued:
                self.stn_flush_queued = True
                self.seq += 1
                heapq.heappush(self.heap, (now + STN_BATCH, 2, self.seq, 0, 0))
            return
        self._stn_layer([(g, n, kind, detail, late, now)], now)

    def _flush_stn(self, when: float) -> None:
        pending, self.stn_pending = self.stn_pending, []
        self.stn_flush_queued = False
        if pending:
            self._stn_layer(pending, when)

    def _stn_layer(self, items: list[tuple[int, int, str, str, float, float]], now: float) -> None:
        """One STN re-solve for the late nodes of ``items`` (robot, node, kind, detail,
        lateness, when); each gets its event (``stn``, or ``replan`` / ``none`` when the
        STN is inconsistent)."""
        nodes = [n for _, n, *_ in items if self.active[n] and np.isnan(self.t[n])]
        t1 = time.perf_counter()
        batch = f" ({len(items)} delays in one re-solve)" if len(items) > 1 else ""
        try:
            if nodes:
                for v in layers.stn_resolve(self, nodes, now):
                    self._try_push(v)
        except InconsistentSTNError as exc:
            self.runtime["stn"] += time.perf_counter() - t1
            for g, _, kind, detail, late, when in items:
                name = self.names[g]
                why = f"{detail}; STN inconsistent: {exc}"
                if "replan" in self.layers:
                    self.log_event(when, name, kind, "replan", late, why)
                    self._request_replan(now, f"STN inconsistent after {name} {detail}")
                else:
                    self.log_event(when, name, kind, "none", late, why)
            return
        self.runtime["stn"] += time.perf_counter() - t1
        for g, _, kind, detail, late, when in items:
            self.log_event(
                when, self.names[g], kind, "stn", late, f"{detail}; STN re-solved{batch}"
            )

    def install(self, stn: STN, locks: np.ndarray, targets: np.ndarray, now: float) -> None:
        """Run on with another STN of the same nodes (switched passing orders) and new
        targets: Type-2 counts are rebuilt from the events that happened; robots on
        their way change speed from ``now`` on."""
        self.stn = stn
        self.locks = locks
        self.S = Structure(stn, self.instance, self.slows)
        happened = ~np.isnan(self.t)
        cross = self.S.cross & ~happened[stn.arc_src]
        self.remaining = np.bincount(stn.arc_dst[cross], minlength=stn.num_nodes).astype(np.int64)
        old_T = self.T
        self.T = np.where(happened, self.T, targets)
        for v in np.flatnonzero(~happened & ~np.isnan(self.phys)).tolist():
            arrive = float(self.phys[v])
            if now < arrive and self.T[v] != old_T[v]:
                g = self.gid[self.agent_of(v)]
                t_last = self.traj[g][-1][0] if self.traj[g] else now
                depart = max(now, t_last)
                here = self.traj_pos(g, depart, v)
                if now > t_last:
                    self.record(g, now, here)
                piece = float(np.linalg.norm(self.pos(v) - self.pos(v - 1)))
                left = float(np.linalg.norm(self.pos(v) - here))
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
            t0 = time.perf_counter()
            restrict_to_frontier(self, now)
            self.frontier_time = time.perf_counter() - t0
            self.runtime["replan"] += self.frontier_time

    # ------------------------------------------------------------ timed disturbances
    def _disturb(self, d: Stop | Breakdown, now: float) -> None:
        g = self.index[d.agent]
        if self.broken[g] or g not in self.gid:
            self.log_event(now, d.agent, _kind(d), "none", 0.0, "robot already broken down")
            return
        j = self.gid.index(g)
        pos, n = self.position(j, now)
        if n >= 0 and not self.active[n]:
            self.pending.append(_shift(d, now))  # at its frontier: next schedule
            return
        if isinstance(d, Breakdown):
            if self.piece_dur is not None:  # where its refined trajectory has got to
                pos = refined_position(self, j, now)
            self.record(g, now, pos)
            self.broken[g] = True
            if n >= 0:
                self.version[n] += 1
                self.active[n] = False
            self._breakdown(g, j, now)
            return
        if n < 0:
            self.log_event(now, d.agent, "stop", "none", 0.0, "robot already at its goal")
            return
        arrive = float(self.phys[n])
        if now < arrive:
            t_last = self.traj[g][-1][0] if self.traj[g] else now
            frac = (arrive - now) / max(arrive - t_last, 1e-12)
            self.record(g, now, pos)
            self.record(g, now + d.duration, pos)
            self.holds[g].append((now, now + d.duration))
            rest = frac * float(self.piece_lb[n] or 0.0)
            self.phys[n] = max(arrive, now + d.duration + rest)
        else:
            self.phys[n] = max(arrive, now + d.duration)
        if self.in_heap[n]:
            self._try_push(n)
        self._react(g, n, "stop", f"halts {d.duration:g} s", now)

    def _footprint_blocked(self, g: int, now: float) -> dict[int, int]:
        """Robots (phase index) whose way ahead passes the broken robot ``g``'s
        footprint (closer than ``r_g + r_j + margin``; point robots: through its point),
        and the first of their nodes they may not reach."""
        S = self.S
        tpg = S.tpg
        p = self.traj[g][-1][1] * self.scale
        radius = self.radius
        out: dict[int, int] = {}
        for j, g2 in enumerate(self.gid):
            if g2 == g or self.broken[g2]:
                continue
            nodes = tpg.agent_nodes(j)
            done = np.flatnonzero(~np.isnan(self.t[nodes.start : nodes.stop]))
            first = nodes.start + (int(done[-1]) + 1 if len(done) else 0)
            if first >= nodes.stop or not len(done):
                continue
            here = self.traj_pos(g2, now, first) * self.scale
            ends = tpg.node_pos[first : nodes.stop]
            starts = np.vstack([here[None, :], ends[:-1]])
            need = float(radius[g] + radius[g2] + self.margin)
            d = segment_distance(starts, ends, p)
            hit = np.flatnonzero((d < need - 1e-9 * max(1.0, need)) | (d <= 1e-9))
            if len(hit):
                out[j] = first + int(hit[0])
        return out

    def _hold_before(self, blocked: dict[int, int]) -> None:
        """Robots never set off towards their blocked nodes (they stay where they were)."""
        ends = self.S.tpg.agent_ptr
        for j, v in blocked.items():
            self.version[v : int(ends[j + 1])] += 1
            self.active[v : int(ends[j + 1])] = False
            self.in_heap[v : int(ends[j + 1])] = False

    def _breakdown(self, g: int, j: int, now: float) -> None:
        name = self.names[g]
        S = self.S
        nodes = S.tpg.agent_nodes(j)
        pending = [v for v in nodes if np.isnan(self.t[v])]
        blocked = descendants(self.stn, pending) - set(pending)
        others = {self.gid[int(S.tpg.node_agent[v])] for v in blocked}
        # Whoever would drive into the broken robot (whatever the TPG says) holds.
        geo = self._footprint_blocked(g, now)
        for j2, v in geo.items():
            self.geo_block[j2] = min(v, self.geo_block.get(j2, v))
        self._hold_before(geo)
        others |= {self.gid[j2] for j2 in geo}
        if not others:
            self.log_event(now, name, "breakdown", "none", math.inf, "no other robot depends on it")
            return
        who = ", ".join(self.names[x] for x in sorted(others)[:3])
        more = f" and {len(others) - 3} more" if len(others) > 3 else ""
        if "replan" in self.layers:
            self.log_event(now, name, "breakdown", "replan", math.inf, f"blocks {who}{more}")
            self._request_replan(now, f"{name} broke down")
        else:
            self.log_event(now, name, "breakdown", "none", math.inf, f"blocks {who}{more} for good")


def _timed(d: Stop | Breakdown) -> bool:
    return d.at_time is not None


def _kind(d: Disturbance) -> str:
    return str(as_dict(d)["kind"])


def _shift(d: Stop | Breakdown, now: float) -> Stop | Breakdown:
    return d


def simulate(
    instance: Instance,
    schedule: Schedule,
    *,
    disturbances: Sequence[Disturbance] = (),
    policy: str = "replan",
    mode: str = "agent",
    seed: int = 0,
    dt: float = 0.1,
    solver: str = "auto",
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
    mode : {"agent", "robot", "replay", "physics"}
        ``agent``: constant velocity between way-points (the discrete-event
        simulation); ``robot``: closed loop (:class:`.closed_loop.ClosedLoop`) over a
        :class:`.kinematic.KinematicPlant` - bounded acceleration, turning in place,
        slippery regions; the robots' lateness feeds back into slack, STN re-solve,
        re-ordering and re-planning; ``replay``: the same dynamics open loop on the
        agent run's event times (:mod:`.robot`; also what ``robot`` does when
        following refined ``trajectories`` or under the ``naive`` policy);
        ``physics``: the same closed loop over the MuJoCo plant
        (:func:`hierplan_opt.physics.run.make_plant`), with the physics' measurements
        in the statistics.
    seed : int
        Seeds random delays that give no seed of their own.
    dt : float
        Sampling step of ``robot`` mode trajectories (seconds).
    solver : str
        Registered MAPF solver for re-plans; ``auto`` (default): ECBS up to 100
        robots, LaCAM beyond, LaCAM when ECBS fails.
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
    >>> s = postprocess(inst, Plan.from_paths([[1, 2, 3], [0, 1, 2]]), margin=0)
    >>> ex = simulate(inst, s, disturbances=[Stop("agent0", 1.5, at_time=0.5)])
    >>> ex.arrival.tolist(), ex.statistics["collisions"], [e.layer for e in ex.log]
    ([3.5, 3.5], 0, ['stn'])
    """
    if policy not in POLICIES:
        raise OptionError(f"unknown policy {policy!r} (use {', '.join(POLICIES)})")
    if mode not in MODES:
        raise OptionError(f"unknown mode {mode!r} (use {', '.join(MODES)})")
    if not (isinstance(dt, (int, float)) and math.isfinite(dt) and dt > 0):
        raise OptionError(f"dt must be a positive number of seconds, got {dt!r}")
    if schedule.stn is None:
        raise InputError("the schedule has no STN (make it with postprocess, not from a file)")
    if schedule.num_agents != instance.num_agents:
        raise InputError(
            f"the schedule has {schedule.num_agents} robots, the instance {instance.num_agents}"
        )
    check_disturbances(disturbances, instance, schedule)
    if mode == "physics" and trajectories is not None:
        raise OptionError(
            "physics mode follows the schedule's way-points, not refined trajectories"
        )
    if mode == "physics" and policy == "naive":
        raise OptionError("physics mode runs a closed loop: use a policy other than 'naive'")
    if trajectories is not None:
        check_trajectories(schedule, trajectories, mode)
    if mode == "physics" or (mode == "robot" and trajectories is None and policy != "naive"):
        return _closed_loop(
            instance, schedule, disturbances, policy, seed, solver, replan_time_limit, dt, mode
        )
    sim = Simulation(
        instance, schedule, disturbances, policy, seed, solver, replan_time_limit, trajectories
    )
    sim.run()
    ex = finish(sim, instance, schedule, policy, mode, seed, dt)
    return ex


def _closed_loop(
    instance: Instance,
    schedule: Schedule,
    disturbances: Sequence[Disturbance],
    policy: str,
    seed: int,
    solver: str,
    replan_time_limit: float,
    dt: float,
    mode: str,
) -> Execution:
    """``mode="robot"`` and ``mode="physics"``: the monitor (:class:`.closed_loop.ClosedLoop`:
    slack -> re-order -> STN re-solve -> re-plan) over a plant: the kinematic one, or
    the robots in MuJoCo (:func:`hierplan_opt.physics.run.make_plant`). In physics mode
    the statistics add the physics' measurements (:func:`hierplan_opt.physics.run.measured`:
    engine contacts, every pair at every physics step, tracking error, real-time factor)
    and ``collisions`` counts the one definition's collisions on the sampled motion plus
    the robot pairs the engine saw in contact."""
    t0 = time.perf_counter()
    if mode == "physics":
        from hierplan_opt.physics.run import (  # heavy module (MuJoCo)
            make_plant,
            measured,
            type_a_max,
        )

        plant: Any = make_plant(instance, schedule, disturbances, seed=seed, monitor=True)
        how: dict[str, Any] = {"mode": "physics", "wait_before": True}
    else:
        plant = kinematic_plant(instance, schedule, disturbances)
        how = {}
    loop = ClosedLoop(
        instance,
        schedule,
        plant,
        disturbances=disturbances,
        policy=policy,
        seed=seed,
        solver=solver,
        replan_time_limit=replan_time_limit,
        dt=dt,
        **how,
    )
    ex = loop.run()
    if mode != "physics":
        return ex
    wall = time.perf_counter() - t0
    st = ex.statistics
    me = measured(plant, schedule, wall, type_a_max(instance, schedule))
    st.update(me)
    st["sim_time"] = float(plant.time)
    st["wall"] = wall
    st["collisions"] = int(st["collisions"]) + len(me["contact_pairs"])
    return ex
