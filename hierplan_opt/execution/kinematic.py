"""A kinematic :class:`~.plant.Plant`: robots with bounded acceleration that turn in
place (differential drive), stop at corners, and are slowed on slippery regions.

Every robot drives along its route (way-points in metres) with a speed profile:

* at most ``v_max`` (times the slippery factor where it is), speed changes of at most
  ``a_max * dt`` per step (``a_max`` None: speed changes at once);
* it brakes (exactly, for the discrete steps) for every point where it must stand
  still: its gate (the monitor's release), a corner of its route (the velocity cannot
  turn while moving), its last way-point; a gate moved closer than it can brake for is
  obeyed anyway and counted as an acceleration violation (never hidden);
* it never reaches a way-point before the way-point's planned time (time-to-go speed);
* a differential drive turns in place at ``omega_max`` before it sets off in a new
  direction;
* ``stop`` (breakdown): it brakes at ``a_max`` and stays stopped.

Slippery regions are ``(centres (m, 3) metres, half width, factor, start, end)``: inside
a box of that half width around a centre, the top speed and the acceleration (speeding
up) are ``factor`` of the robot's; it slows down to the lower top speed at ``a_max``
(configured on the plant, the monitor only sees lateness).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import replace

import numpy as np

from hierplan_opt.core.instance import Instance, Kinematics
from hierplan_opt.execution.disturbances import Disturbance, Slow, on_map
from hierplan_opt.execution.plant import pad3
from hierplan_opt.schedule.output import Schedule

#: Distance tolerance (metres).
EPS = 1e-9
#: Relative tolerance of the acceleration bound.
A_TOL = 1e-6

Slippery = tuple[np.ndarray, float, float, float, float]


class KinematicPlant:
    """Robots with bounded acceleration on way-point routes (see the module text).

    Example
    -------
    >>> from hierplan_opt.core.instance import Kinematics
    >>> p = KinematicPlant([Kinematics(v_max=1.0, a_max=1.0)], np.zeros((1, 3)))
    >>> p.assign(0, np.array([[2.0, 0, 0]]), np.array([0.0]))
    >>> p.release(0, 0)
    >>> for _ in range(40):
    ...     p.step(0.1)
    >>> p.reached(0), p.positions()[0].round(6).tolist(), p.violations
    (0, [2.0, 0.0, 0.0], 0)
    """

    def __init__(
        self,
        kinematics: Sequence[Kinematics],
        positions: np.ndarray,
        *,
        headings: np.ndarray | None = None,
        slippery: Sequence[Slippery] = (),
    ) -> None:
        n = len(kinematics)
        self.time = 0.0
        self.kin = list(kinematics)
        self.pos = np.array(positions, dtype=float).reshape(n, 3)
        self.heading = np.zeros(n) if headings is None else np.array(headings, dtype=float)
        self.speed = np.zeros(n)
        self.routes: list[np.ndarray] = [self.pos[i : i + 1].copy() for i in range(n)]
        self.times: list[np.ndarray] = [np.zeros(1) for _ in range(n)]
        self.gates = np.full(n, -1, dtype=np.int64)
        self.done = np.full(n, 0, dtype=np.int64)  # reached index per robot
        self.stopped = np.zeros(n, dtype=bool)
        self.slippery = list(slippery)
        #: Steps where a robot needed more than ``a_max`` (a gate it could not brake for).
        self.violations = 0
        #: Largest |a| / a_max seen.
        self.max_ratio = 0.0
        self._stops: list[np.ndarray] = [np.zeros(1, dtype=bool) for _ in range(n)]

    # ------------------------------------------------------------ protocol
    def positions(self) -> np.ndarray:
        return self.pos.copy()

    def assign(self, robot: int, waypoints: np.ndarray, times: np.ndarray) -> None:
        wp = np.array(waypoints, dtype=float).reshape(-1, 3)
        self.routes[robot] = wp
        self.times[robot] = np.array(times, dtype=float)
        self.gates[robot] = -1
        self.done[robot] = -1
        self._stops[robot] = _corners(self.pos[robot], wp)

    def release(self, robot: int, gate: int) -> None:
        self.gates[robot] = gate

    def retime(self, robot: int, times: np.ndarray) -> None:
        self.times[robot] = np.array(times, dtype=float)

    def reached(self, robot: int) -> int:
        return int(self.done[robot])

    def stop(self, robot: int) -> None:
        self.stopped[robot] = True

    def step(self, dt: float) -> None:
        for i in range(len(self.kin)):
            self._step_robot(i, dt)
        self.time += dt

    # ------------------------------------------------------------ dynamics
    def _factor(self, p: np.ndarray) -> float:
        f = 1.0
        for centres, half, factor, t0, t1 in self.slippery:
            if t0 <= self.time < t1 and len(centres):
                inside = np.all(np.abs(centres - p) <= half + EPS, axis=1)
                if inside.any():
                    f = min(f, factor)
        return f

    def _limit(self, i: int, v_new: float, v_old: float, a: float, dt: float) -> float:
        """Speed after one step towards ``v_new`` within ``a`` (harder braking is done
        and counted as a violation)."""
        if math.isinf(a):
            return v_new
        if v_new > v_old + a * dt:
            v_new = v_old + a * dt
        if v_new < v_old - a * dt * (1 + A_TOL):
            self.violations += 1
        if a > 0 and dt > 0:
            self.max_ratio = max(self.max_ratio, abs(v_new - v_old) / (a * dt))
        return max(v_new, 0.0)

    def _step_robot(self, i: int, dt: float) -> None:
        kin = self.kin[i]
        f = self._factor(self.pos[i])
        a = kin.a_max if kin.a_max else math.inf  # braking: full a_max
        a_up = a * f  # speeding up on a slippery region: factor f of it
        route, times, stops = self.routes[i], self.times[i], self._stops[i]
        k = int(self.done[i]) + 1
        v0 = float(self.speed[i])
        if self.stopped[i]:
            v1 = max(0.0, v0 - a * dt) if math.isfinite(a) else 0.0
            self._advance(i, 0.5 * (v0 + v1) * dt, limit=len(route) - 1, brake=True)
            self.speed[i] = v1
            return
        gate = min(int(self.gates[i]), len(route) - 1)
        if k > gate:  # hold: brake on the way to the way-point it was heading for
            v1 = max(0.0, v0 - a * dt) if math.isfinite(a) else 0.0
            if k < len(route):
                self._advance(i, 0.5 * (v0 + v1) * dt, limit=k, brake=False)
            if int(self.done[i]) >= k and v1 > 0:
                self._limit(i, 0.0, v0, a, dt)  # stopped harder than a_max: counted
                v1 = 0.0
            self.speed[i] = v1
            return
        d_next = float(np.linalg.norm(route[k] - self.pos[i]))
        if d_next <= EPS:
            if self.time + dt >= times[k] - EPS:
                self.done[i] = k  # a wait way-point: reached at its time
            self.speed[i] = 0.0
            return
        direction = (route[k] - self.pos[i]) / d_next
        if kin.drive == "differential" and v0 <= EPS:
            want = math.atan2(direction[1], direction[0])
            diff = (want - self.heading[i] + math.pi) % (2 * math.pi) - math.pi
            if abs(diff) > 1e-6:
                turn = (kin.omega_max or math.inf) * dt * f
                self.heading[i] += max(-turn, min(turn, diff))
                return
        # Distance to the next point where it must stand still.
        stop_at = k
        while stop_at < gate and not stops[stop_at]:
            stop_at += 1
        d_stop = d_next + float(
            np.sum(np.linalg.norm(np.diff(route[k : stop_at + 1], axis=0), axis=1))
        )
        v_cap = kin.v_max * f
        if math.isfinite(a):
            # It moves (v0 + v1) dt / 2 this step and can then brake v1^2 / (2 a) (the
            # trapezoid rule is exact for linear speed): the largest v1 that stops in time.
            room = max(d_stop - 0.5 * v0 * dt, 0.0)
            v_brake = a * (-0.5 * dt + math.sqrt(0.25 * dt * dt + 2 * room / a))
        else:
            v_brake = d_stop / dt
        left = float(times[k]) - self.time
        v_time = d_next / left if left > dt else math.inf
        # Time-to-go slows it down only as far as a_max allows (it may come a little
        # early where it cannot slow down in time); braking for stops is a must.
        v_soft = max(v_time, v0 - a * dt) if math.isfinite(a) else v_time
        # On a slippery region it slows down to its lower top speed as it can.
        v_top = max(v_cap, v0 - a * dt) if math.isfinite(a) else v_cap
        v1 = self._limit(i, min(v_top, v_brake, v_soft, v0 + a_up * dt), v0, a, dt)
        self._advance(i, 0.5 * (v0 + v1) * dt, limit=gate, brake=False)
        j = int(self.done[i])
        at_point = j >= 0 and bool(np.all(self.pos[i] == route[j]))
        self.speed[i] = 0.0 if at_point and (stops[j] or j >= gate) else v1

    def _advance(self, i: int, s: float, *, limit: int, brake: bool) -> None:
        """Move robot ``i`` ``s`` metres along its route, way-point by way-point, never
        past way-point ``limit``; reached way-points are recorded."""
        route = self.routes[i]
        k = int(self.done[i]) + 1
        while s > EPS and k <= limit and k < len(route):
            seg = route[k] - self.pos[i]
            d = float(np.linalg.norm(seg))
            if d <= s + EPS:
                self.pos[i] = route[k]
                s -= d
                if d > EPS:
                    self.heading[i] = math.atan2(seg[1], seg[0])
                early = self.time + 1e-12 < self.times[i][k] - 1e-6
                if early and self._stops[i][k] and not brake:
                    break  # early at a point where it stops anyway: it waits for the time
                self.done[i] = k
                k += 1
                if self._stops[i][k - 1]:
                    break
            else:
                self.pos[i] = self.pos[i] + seg / d * s
                self.heading[i] = math.atan2(seg[1], seg[0])
                s = 0.0


def _corners(start: np.ndarray, route: np.ndarray) -> np.ndarray:
    """Way-points of ``route`` (driven from ``start``) where the direction changes, and
    the last one: the points where the robot must stand still."""
    pts = np.vstack([start[None, :], route])
    stops = np.zeros(len(route), dtype=bool)
    stops[-1] = True
    last_dir: np.ndarray | None = None
    last_end = -1
    for k in range(len(route)):
        d = pts[k + 1] - pts[k]
        n = float(np.linalg.norm(d))
        if n <= EPS:
            continue
        u = d / n
        if last_dir is not None and float(u @ last_dir) < 1 - 1e-9 and last_end >= 0:
            stops[last_end] = True
        last_dir, last_end = u, k
    # A way-point where it waits (the next one is at the same place) is a stop too.
    for k in range(len(route) - 1):
        if float(np.linalg.norm(route[k + 1] - route[k])) <= EPS:
            stops[k] = stops[k + 1] = True
    return stops


def kinematic_plant(
    instance: Instance, schedule: Schedule, disturbances: Sequence[Disturbance] = ()
) -> KinematicPlant:
    """The kinematic plant of ``instance``'s robots at the schedule's starts (metres:
    speeds and accelerations scaled by the map's cell size), with the ``Slow``
    disturbances as slippery regions (speed and acceleration times their factor)."""
    scale = float(schedule.scale)
    kins = [
        replace(
            a.kinematics,
            v_max=a.kinematics.v_max * scale,
            a_max=a.kinematics.a_max * scale if a.kinematics.a_max else None,
        )
        for a in instance.agents
    ]
    starts = np.array([pad3(w.coords[0] * scale) for w in schedule.waypoints])
    headings = np.array([float(w.theta[0]) for w in schedule.waypoints])
    g = instance.graph
    slippery: list[Slippery] = []
    for d in disturbances:
        if isinstance(d, Slow):
            cells = [c for c in d.cells if on_map(g, c)]
            for a, b in d.edges:
                cells += [c for c in (a, b) if on_map(g, c)]
            if cells:
                centres = np.array([pad3(np.asarray(c, dtype=float) * scale) for c in cells])
                slippery.append((centres, 0.5 * scale, d.factor, d.start, d.end))
    return KinematicPlant(kins, starts, headings=headings, slippery=slippery)
