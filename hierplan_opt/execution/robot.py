"""``robot`` mode: simple robot dynamics on top of the executed event times.

The agent simulation gives every TPG node of every executed schedule (the first one and
those after re-plans) an executed time that respects the TPG. Robot mode then drives
each robot along the path it took there with a fixed step ``dt``:

* **time-to-go speed control** (the paper's Control section): the speed command is the
  distance to the next node over the time left until its target time (the agent
  simulation's executed time), capped by ``v_max``;
* **bounded acceleration** ``a_max``: the speed changes by at most ``a_max * dt`` per
  step, and the robot plans its braking (exactly for the discrete steps) for every
  point where it must stand still: a node whose Type-2 predecessors have not been
  passed *by the robots of this simulation* (the TPG rule, so the clearance theorem
  still holds), a corner (the velocity cannot change direction while moving, for any
  drive), a vertex where a differential drive turns, its goal, the start of a
  re-planned schedule and the place where it breaks down;
* **differential drive** turns in place at ``omega_max``.

**Re-plans.** A robot follows its executed nodes of one schedule after the other. The
start node of a new schedule is a point where it must stand still (it brakes before it
follows the new plan), but it learns so only at the re-plan's time: a robot that then
cannot stop in time within ``a_max`` is stopped there anyway and the run records an
*acceleration violation* (``statistics["acceleration_violations"]``, with the largest
deceleration it needed), never hidden. The hand-over of the re-plan is kept as events:
a robot leaves its held place after the robots whose ways it crosses have reached their
new start vertices, new path nodes near another robot's way wait for that robot (the
waits :mod:`.replan` imposes in time), and nobody starts a new plan before the robots
that broke down stand still where the re-plan assumed them (a robot breaks down at the
place where the agent simulation had it break down and brakes for that place like for
its goal: in robot mode a breakdown is a place, its time may differ).

A robot never passes a node before its Type-2 predecessors, so the robot-mode run keeps
the TPG order; the target times only pace it (the controller may arrive a little early
where it cannot slow down in time, never before a predecessor). It is later than the
agent run where it must accelerate and brake.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from hierplan_opt.core.instance import Instance
from hierplan_opt.execution.state import ExecState

#: Distance tolerance (metres).
EPS = 1e-9
#: Relative tolerance of the acceleration bound.
A_TOL = 1e-6


@dataclass
class _Path:
    """One robot's way through every schedule it executed (points in path order)."""

    coords: list[np.ndarray] = field(default_factory=list)  # instance coordinates
    ids: list[int] = field(default_factory=list)  # global node ids
    target: list[float] = field(default_factory=list)  # pacing times
    known: list[float] = field(default_factory=list)  # stop required from this time on
    rest: list[bool] = field(default_factory=list)  # must stand still there
    #: Per point: nodes of the schedule before a re-plan that the robot still expects
    #: to pass there until it learns of the re-plan (it brakes for them as usual).
    ghost: list[list[int]] = field(default_factory=list)


@dataclass(frozen=True)
class RobotRun:
    """Trajectories ``(time, coords...)`` per robot, arrival times, the violations of
    the acceleration bound (``(time, agent index, needed deceleration)``) and the
    robot-mode times of the first schedule's nodes."""

    trajectories: list[np.ndarray]
    arrival: np.ndarray
    violations: tuple[tuple[float, int, float], ...]
    max_ratio: float
    #: When the robots passed each node of the first schedule (NaN: never).
    event_times: np.ndarray = field(default_factory=lambda: np.zeros(0))


