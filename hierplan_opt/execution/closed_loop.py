"""Closed-loop execution: a monitor that drives any :class:`~.plant.Plant`.

Every ``dt`` the monitor reads which way-point each robot has reached, and

* **gates** (Type-2 arcs): a robot is released up to the first node of its route whose
  Type-2 predecessors have not happened (it may drive there and wait); a node happens
  when the robot has reached it and its predecessors have happened (plus the arcs'
  lower bounds). So the robots pass the nodes in the order of the TPG, whatever their
  dynamics, and MAPF-POST's guarantee holds;
* **lateness -> layers**: a robot whose predicted arrival at its next node (now plus
  the rest of the way at full speed) is later than the node's latest time is handed to
  the layers of the policy as in the agent simulation: slack (logged), re-order
  (:mod:`.reorder`), STN re-solve (:func:`.layers.stn_resolve`, new times to every
  robot through ``Plant.retime``), re-plan;
* **disturbances** the monitor imposes: a breakdown (``Plant.stop``; robots whose way
  passes the broken robot's footprint are held before it; re-plan), a stop (the robot
  is held for its duration), random delays (held at a vertex). Physical disturbances
  (slippery regions, ...) live in the plant: the monitor sees them as lateness;
* **re-plan**: every working robot is held at its next vertex node; when all stand
  still (slower than the plant's ``still_speed``, if it has one), a new plan from the
  vertices they stand on (broken robots' footprints blocked)
  goes through :func:`.chain.plan_and_post` and the new routes are assigned.
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from typing import Any

import numpy as np

from hierplan_opt.core.graph import Graph
from hierplan_opt.core.instance import Agent, Instance
from hierplan_opt.execution import layers
from hierplan_opt.execution.disturbances import Breakdown, Disturbance, Stop
from hierplan_opt.execution.plant import Plant, pad3
from hierplan_opt.execution.reorder import arc_locks, try_reorder
from hierplan_opt.execution.replan import (
    _distinct_starts,
    _solve,
    _substitute_goals,
    footprint_vertices,
    rescheduled,
)
from hierplan_opt.execution.state import ExecState, Execution, Phase, Structure, descendants
from hierplan_opt.execution.statistics import finish
from hierplan_opt.schedule.output import Schedule
from hierplan_opt.schedule.solve_graph import InconsistentSTNError
from hierplan_opt.schedule.stn import STN

#: At most this many re-plans per closed-loop run.
MAX_REPLANS = 8


#: Disturbances a plant makes itself (physics): a delay they cause is named after them.
PHYSICAL_KINDS = ("spill", "payload", "weak_motor", "wind")
#: Smallest lateness (seconds) at a node worth an event when slack absorbed it.
ABSORBED_MIN = 0.2


class ClosedLoop:
    """The execution monitor over a plant (see the module text).

    Parameters
    ----------
    instance, schedule : the instance and its MAPF-POST schedule (with its STN).
    plant : Plant
        Robot ``g`` of the plant is robot ``g`` of the instance; positions in metres.
    disturbances, policy, seed, solver, replan_time_limit : as :func:`.simulate`.
    dt : float
        Control period (seconds).
    horizon : float, optional
        Give up (robots not at their goals are reported) at this time; default three
        times the planned makespan plus 60 s.
    mode : str
        The execution mode reported (``robot``: a kinematic plant; ``physics``: MuJoCo).
    wait_before : bool
        A robot whose next node is gated waits at the node before it, not on it (as
        on a plain TPG). On a margin-aware TPG a robot waiting *on* a gated node stands
        exactly the clearance from the robot it waits for; a physical robot stops
        within its reach tolerance and touches (the MuJoCo plant sets this).
    """

    def __init__(
        self,
        instance: Instance,
        schedule: Schedule,
        plant: Plant,
        *,
        disturbances: Sequence[Disturbance] = (),
        policy: str = "replan",
        seed: int = 0,
        solver: str = "auto",
        replan_time_limit: float = 30.0,
        dt: float = 0.1,
        horizon: float | None = None,
        mode: str = "robot",
        wait_before: bool = False,
    ) -> None:
        self.instance = instance
        self.mode = mode
        self.wait_before = wait_before
        self.schedule = schedule
        self.plant = plant
        self.dt = float(dt)
        self.seed = seed
        self.state = ExecState(
            instance, schedule, disturbances, policy, seed, solver, replan_time_limit
        )
        self.horizon = horizon if horizon is not None else 3.0 * schedule.makespan + 60.0
        self.timed = sorted(self.state.timed, key=lambda d: float(d.at_time or 0.0))
        self.state.timed = []
        self.halt_until = np.zeros(self.state.K)
        #: Halts not started yet: the robot brakes, then stands still this long.
        self.halt_pending: dict[int, float] = {}
        self.replan_pending = ""
        self.block_limit: dict[int, int] = {}  # robot (phase index) -> last node it may reach
        self.late_logged: set[int] = set()
        #: (robot, physical disturbance) pairs whose delay has been logged once.
        self.cause_logged: set[tuple[int, str]] = set()
        #: The fastest robot's speed over the last step (m/s).
        self.last_motion = 0.0
        #: While a re-plan is pending: the node each robot (phase index) stops at.
        self.frontier: dict[int, int] = {}
        #: Halted robots (stops, random delays): the node each one brakes for.
        self.halt_gate: dict[int, int] = {}
        #: Each robot's speed over the last step (metres per second).
        self.speeds = np.zeros(self.state.K)
        #: Below this speed (m/s) a robot stands still: the plant's ``still_speed`` (a
        #: physical robot's position hold creeps onto its way-point for seconds), else
        #: any motion counts.
        self.still_speed = float(getattr(plant, "still_speed", 0.0))

    # ------------------------------------------------------------ phases
    def _start(
        self, sched: Schedule, stn: STN, gid: tuple[int, ...], targets: np.ndarray, t0: float
    ) -> None:
        st = self.state
        latest = layers.latest_times(st.policy, sched.latest, targets)
        st.start_phase(sched, stn, gid, targets, t0, arc_locks(stn), latest)
        st.phases.append(Phase(sched, gid, t0, st.t, st.T, stn))
        self._arcs()
        self.block_limit = {}
        self.late_logged = set()
        self.frontier = {}
        tpg = stn.tpg
        here = self.plant.positions()
        for j, g in enumerate(gid):
            nodes = tpg.agent_nodes(j)
            route = pad3(tpg.node_pos[nodes])
            self.plant.assign(g, route, st.T[nodes])
            self.plant.release(g, -1)
            if float(np.linalg.norm(here[g] - route[0])) <= 1e-9:
                st.t[nodes.start] = max(t0, float(st.T[nodes.start]))  # it is there

    def _arcs(self) -> None:
        """Per node, its Type-2 predecessors and the arcs' lower bounds (CSR)."""
        st = self.state
        S = st.S
        self.pred_ptr = S.in_ptr
        arcs = S.in_arcs
        self.pred_arc = np.where(S.cross[arcs], arcs, -1)

    def _ready(self, v: int, now: float) -> bool:
        st = self.state
        for k in self.pred_arc[self.pred_ptr[v] : self.pred_ptr[v + 1]].tolist():
            if k < 0:
                continue
            u = int(st.stn.arc_src[k])
            tu = st.t[u]
            if math.isnan(tu) or now + 1e-9 < tu + float(st.stn.lb[k]):
                return False
        return True

    # ------------------------------------------------------------ the loop
    def run(self) -> Execution:
        """Run until every working robot is at the end of its route (or the horizon)."""
        st = self.state
        t_start = time.perf_counter()
        sched = self.schedule
        assert sched.stn is not None
        targets = layers.initial_targets(st.policy, np.array(sched.times, dtype=float))
        self._start(sched, sched.stn, tuple(range(st.K)), targets, 0.0)
        scale = st.scale
        dim = st.S.tpg.node_coord.shape[1]
        pos = self.plant.positions()
        for g in range(st.K):
            st.traj[g].append((0.0, pos[g, :dim] / scale))
        replans = 0
        while True:
            now = float(self.plant.time)
            self._disturbances(now)
            self._happen(now)
            self._lateness(now)
            if self._finished():
                break
            if now > self.horizon:
                st.log_event(now, "-", "horizon", "none", 0.0, f"gave up at {now:.3g} s")
                break
            moving = self._gates(now)
            if self.replan_pending and not moving and replans < MAX_REPLANS:
                replans += 1
                self._replan(now)
                continue
            if self.replan_pending and not moving:
                self.replan_pending = ""  # no more re-plans: robots hold for good
            before = self.plant.positions()
            self.plant.step(self.dt)
            pos = self.plant.positions()
            t = float(self.plant.time)
            for g in range(st.K):
                st.traj[g].append((t, pos[g, :dim] / scale))
            moved = np.linalg.norm(pos - before, axis=1)
            self.speeds = moved / self.dt
            self.last_motion = float(np.max(self.speeds, initial=0.0))
        # Close the running phase.
        ph = st.phases[-1]
        st.phases[-1] = Phase(ph.schedule, ph.agents, ph.start, st.t.copy(), st.T.copy(), st.stn)
        st.runtime["simulation"] = time.perf_counter() - t_start - st.runtime["replan"]
        return finish(
            st,
            self.instance,
            self.schedule,
            st.policy,
            self.mode,
            self.seed,
            self.dt,
            plant=self.plant,
        )

    def _finished(self) -> bool:
        st = self.state
        tpg = st.S.tpg
        for j, g in enumerate(st.gid):
            if st.broken[g]:
                continue
            if math.isnan(st.t[int(tpg.agent_ptr[j + 1]) - 1]):
                if j in self.block_limit and not self.replan_pending:
                    continue  # held for good before a broken robot
                return False
        return True

    # ------------------------------------------------------------ events
    def _happen(self, now: float) -> None:
        st = self.state
        tpg = st.S.tpg
        for j, g in enumerate(st.gid):
            if st.broken[g]:
                continue
            first = int(tpg.agent_ptr[j])
            end = int(tpg.agent_ptr[j + 1])
            r = first + self.plant.reached(g)
            v = st.last_happened(j) + 1
            while v <= r and v < end and self._ready(v, now):
                st.t[v] = self._event_time(v, now)
                self._absorbed(g, v)
                if v == end - 1:
                    st.arrival[g] = now
                elif st.S.is_vertex[v]:
                    self._random_delays(j, g, v, now)
                v += 1

    def _physical_cause(self, g: int) -> str:
        """The physical disturbance (a plant's own: spill, payload, weak motor, wind)
        that acted on robot ``g`` in the last seconds, or ``""``; plants without
        physical disturbances have no ``cause``."""
        cause = getattr(self.plant, "cause", None)
        kind = cause(g) if cause is not None else ""
        return kind if kind in PHYSICAL_KINDS else ""

    def _absorbed(self, g: int, v: int) -> None:
        """Log, once per robot and physical disturbance, a delay it caused that slack
        absorbed (node ``v`` passed late but within its window: no layer above ran)."""
        st = self.state
        late = float(st.t[v] - st.T[v])
        if late <= ABSORBED_MIN or v in self.late_logged:
            return
        kind = self._physical_cause(g)
        if not kind or (g, kind) in self.cause_logged:
            return
        self.cause_logged.add((g, kind))
        st.log_event(
            float(st.t[v]),
            st.names[g],
            kind,
            "slack",
            late,
            f"{late:.3g} s late after the {kind}; absorbed by slack",
        )

    def _event_time(self, v: int, now: float) -> float:
        """When node ``v`` counts as passed: now, but never before its own robot's
        earlier nodes plus the STN's lower bounds (the robot may be faster than those
        bounds - e.g. it turned while it waited - and the STN stays consistent; a later
        time only makes the robots after it wait longer)."""
        st = self.state
        S = st.S
        arcs = S.in_arcs[S.in_ptr[v] : S.in_ptr[v + 1]]
        arcs = arcs[~S.cross[arcs]]
        t = now
        for k in arcs.tolist():
            tu = st.t[int(st.stn.arc_src[k])]
            if not math.isnan(tu):
                t = max(t, float(tu) + float(st.stn.lb[k]))
        return t

    def _random_delays(self, j: int, g: int, v: int, now: float) -> None:
        st = self.state
        for d, rng in st.randoms:
            if rng.random() < d.probability:
                x = d.draw(rng)
                if x > 0:
                    self._hold(g, x)
                    self._react(j, g, v + 1, now, "random", f"delayed {x:.3g} s")

    def _hold(self, g: int, duration: float) -> None:
        """Robot ``g`` halts ``duration`` seconds once it stands still (it brakes first)."""
        self.halt_pending[g] = self.halt_pending.get(g, 0.0) + duration

    def _disturbances(self, now: float) -> None:
        st = self.state
        while self.timed and float(self.timed[0].at_time or 0.0) <= now + 1e-12:
            d = self.timed.pop(0)
            g = st.index[d.agent]
            if st.broken[g] or g not in st.gid:
                st.log_event(now, d.agent, _kind(d), "none", 0.0, "robot already broken down")
                continue
            j = st.gid.index(g)
            if isinstance(d, Breakdown):
                self._breakdown(j, g, now)
                continue
            assert isinstance(d, Stop)
            self._hold(g, d.duration)
            n = st.last_happened(j) + 1
            if n >= int(st.S.tpg.agent_ptr[j + 1]):
                st.log_event(now, d.agent, "stop", "none", 0.0, "robot already at its goal")
                continue
            self._react(j, g, n, now, "stop", f"halts {d.duration:g} s")

    def _breakdown(self, j: int, g: int, now: float) -> None:
        st = self.state
        self.plant.stop(g)
        st.broken[g] = True
        name = st.names[g]
        # Where it will stand: it brakes; conservatively its position now and the rest
        # of the current piece are covered.
        p = self.plant.positions()[g]
        tpg = st.S.tpg
        nodes = tpg.agent_nodes(j)
        pending = [v for v in nodes if math.isnan(st.t[v])]
        blocked = descendants(st.stn, pending) - set(pending)
        others = {int(tpg.node_agent[v]) for v in blocked}
        geo = self._footprint_blocked(g, p)
        for j2, v in geo.items():
            self.block_limit[j2] = min(self.block_limit.get(j2, v - 1), v - 1)
        others |= set(geo)
        others.discard(j)
        if not others:
            st.log_event(now, name, "breakdown", "none", math.inf, "no other robot depends on it")
            return
        who = ", ".join(st.names[st.gid[x]] for x in sorted(others)[:3])
        more = f" and {len(others) - 3} more" if len(others) > 3 else ""
        if "replan" in st.layers:
            st.log_event(now, name, "breakdown", "replan", math.inf, f"blocks {who}{more}")
            self.replan_pending = self.replan_pending or f"{name} broke down"
        else:
            st.log_event(now, name, "breakdown", "none", math.inf, f"blocks {who}{more} for good")

    def _footprint_blocked(self, g: int, p: np.ndarray) -> dict[int, int]:
        """Robots whose remaining route passes robot ``g``'s footprint at ``p`` and the
        first node they may not reach."""
        st = self.state
        tpg = st.S.tpg
        here = self.plant.positions()
        out: dict[int, int] = {}
        dim = tpg.node_pos.shape[1]
        for j, g2 in enumerate(st.gid):
            if g2 == g or st.broken[g2]:
                continue
            first = int(tpg.agent_ptr[j]) + self.plant.reached(g2) + 1
            end = int(tpg.agent_ptr[j + 1])
            if first >= end:
                continue
            ends = tpg.node_pos[first:end]
            starts = np.vstack([here[g2, :dim][None, :], ends[:-1]])
            need = float(st.radius[g] + st.radius[g2] + st.margin)
            ab = ends - starts
            L = np.einsum("ij,ij->i", ab, ab)
            q = p[:dim]
            f = np.clip(np.einsum("ij,ij->i", q - starts, ab) / np.where(L > 0, L, 1.0), 0, 1)
            d = np.linalg.norm(starts + f[:, None] * ab - q, axis=1)
            hit = np.flatnonzero((d < need - 1e-9 * max(1.0, need)) | (d <= 1e-9))
            if len(hit):
                out[j] = first + int(hit[0])
        return out

    # ------------------------------------------------------------ layers
    def _lateness(self, now: float) -> None:
        st = self.state
        tpg = st.S.tpg
        pos = self.plant.positions()
        dim = tpg.node_pos.shape[1]
        for j, g in enumerate(st.gid):
            if st.broken[g]:
                continue
            n = st.last_happened(j) + 1
            if n >= int(tpg.agent_ptr[j + 1]) or n in self.late_logged:
                continue
            v_max = self.instance.agents[g].kinematics.v_max * st.scale
            rest = float(np.linalg.norm(tpg.node_pos[n] - pos[g, :dim])) / max(v_max, 1e-12)
            halt = max(now, float(self.halt_until[g])) + self.halt_pending.get(g, 0.0)
            predicted = halt + rest
            if predicted > st.latest[n] + 1e-6 and predicted > st.T[n] + 1e-6:
                kind = self._physical_cause(g)
                if kind:
                    self.cause_logged.add((g, kind))
                self._react(j, g, n, now, kind or "late", f"{predicted - st.T[n]:.3g} s behind")

    def _react(self, j: int, g: int, n: int, now: float, kind: str, detail: str) -> None:
        """Node ``n`` of robot ``g`` may now be late: the policy's layers handle it."""
        st = self.state
        tpg = st.S.tpg
        if n >= int(tpg.agent_ptr[j + 1]):
            return
        v_max = self.instance.agents[g].kinematics.v_max * st.scale
        pos = self.plant.positions()[g, : tpg.node_pos.shape[1]]
        rest = float(np.linalg.norm(tpg.node_pos[n] - pos)) / max(v_max, 1e-12)
        halt = max(now, float(self.halt_until[g])) + self.halt_pending.get(g, 0.0)
        st.phys[n] = max(float(st.T[n]), halt + rest)
        self.late_logged.add(n)
        t0 = time.perf_counter()
        verdict, late, note = layers.slack_decision(st, n)
        name = st.names[g]
        if verdict != "escalate":
            st.runtime["slack"] += time.perf_counter() - t0
            st.log_event(now, name, kind, "slack", late, f"{detail}; {note}")
            return
        if "reorder" in st.layers:
            t1 = time.perf_counter()
            out = try_reorder(st, now)
            st.runtime["reorder"] += time.perf_counter() - t1
            if out is not None:
                stn, locks, targets, switched = out
                st.stn, st.locks = stn, locks
                st.S = Structure(stn, self.instance, st.slows)
                st.T = np.where(np.isnan(st.t), targets, st.T)
                self._arcs()
                st.counts["reorders"] += switched
                self._retime()
                st.log_event(
                    now, name, kind, "reorder", late, f"{detail}; {switched} order(s) switched"
                )
                return
        t1 = time.perf_counter()
        try:
            layers.stn_resolve(st, n, now)
        except InconsistentSTNError as exc:
            st.runtime["stn"] += time.perf_counter() - t1
            if "replan" in st.layers:
                st.log_event(now, name, kind, "replan", late, f"{detail}; STN inconsistent: {exc}")
                self.replan_pending = self.replan_pending or f"STN inconsistent after {name}"
            else:
                st.log_event(now, name, kind, "none", late, f"{detail}; STN inconsistent: {exc}")
            return
        st.runtime["stn"] += time.perf_counter() - t1
        self._retime()
        st.log_event(now, name, kind, "stn", late, f"{detail}; STN re-solved")

    def _retime(self) -> None:
        st = self.state
        tpg = st.S.tpg
        for j, g in enumerate(st.gid):
            if not st.broken[g]:
                self.plant.retime(g, st.T[tpg.agent_nodes(j)])

    # ------------------------------------------------------------ gates
    def _gates(self, now: float) -> bool:
        """Release every robot as far as the TPG allows; whether any may still move."""
        st = self.state
        tpg = st.S.tpg
        any_free = False
        for j, g in enumerate(st.gid):
            if st.broken[g]:
                continue
            first = int(tpg.agent_ptr[j])
            end = int(tpg.agent_ptr[j + 1])
            r = first + self.plant.reached(g)
            if g in self.halt_pending and self.speeds[g] <= max(self.still_speed, 1e-9):
                self.halt_until[g] = now + self.halt_pending.pop(g)  # it stands: halt
            halted = now < self.halt_until[g] or g in self.halt_pending
            v = max(st.last_happened(j) + 1, first)
            while v < end - 1 and self._ready(v, now):
                v += 1
            gate = v
            if (
                (self.wait_before or tpg.regime == "none")
                and gate < end  # the last node (its goal) too: it may be gated
                and not self._ready(gate, now)
            ):
                gate = max(gate - 1, r)  # wait before the gated node, not on it
            if j in self.block_limit:
                gate = min(gate, self.block_limit[j])
            if self.replan_pending:
                if j not in self.frontier:
                    # It stops at the first vertex node it can brake for (fixed when the
                    # re-plan is asked).
                    self.frontier[j] = self._stop_node(j, g, r, vertex=True)
                gate = min(gate, self.frontier[j])
            if halted:
                if g not in self.halt_gate:
                    self.halt_gate[g] = self._stop_node(j, g, r, vertex=False)
                gate = min(gate, self.halt_gate[g])
                any_free = True  # it goes on after the halt
            else:
                self.halt_gate.pop(g, None)
            gate = max(gate, r)
            self.plant.release(g, gate - first)
            if gate > r:
                any_free = True
        return any_free or self.last_motion > max(self.still_speed, 1e-9 / self.dt)

    def _stop_node(self, j: int, g: int, r: int, *, vertex: bool) -> int:
        """The first node after ``r`` (a vertex node with ``vertex``) that robot ``g``
        can still brake for: at least ``v^2 / (2 a_max)`` ahead (its speed measured from
        the last step)."""
        st = self.state
        S = st.S
        tpg = S.tpg
        end = int(tpg.agent_ptr[j + 1]) - 1
        kin = self.instance.agents[g].kinematics
        v = self.speeds[g] if g < len(self.speeds) else 0.0
        a = kin.a_max * st.scale if kin.a_max else math.inf
        # (The measured speed is the last step's mean: one more step of speeding up and
        # one step of travel before the new gate acts.)
        v_up = v + a * self.dt if math.isfinite(a) else v
        need = v_up * v_up / (2 * a) + v_up * self.dt if math.isfinite(a) else 0.0
        dim = tpg.node_pos.shape[1]
        here = self.plant.positions()[g, :dim]
        ahead = 0.0
        prev = here
        for w in range(r + 1, end + 1):
            ahead += float(np.linalg.norm(tpg.node_pos[w] - prev))
            prev = tpg.node_pos[w]
            if ahead >= need - 1e-9 and (not vertex or S.is_vertex[w]):
                return w
        return end

    # ------------------------------------------------------------ re-plan
    def _replan(self, now: float) -> None:
        st = self.state
        t_begin = time.perf_counter()
        reason, self.replan_pending = self.replan_pending, ""
        inst = self.instance
        g0 = inst.graph
        if g0.kind != "grid":
            st.log_event(now, "-", "replan", "none", 0.0, "re-planning needs a grid map")
            return
        scale = g0.cell_size
        pos = self.plant.positions()
        dim = g0.coords.shape[1]
        vert_pos = g0.coords * scale
        radius = st.radius
        r_max = float(radius.max())
        blocked = np.zeros(g0.n, dtype=bool)
        for b in np.flatnonzero(st.broken).tolist():
            blocked[footprint_vertices(g0, pos[b, :dim], radius[b] + r_max + st.margin)] = True
        tpg = st.S.tpg
        options: dict[int, list[int]] = {}
        goals: dict[int, int] = {}
        for j, g in enumerate(st.gid):
            if st.broken[g]:
                continue
            d = np.linalg.norm(vert_pos - pos[g, :dim], axis=1)
            d[~g0.passable] = np.inf
            options[g] = [int(v) for v in np.argsort(d)[:2]]
            goals[g] = int(tpg.node_vertex[int(tpg.agent_ptr[j + 1]) - 1])
        starts = _distinct_starts(options)
        if starts is None:
            st.log_event(now, "-", "replan", "none", 0.0, "two robots would start at one vertex")
            return
        for s in starts.values():
            blocked[s] = False
        gid2 = tuple(sorted(starts))
        dims = g0.shape
        assert dims is not None
        graph = Graph.grid(
            *dims, blocked=(~g0.passable | blocked).reshape(tuple(reversed(dims))), cell_size=scale
        )
        _substitute_goals(st, now, g0, graph, gid2, starts, goals)
        agents = tuple(
            Agent(inst.agents[k].name, starts[k], goals[k], None, inst.agents[k].kinematics)
            for k in gid2
        )
        inst2 = Instance(graph, agents, (), None, f"{inst.name}-replan")
        planned = _solve(st, inst2, st.margin)
        if planned.schedule is None or planned.result.plan is None:
            st.log_event(now, "-", "replan", "none", 0.0, planned.why)
            for j in range(len(st.gid)):  # they hold where they are
                self.block_limit.setdefault(j, st.last_happened(j))
            return
        st.replans.append((inst2, planned.result.plan))
        sched = planned.schedule
        st.replan_margins.append(float(sched.margin))
        assert sched.stn is not None
        stn = sched.stn
        release = np.array(stn.release, dtype=float)
        deadline = np.array(stn.deadline, dtype=float)
        for k, g in enumerate(gid2):
            v0 = int(stn.tpg.agent_ptr[k])
            v_max = inst.agents[g].kinematics.v_max * scale
            way = float(np.linalg.norm(vert_pos[starts[g]] - pos[g, :dim]))
            release[v0] = now + way / v_max
            deadline[v0] = np.inf
        new_stn = stn.with_bounds(release=release, deadline=deadline)
        sched, times = rescheduled(sched, new_stn)
        st.counts["replans"] += 1
        layer = time.perf_counter() - t_begin
        st.replan_timing.append(
            {
                "time": now,
                "robots": len(gid2),
                "solver": planned.solver,
                "frontier": 0.0,
                "solve": planned.solve_time,
                "post": planned.post_time,
                "handover": 0.0,
                "layer": layer,
            }
        )
        st.runtime["replan"] += layer
        st.log_event(
            now,
            "-",
            "replan",
            "replan",
            0.0,
            f"{reason}: new plan for {len(gid2)} robots ({planned.solver}, cost "
            f"{planned.result.cost}, solve {planned.solve_time:.3g} s, whole layer {layer:.3g} s)",
        )
        ph = st.phases[-1]
        st.phases[-1] = Phase(ph.schedule, ph.agents, ph.start, st.t.copy(), st.T.copy(), st.stn)
        self._start(sched, new_stn, gid2, times, now)


def _kind(d: Disturbance) -> str:
    return "breakdown" if isinstance(d, Breakdown) else "stop"


def closed_loop_run(
    instance: Instance,
    schedule: Schedule,
    plant: Plant,
    **kwargs: Any,
) -> Execution:
    """Run :class:`ClosedLoop` over ``plant`` and return its :class:`Execution`."""
    return ClosedLoop(instance, schedule, plant, **kwargs).run()