def _paths(sim: ExecState) -> tuple[list[_Path], list[list[tuple[int, float]]], int]:
    """Every robot's points across the phases, and the predecessors of every global node
    (Type-2 arcs, hand-over waits, broken robots before a re-planned start)."""
    K = sim.K
    paths = [_Path() for _ in range(K)]
    offsets = np.cumsum([0] + [ph.stn.num_nodes for ph in sim.phases])
    nid = int(offsets[-1])
    preds: dict[int, list[tuple[int, float]]] = {}
    broken_end: dict[int, tuple[int, float]] = {}  # robot -> (its last point, when)
    ahead: dict[int, list[int]] = {}  # robot -> its nodes cut off by the last re-plan
    for p, ph in enumerate(sim.phases):
        stn = ph.stn
        tpg = stn.tpg
        off = int(offsets[p])
        if sim.policy != "naive":
            cross = tpg.node_agent[stn.arc_src] != tpg.node_agent[stn.arc_dst]
            for k in np.flatnonzero(cross).tolist():
                u, v = int(stn.arc_src[k]), int(stn.arc_dst[k])
                preds.setdefault(off + v, []).append((off + u, float(stn.lb[k])))
        # A re-plan's hand-over: every robot first arrives at its new start vertex (a
        # point of its own, where it stands still), the waits of :mod:`.replan` are
        # kept as events on these arrivals.
        arrive: dict[int, int] = {}
        if p:
            for g in ph.agents:
                arrive[g] = nid
                nid += 1
        prior = dict(broken_end)
        deps = sim.handover.get(p, []) if p else []
        for kind, _g, v, g_a in deps:
            if kind == "node":
                preds.setdefault(off + v, []).append((arrive[g_a], 0.0))
        for j, g in enumerate(ph.agents):
            nodes = np.arange(int(tpg.agent_ptr[j]), int(tpg.agent_ptr[j + 1]))
            done = nodes[~np.isnan(ph.times[nodes])]
            if not len(done):
                continue
            path = paths[g]
            v0 = int(done[0])
            if p and path.ids:
                # Learnt of at the re-plan: until then the robot expects its old plan
                # (``ghost``: the nodes the re-plan cut off).
                boundary = len(path.ids)
                waits = [g_a for kind, gg, _, g_a in deps if kind == "depart" and gg == g]
                if waits:  # leaves its held place after these robots' arrivals
                    preds[nid] = [(arrive[g_a], 0.0) for g_a in waits]
                    _add(path, nid, path.coords[-1], path.target[-1], ph.start, False)
                    nid += 1
                _add(path, arrive[g], tpg.node_coord[v0], float(ph.times[v0]), ph.start, True)
                path.ghost[boundary] = ahead.pop(g, [])
                for b, (end, _when) in prior.items():  # broken robots are in place
                    if b != g:
                        preds.setdefault(off + v0, []).append((end, 0.0))
            for v in done.tolist():
                _add(path, off + v, tpg.node_coord[v], float(ph.times[v]), -math.inf, False)
            if len(done) == len(nodes):
                path.rest[-1] = True  # its goal in this schedule
            cut = nodes[len(done) :]
            ahead[g] = [off + int(v) for v in cut[:8]]
            last_phase = p == len(sim.phases) - 1 or g not in sim.phases[p + 1].agents
            if sim.broken[g] and last_phase:
                t_b, here = sim.traj[g][-1]
                if len(done) < len(nodes):  # broke down on its way: stops there
                    _add(path, nid, here, float(t_b), -math.inf, True)
                    nid += 1
                broken_end[g] = (path.ids[-1], float(t_b))
    out = [preds.get(i, []) for i in range(nid)]
    return paths, out, nid


def _add(path: _Path, nid: int, coord: Any, target: float, known: float, rest: bool) -> None:
    path.ids.append(nid)
    path.coords.append(np.asarray(coord, dtype=float))
    path.target.append(target)
    path.known.append(known)
    path.rest.append(rest)
    path.ghost.append([])


def _corners(pts: np.ndarray) -> np.ndarray:
    """Turn angle (radians) at every point between its incoming and outgoing moves
    (zero-length moves skipped; 0 at the ends)."""
    m = len(pts)
    ang = np.zeros(m)
    seg = np.diff(pts, axis=0)
    length = np.linalg.norm(seg, axis=1)
    last_dir: np.ndarray | None = None
    for k in range(m - 1):
        if length[k] <= EPS:
            continue
        d = seg[k] / length[k]
        if last_dir is not None:
            c = float(np.clip(d @ last_dir, -1.0, 1.0))
            ang[k] = math.acos(c)
        last_dir = d
    return ang


def _brake(d_stop: float, v0: float, a: float, dt: float) -> float:
    """Largest speed after the next step (trapezoidal position update) from which the
    robot still stops within ``d_stop`` braking at ``a`` per step."""
    room = d_stop - 0.5 * dt * v0
    if room <= 0:
        return 0.0
    if not math.isfinite(room):
        return math.inf
    ad = a * dt
    # Braking from v1 = n*ad + r (0 <= r < ad) to rest covers
    # dt * (v1 / 2 + sum_{i=1..n} (v1 - i*ad)) = dt * ((n + 1/2) v1 - ad n (n + 1) / 2),
    # and the step itself 0.5 dt v1: dt * (n + 1) v1 - dt * ad * n (n + 1) / 2 <= room.
    n = max(int(math.sqrt(2 * room / a) / dt), 0)
    best = 0.0
    for m in range(max(n - 2, 0), n + 3):
        v1 = (room / dt + ad * m * (m + 1) / 2) / (m + 1)
        v1 = min(v1, (m + 1) * ad)
        if v1 >= m * ad - 1e-12:
            best = max(best, v1)
    return best


def robot_run(sim: ExecState, instance: Instance, dt: float) -> RobotRun:
    """Drive every robot with bounded acceleration along its executed way (module text)."""
    K = sim.K
    scale = float(sim.scale)
    paths, preds, nid = _paths(sim)
    passed = np.full(nid, np.nan)
    kin = [a.kinematics for a in instance.agents]
    pts: list[np.ndarray] = []
    s_of: list[np.ndarray] = []
    target: list[np.ndarray] = []
    known: list[np.ndarray] = []
    rest: list[np.ndarray] = []
    turn_time: list[np.ndarray] = []
    for g in range(K):
        P = np.array(paths[g].coords, dtype=float).reshape(len(paths[g].coords), -1)
        pts.append(P)
        seg = np.linalg.norm(np.diff(P, axis=0), axis=1) * scale
        s_of.append(np.concatenate(([0.0], np.cumsum(seg))))
        target.append(np.array(paths[g].target, dtype=float))
        known.append(np.array(paths[g].known, dtype=float))
        ang = _corners(P)
        r = np.array(paths[g].rest, dtype=bool) | (ang > 1e-9)
        if len(r):
            r[-1] = True
        rest.append(r)
        k = kin[g]
        tt = np.zeros(len(P))
        if k.drive == "differential" and k.omega_max:
            tt = ang / k.omega_max
            first = sim.phases[0]
            j0 = first.agents.index(g) if g in first.agents else -1
            if j0 >= 0 and len(tt):
                v0 = int(first.stn.tpg.agent_ptr[j0])
                tt[0] = float(first.stn.tpg.node_turn[v0]) / k.omega_max
        turn_time.append(tt)
    ids = [np.array(paths[g].ids, dtype=np.int64) for g in range(K)]
    nxt = np.ones(K, dtype=np.int64)  # index of the next point to pass
    s = np.zeros(K)
    v = np.zeros(K)
    busy_until = np.zeros(K)  # turning in place
    done = np.zeros(K, dtype=bool)
    arrival = np.full(K, np.nan)
    traj: list[list[tuple[float, np.ndarray]]] = [[] for _ in range(K)]
    violations: list[tuple[float, int, float]] = []
    max_ratio = 0.0
    for g in range(K):
        if not len(ids[g]):
            done[g] = True
            continue
        passed[ids[g][0]] = 0.0
        busy_until[g] = turn_time[g][0]
        traj[g].append((0.0, pts[g][0].copy()))
        if len(ids[g]) == 1:
            done[g] = True
            arrival[g] = 0.0 if not np.isnan(sim.arrival[g]) else np.nan
    finite = [float(np.nanmax(x)) for x in target if len(x) and np.isfinite(x).any()]
    horizon = (max(finite) if finite else 0.0) * 3 + 120.0
    step = 0
    idle = 0
    while not done.all() and step * dt < horizon and idle < 10 * int(1 / dt + 1):
        t = step * dt
        t1 = (step + 1) * dt
        moved = False
        for g in range(K):
            if done[g]:
                continue
            if t < busy_until[g]:  # turning in place
                moved = True
                traj[g].append((t1, traj[g][-1][1]))
                continue
            idx = ids[g]
            k = int(nxt[g])
            a_max = kin[g].a_max or math.inf
            v_max = kin[g].v_max
            # Where it must be able to stand still: the first point it may not pass
            # yet, or must rest at. A re-plan's start it learns of at the re-plan.
            stop_at = math.inf
            for m in range(k, len(idx)):
                if known[g][m] > t1:
                    # Beyond: the old plan, as far as the robot knows; it stands still
                    # where that plan holds it (at its last point of that plan).
                    ghost = paths[g].ghost[m]
                    if any(not _free(preds[u], passed, t1) for u in ghost[:1]):
                        stop_at = float(s_of[g][max(m - 1, 0)])
                    break
                if rest[g][m] or not _free(preds[int(idx[m])], passed, t1):
                    stop_at = float(s_of[g][m])
                    break
            d_stop = max(stop_at - s[g], 0.0)
            d_next = max(float(s_of[g][k]) - s[g], 0.0)
            left = float(target[g][k]) - t
            v_cmd = v_max if not (left > dt) else min(v_max, d_next / left)
            v0 = float(v[g])
            if math.isfinite(a_max):
                v_cmd = min(v_cmd, _brake(d_stop, v0, a_max, dt))
                v_new = min(max(v_cmd, v0 - a_max * dt), v0 + a_max * dt)
            else:
                v_new = v_cmd
            v_new = max(0.0, min(v_new, v_max))
            s_new = s[g] + 0.5 * (v0 + v_new) * dt
            if s_new > stop_at + EPS:
                # It cannot stop there within a_max (it learnt of the point too late):
                # stopped there anyway, and recorded.
                need = v0 * v0 / (2 * d_stop) if d_stop > EPS else math.inf
                violations.append((t, g, need))
                s_new, v_new = stop_at, 0.0
            s_new = min(s_new, stop_at)
            if math.isfinite(a_max):
                max_ratio = max(max_ratio, abs(v_new - v0) / dt / a_max)
            # Pass the points reached.
            while k < len(idx) and s_new >= s_of[g][k] - EPS:
                w = int(idx[k])
                if known[g][k] > t1 or not _free(preds[w], passed, t1 + EPS):
                    if v0 > a_max * dt * (1 + A_TOL):  # from v0 to rest in one step
                        violations.append((t, g, v0 / dt))
                    s_new, v_new = float(s_of[g][k]), 0.0
                    break
                passed[w] = t1
                if turn_time[g][k] > 0:
                    busy_until[g] = t1 + turn_time[g][k]
                    s_new, v_new = float(s_of[g][k]), 0.0
                k += 1
                moved = True
                if k == len(idx):
                    done[g] = True
                    if not np.isnan(sim.arrival[g]):
                        arrival[g] = t1
                    break
            nxt[g] = min(k, len(idx) - 1)
            if s_new != s[g] or v_new != v0:
                moved = True
            s[g], v[g] = s_new, v_new
            traj[g].append((t1, _coords(pts[g], s_of[g], s_new)))
        # Stop when nothing can move any more (robots waiting for broken ones).
        late = t1 > horizon / 3 and not moved
        idle = idle + 1 if late else 0
        step += 1
    out = []
    for g in range(K):
        pts_g = traj[g]
        arr = np.array([[p[0], *p[1]] for p in pts_g], dtype=float)
        # Drop samples where nothing changes (keeps the two ends of every rest).
        keep = np.ones(len(arr), dtype=bool)
        if len(arr) > 2:
            same_prev = np.all(arr[1:-1, 1:] == arr[:-2, 1:], axis=1)
            same_next = np.all(arr[1:-1, 1:] == arr[2:, 1:], axis=1)
            keep[1:-1] = ~(same_prev & same_next)
        out.append(arr[keep])
    for _t, g, need in violations:
        a = kin[g].a_max or math.inf
        max_ratio = max(max_ratio, need / a)
    first = passed[: sim.phases[0].stn.num_nodes].copy()
    return RobotRun(out, arrival, tuple(violations), max_ratio, first)


def _free(pre: list[tuple[int, float]], passed: np.ndarray, t: float) -> bool:
    """Whether every predecessor was passed (its lower bound elapsed) by ``t``."""
    for u, lb in pre:
        pu = passed[u]
        if pu != pu or pu + lb > t:  # NaN: not passed
            return False
    return True


def _coords(pts: np.ndarray, s_nodes: np.ndarray, s: float) -> np.ndarray:
    """Instance coordinates at path length ``s`` (straight pieces between points)."""
    k = int(np.searchsorted(s_nodes, s, side="right")) - 1
    k = min(max(k, 0), len(pts) - 1)
    if k == len(pts) - 1:
        return pts[k].copy()
    a, b = pts[k], pts[k + 1]
    span = s_nodes[k + 1] - s_nodes[k]
    f = (s - s_nodes[k]) / span if span > 0 else 0.0
    return a + f * (b - a)
