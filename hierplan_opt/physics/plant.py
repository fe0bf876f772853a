"""``MujocoPlant``: robots in a MuJoCo world that follow way-points (the Plant protocol).

The world holds one body per robot (:mod:`.models`): ground robots on a planar base
(x, y, yaw; the floor's grip is the force limit of their wheel motors), quadcopters as
free rigid bodies under gravity. Only robots have collision geometry (a cylinder of the
footprint radius, a sphere for quadcopters), so every contact the engine reports is a
robot-robot contact.

Control (:mod:`.control`) runs every ``control_period`` (ground robots) or every physics
step (quadcopters' attitude loop); between way-points a robot follows the straight line
at the time-to-go speed ``distance / (planned arrival - now)``, capped by ``v_max``, by
the speed from which it can still stop at its next stop point (a corner, its last
way-point, or the way-point ``gate`` it is held at) with its acceleration, and it never
leaves a way-point before that way-point's planned time. Differential drives turn in
place before they drive. A way-point is *reached* within ``reach_tol`` metres (heading
independent) and not before ``early`` seconds ahead of its time.

Measured, every physics step: the distance of every pair of robots (vectorised) against
its required clearance, and the engine's contacts. The plant also records every robot's
position at every control step (:attr:`MujocoPlant.samples`).
"""

from __future__ import annotations

import importlib
import logging
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from hierplan_opt.physics.disturbances import (
    Payload,
    PhysicalDisturbance,
    RandomStops,
    RobotStop,
    Spill,
    WeakMotor,
    Wind,
)
from hierplan_opt.physics.models import (
    CHASSIS_HEIGHT,
    MU_FLOOR,
    ROLLING_DAMPING,
    RobotModel,
    traction,
)

log = logging.getLogger(__name__)

#: MuJoCo (heavy module: only hierplan_opt.physics imports it; compiled bindings
#: without type information, hence Any).
mujoco: Any = importlib.import_module("mujoco")

#: Air density (kg/m^3).
RHO_AIR = 1.2
#: Drag area c_d * A (m^2): quadcopter (ours, Crazyflie frame and props), ground robots
#: per metre of diameter (ours: c_d 1 times a 0.2 m high chassis).
DRAG_AREA_QUAD = 0.005
DRAG_AREA_GROUND_PER_M = 0.2
#: Pairs measured at every physics step: within this (m) of the closest pair's distance
#: or clearance margin at the last control step (robots move < 0.1 m per period).
NEAR = 0.5
#: Heading error (rad) above which a differential drive stands and turns in place.
TURN_IN_PLACE = 0.1
#: Heading error (rad) below which a turn in place is done.
TURN_DONE = 0.03


@dataclass
class Measure:
    """What the plant measured (updated every physics step)."""

    min_distance: float = math.inf  # smallest centre distance of any pair (m)
    min_margin: float = math.inf  # smallest (distance - required clearance) (m)
    min_pair: tuple[int, int] = (-1, -1)
    min_time: float = 0.0
    contacts: int = 0  # physics steps with a robot-robot contact
    contact_pairs: set[tuple[int, int]] = field(default_factory=set)
    steps: int = 0


class MujocoPlant:
    """Robots of ``models`` in one MuJoCo world, starting at ``starts`` (metres).

    Implements :class:`hierplan_opt.execution.plant.Plant` (``time``, ``positions``,
    ``assign``, ``release``, ``retime``, ``reached``, ``stop``, ``step``).

    Parameters
    ----------
    models : sequence of RobotModel
    starts : (n, 3) array
        Start positions in metres (z = 0 on 2D maps).
    headings : (n,) array, optional
        Start headings (rad) of ground robots.
    names : sequence of str, optional
        Robot names (disturbances name robots).
    disturbances : sequence of physical disturbances (:mod:`.disturbances`)
    clearance : (n, n) array, optional
        Required centre distance of every pair (default: sum of radii).
    seed : int
        Seeds ``noise`` and :class:`~.disturbances.RandomStops`.
    noise : float
        Standard deviation (m) of the position measurement the controllers see.
    timestep, control_period : float
        Physics step (default 5 ms, 2 ms with quadcopters) and control period (20 ms).
    still_speed : float
        A robot slower than this (m/s) counts as standing still for the execution
        monitor (a held robot's position hold creeps onto its way-point for seconds at
        ever smaller speeds; a re-plan or a halt must not wait for the creep to end).

    Example
    -------
    >>> import numpy as np
    >>> from hierplan_opt.core.instance import Kinematics
    >>> from hierplan_opt.physics.models import robot_model
    >>> m = robot_model(Kinematics("y", v_max=0.8, a_max=1.0, radius=0.35), dim=2)
    >>> p = MujocoPlant([m], np.zeros((1, 3)))
    >>> p.assign(0, np.array([[1.0, 0, 0]]), np.array([2.0]))
    >>> p.release(0, 0)
    >>> p.step(4.0)
    >>> p.reached(0), bool(abs(p.positions()[0, 0] - 1.0) < 0.05)
    (0, True)
    """

    def __init__(
        self,
        models: Sequence[RobotModel],
        starts: np.ndarray,
        headings: np.ndarray | None = None,
        *,
        names: Sequence[str] | None = None,
        disturbances: Sequence[PhysicalDisturbance] = (),
        clearance: np.ndarray | None = None,
        seed: int = 0,
        noise: float = 0.0,
        timestep: float | None = None,
        control_period: float = 0.02,
        reach_tol: float = 0.05,
        early: float = 0.1,
        still_speed: float = 0.01,
    ) -> None:
        n = len(models)
        self.n = n
        self.names = tuple(names) if names is not None else tuple(f"r{i}" for i in range(n))
        index = {nm: i for i, nm in enumerate(self.names)}
        starts = np.asarray(starts, dtype=float).reshape(n, 3)
        headings = np.zeros(n) if headings is None else np.asarray(headings, float).reshape(n)
        # Disturbances fixed at construction: payload and weak motors change the models.
        force_factor = np.ones(n)
        payload = np.zeros(n)
        self.spills: list[Spill] = []
        self.winds: list[tuple[Wind, np.ndarray]] = []
        self.stops: list[tuple[int, RobotStop]] = []
        self.randoms: list[tuple[RandomStops, np.random.Generator]] = []
        for d in disturbances:
            if isinstance(d, (Payload, WeakMotor, RobotStop)) and d.agent not in index:
                raise KeyError(f"physical disturbance names robot {d.agent!r}, not in the run")
            if isinstance(d, Payload):
                payload[index[d.agent]] += d.mass
            elif isinstance(d, WeakMotor):
                force_factor[index[d.agent]] *= d.factor
            elif isinstance(d, Spill):
                self.spills.append(d)
            elif isinstance(d, Wind):
                mask = np.ones(n, dtype=bool)
                if d.agents is not None:
                    mask[:] = False
                    for a in d.agents:
                        mask[index[a]] = True
                self.winds.append((d, mask))
            elif isinstance(d, RobotStop):
                self.stops.append((index[d.agent], d))
            elif isinstance(d, RandomStops):
                # Its own seed if it gives one, else the plant's.
                key = d.seed if d.seed is not None else [seed, 1, len(self.randoms)]
                self.randoms.append((d, np.random.default_rng(key)))
        self.models = list(models)
        self.kind = np.array([m.kind for m in models])
        self.is_quad = self.kind == "quad"
        self.is_diff = self.kind == "diff"
        self.is_omni = self.kind == "omni"
        self.ground = ~self.is_quad
        self.radius = np.array([m.radius for m in models])
        # Quadcopters aim 10 % below v_max: their attitude loop lags the velocity
        # reference by ~0.1 s and overshoots it by about a_max x 0.05 s (ours).
        self.v_max = np.array([m.v_max * (0.9 if m.kind == "quad" else 1.0) for m in models])
        self.a_max = np.array([m.a_max for m in models])
        self.omega_max = np.array([m.omega_max for m in models])
        self.mass = np.array([m.mass for m in models]) + payload
        self.force_max = np.array([m.force_max for m in models]) * force_factor
        self.torque_max = np.array([m.torque_max for m in models]) * force_factor
        self.track = np.array([m.track for m in models])
        self.clearance = (
            self.radius[:, None] + self.radius[None, :] if clearance is None else clearance
        )
        if timestep is None:
            timestep = 0.002 if self.is_quad.any() else 0.01
        self.timestep = float(timestep)
        self.control_every = max(1, round(control_period / self.timestep))
        self.control_period = self.control_every * self.timestep
        self.reach_tol = reach_tol
        self.early = early
        self.still_speed = float(still_speed)
        self.noise = noise
        self.rng = np.random.default_rng(seed)
        self.z0 = np.where(self.is_quad, 0.0, 0.5 * CHASSIS_HEIGHT)
        self._build(starts, headings)
        # Routes and progress.
        self.routes: list[np.ndarray] = [np.zeros((0, 3)) for _ in range(n)]
        self.times: list[np.ndarray] = [np.zeros(0) for _ in range(n)]
        self.gate = np.full(n, -1, dtype=np.int64)
        self._reached = np.full(n, -1, dtype=np.int64)
        self.broken = np.zeros(n, dtype=bool)
        self.pause_until = np.zeros(n)
        self.hold = starts.copy()  # where a robot with nothing to drive to stays
        self.reach_log: list[list[tuple[int, float]]] = [[] for _ in range(n)]
        # Per robot: current target B, its time, the next stop point S and the path
        # length B -> S, whether B is a stop, the direction after B (for turning).
        self.B = starts.copy()
        self.A = starts.copy()
        self.tB = np.zeros(n)
        self.S = starts.copy()
        self.dBS = np.zeros(n)
        self.active = np.zeros(n, dtype=bool)  # has a released way-point to drive to
        self.B_stop = np.ones(n, dtype=bool)
        self.next_dir = np.zeros((n, 3))
        self.next_dir[:, 0] = np.cos(headings)
        self.next_dir[:, 1] = np.sin(headings)
        self.v_cmd = np.zeros(n)  # commanded along-path speed (ramp-limited)
        self.turning = np.zeros(n, dtype=bool)
        self.time = 0.0
        #: Per robot: when each disturbance kind last acted on it (``spill``, ``stop``,
        #: ``random``, ``breakdown``, ``wind``): the monitor names the cause of a delay.
        self.causes: list[dict[str, float]] = [{} for _ in range(n)]
        self.measure = Measure()
        self.samples_t: list[float] = []
        self.samples_p: list[np.ndarray] = []
        self.samples_v: list[np.ndarray] = []
        self._sample()

    # ------------------------------------------------------------------ world
    def _build(self, starts: np.ndarray, headings: np.ndarray) -> None:
        parts = [
            '<mujoco model="hierplan"><compiler angle="radian"/>',
            f'<option timestep="{self.timestep}" integrator="implicitfast" gravity="0 0 -9.81">'
            '<flag energy="disable"/></option>',
            '<default><geom contype="1" conaffinity="1" condim="1" friction="0 0 0"/></default>',
            "<worldbody>",
        ]
        acts = ["<actuator>"]
        for i, m in enumerate(self.models):
            x, y, z = starts[i]
            if m.kind == "quad":
                ix, iy, iz = m.inertia
                parts.append(
                    f'<body name="b{i}" pos="{x} {y} {z}"><freejoint name="j{i}"/>'
                    f'<inertial pos="0 0 0" mass="{self.mass[i]}" diaginertia="{ix} {iy} {iz}"/>'
                    f'<geom type="sphere" size="{m.radius}" mass="0" density="0"/>'
                    f'<site name="s{i}c"/></body>'
                )
                f = self.force_max[i]
                tq = self.torque_max[i]
                acts.append(
                    f'<general site="s{i}c" gear="0 0 1 0 0 0" ctrlrange="0 {f}" '
                    'ctrllimited="true"/>'
                )
                for ax in ("1 0 0", "0 1 0", "0 0 1"):
                    acts.append(
                        f'<general site="s{i}c" gear="0 0 0 {ax}" ctrlrange="{-tq} {tq}" '
                        'ctrllimited="true"/>'
                    )
                continue
            h = 0.5 * CHASSIS_HEIGHT
            damp = ROLLING_DAMPING * self.mass[i]
            parts.append(
                f'<body name="b{i}" pos="0 0 {h}">'
                f'<joint name="j{i}x" type="slide" axis="1 0 0" damping="{damp}"/>'
                f'<joint name="j{i}y" type="slide" axis="0 1 0" damping="{damp}"/>'
                f'<joint name="j{i}t" type="hinge" axis="0 0 1" damping="{0.1 * damp}"/>'
                f'<geom type="cylinder" size="{m.radius} {h}" mass="{self.mass[i]}"/>'
                f'<site name="s{i}c"/>'
            )
            vlim = 1.2 * m.v_max
            if m.kind == "diff":
                half = 0.5 * m.track
                parts.append(
                    f'<site name="s{i}l" pos="0 {half} 0"/><site name="s{i}r" pos="0 {-half} 0"/>'
                )
                kv = 20.0 * self.mass[i]
                wl = vlim + m.omega_max * half
                for side in ("l", "r"):
                    acts.append(
                        f'<velocity site="s{i}{side}" gear="1 0 0 0 0 0" kv="{kv}" '
                        f'ctrlrange="{-wl} {wl}" forcelimited="true" forcerange="-1 1"/>'
                    )
                acts.append(
                    f'<velocity site="s{i}c" gear="0 1 0 0 0 0" kv="{4 * kv}" '
                    'ctrlrange="-1 1" forcelimited="true" forcerange="-1 1"/>'
                )
            else:
                kv = 20.0 * self.mass[i]
                for ax in ("x", "y"):
                    acts.append(
                        f'<velocity joint="j{i}{ax}" kv="{kv}" ctrlrange="{-vlim} {vlim}" '
                        'forcelimited="true" forcerange="-1 1"/>'
                    )
                inertia = 0.5 * self.mass[i] * m.radius**2
                acts.append(
                    f'<velocity joint="j{i}t" kv="{20.0 * inertia}" '
                    f'ctrlrange="{-1.2 * m.omega_max} {1.2 * m.omega_max}" forcelimited="true" '
                    f'forcerange="{-self.torque_max[i]} {self.torque_max[i]}"/>'
                )
            parts.append("</body>")
        parts.append("</worldbody>")
        acts.append("</actuator>")
        xml = "".join(parts) + ("".join(acts) if len(acts) > 2 else "") + "</mujoco>"
        self.model = mujoco.MjModel.from_xml_string(xml)
        self.data = mujoco.MjData(self.model)
        m = self.model
        n = self.n
        # Addresses.
        self.body = np.array([m.body(f"b{i}").id for i in range(n)])
        self.geom_robot = np.full(m.ngeom, -1, dtype=np.int64)
        for i in range(n):
            self.geom_robot[m.geom_bodyid == self.body[i]] = i
        qadr = np.zeros((n, 3), dtype=np.int64)
        dadr = np.zeros((n, 3), dtype=np.int64)
        self.act = np.zeros((n, 4), dtype=np.int64)
        a = 0
        for i, mod in enumerate(self.models):
            if mod.kind == "quad":
                jq = m.jnt_qposadr[m.joint(f"j{i}").id]
                jd = m.jnt_dofadr[m.joint(f"j{i}").id]
                qadr[i] = (jq, jq + 1, jq + 2)
                dadr[i] = (jd, jd + 1, jd + 2)
                self.act[i] = (a, a + 1, a + 2, a + 3)
                a += 4
            else:
                for k, ax in enumerate(("x", "y", "t")):
                    jid = m.joint(f"j{i}{ax}").id
                    qadr[i, k] = m.jnt_qposadr[jid]
                    dadr[i, k] = m.jnt_dofadr[jid]
                self.act[i] = (a, a + 1, a + 2, a + 2)
                a += 3
        self.qadr = qadr
        self.dadr = dadr
        for i in np.flatnonzero(self.ground).tolist():
            self.data.qpos[qadr[i]] = (starts[i, 0], starts[i, 1], headings[i])
        mujoco.mj_forward(m, self.data)
        self.yaw0 = headings.copy()
        self.quads = np.flatnonzero(self.is_quad)
        self.diffs = np.flatnonzero(self.is_diff)
        self.omnis = np.flatnonzero(self.is_omni)
        self.grip_share = np.where(self.is_omni, 0.3, np.where(self.is_quad, np.inf, 1.0))
        self.noise_axes = np.where(self.is_quad, 1.0, 0.0)[:, None] * np.array(
            [0, 0, 1.0]
        ) + np.array([1.0, 1.0, 0])
        self.quad_ref = np.zeros((len(self.quads), 3))
        self.quad_ff = np.zeros((len(self.quads), 3))
        self.holonomic = np.flatnonzero(~self.is_diff)
        self.v_vec = np.zeros((n, 3))
        self.grounds = np.flatnonzero(self.ground)
        self.quad_q = np.array(
            [m.jnt_qposadr[m.joint(f"j{i}").id] for i in self.quads], dtype=np.int64
        )
        self.quad_d = np.array(
            [m.jnt_dofadr[m.joint(f"j{i}").id] for i in self.quads], dtype=np.int64
        )
        self.vel_int = np.zeros((len(self.quads), 3))
        self.mu = np.full(n, MU_FLOOR)
        self._set_force_limits()
        self.zmask = self.is_quad.astype(float)
        iu = np.triu_indices(n, 1)
        self.pair_i, self.pair_j = iu
        self.pair_req = self.clearance[iu] if n > 1 else np.zeros(0)
        self.near_i, self.near_j, self.near_req = self.pair_i, self.pair_j, self.pair_req

    def _set_force_limits(self) -> None:
        """Motor force limits of ground robots: motor force and the floor's grip."""
        fr = self.model.actuator_forcerange
        for i in self.grounds.tolist():
            grip = traction(self.models[i], float(self.mu[i])) * self.mass[i] / self.models[i].mass
            a = self.act[i]
            if self.is_diff[i]:
                f = min(self.force_max[i], 0.5 * grip)
                fr[a[0]] = (-f, f)
                fr[a[1]] = (-f, f)
                fr[a[2]] = (-grip, grip)
            else:
                f = min(self.force_max[i], grip / math.sqrt(2))
                fr[a[0]] = (-f, f)
                fr[a[1]] = (-f, f)

    # ------------------------------------------------------------------ state
    def positions(self) -> np.ndarray:
        """(n, 3) positions in metres (the physics state; ground robots at z = 0)."""
        p = self.data.qpos[self.qadr]
        p[:, 2] *= self.zmask
        return p

    def velocities(self) -> np.ndarray:
        """(n, 3) linear velocities (m/s, world frame)."""
        v = self.data.qvel[self.dadr].copy()
        v[self.grounds, 2] = 0.0
        return v

    def headings(self) -> np.ndarray:
        """(n,) yaw of ground robots (rad); quadcopters: 0."""
        out = np.zeros(self.n)
        g = self.grounds
        out[g] = _wrap(self.data.qpos[self.qadr[g, 2]])
        return out

    # ------------------------------------------------------------------ protocol
    def assign(self, robot: int, waypoints: np.ndarray, times: np.ndarray) -> None:
        wp = np.asarray(waypoints, dtype=float).reshape(-1, 3)
        tt = np.asarray(times, dtype=float).reshape(-1)
        if len(wp) != len(tt):
            raise ValueError(f"robot {robot}: {len(wp)} way-points but {len(tt)} times")
        self.routes[robot] = wp
        self.times[robot] = tt
        self.gate[robot] = -1
        self._reached[robot] = -1
        self.hold[robot] = self.positions()[robot]
        self._refresh(robot)

    def release(self, robot: int, gate: int) -> None:
        self.gate[robot] = min(int(gate), len(self.routes[robot]) - 1)
        self._refresh(robot)

    def retime(self, robot: int, times: np.ndarray) -> None:
        tt = np.asarray(times, dtype=float).reshape(-1)
        if len(tt) != len(self.routes[robot]):
            raise ValueError(
                f"robot {robot}: retime with {len(tt)} times for "
                f"{len(self.routes[robot])} way-points"
            )
        self.times[robot] = tt
        self._refresh(robot)

    def reached(self, robot: int) -> int:
        return int(self._reached[robot])

    def stop(self, robot: int) -> None:
        self.broken[robot] = True
        self.causes[robot]["breakdown"] = self.time
        self.hold[robot] = self.positions()[robot]
        self._refresh(robot)

    def step(self, dt: float) -> None:
        n_steps = max(0, round(dt / self.timestep))
        for _ in range(n_steps):
            k = self.measure.steps
            if k % self.control_every == 0:
                self._control()
            if len(self.quads):
                self._quad_control()
            mujoco.mj_step(self.model, self.data)
            self.time += self.timestep
            self.measure.steps += 1
            self._measure()
            if (k + 1) % self.control_every == 0:
                self._sample()

    # ------------------------------------------------------------------ routes
    def _refresh(self, i: int) -> None:
        """Recompute robot i's target, stop point and flags from its route and gate."""
        wp = self.routes[i]
        k = int(self._reached[i]) + 1
        last = len(wp) - 1
        if self.broken[i] or k > min(int(self.gate[i]), last):
            self.active[i] = False
            self.B[i] = self.hold[i]
            self.S[i] = self.hold[i]
            self.dBS[i] = 0.0
            self.B_stop[i] = True
            self.tB[i] = self.time
            # A robot held with a route ahead turns towards it while it waits.
            if not self.broken[i] and k <= last:
                d = _first_dir(wp, k, self.hold[i])
                if d is not None:
                    self.next_dir[i] = d
            return
        self.active[i] = True
        self.A[i] = wp[k - 1] if k > 0 else self.hold[i]
        self.B[i] = wp[k]
        self.tB[i] = self.times[i][k]
        stop_at = min(int(self.gate[i]), last)
        prev = self.A[i]
        length = 0.0
        s_idx = stop_at
        for m in range(k, stop_at + 1):
            seg = wp[m] - (prev if m == k else wp[m - 1])
            if m > k:
                length += float(np.linalg.norm(seg))
            if m == stop_at:
                break
            # A corner (or a pause: the next way-point is later than straight driving
            # allows) is a stop point.
            d_in = wp[m] - (prev if m == k else wp[m - 1])
            d_out = wp[m + 1] - wp[m]
            if _corner(d_in, d_out):
                s_idx = m
                break
        self.S[i] = wp[s_idx]
        self.dBS[i] = length if s_idx > k else 0.0
        self.B_stop[i] = s_idx == k
        d = _first_dir(wp, k + 1, wp[k]) if k < last else None
        if d is not None:
            self.next_dir[i] = d

    def _advance(self, p: np.ndarray) -> None:
        """Mark way-points reached (vectorised test; a loop over robots that reached)."""
        act = self.active
        if not act.any():
            return
        diff = self.B - p
        dist = np.linalg.norm(diff, axis=1)
        # A pass-through way-point counts once the robot is past it along its segment.
        seg = self.B - self.A
        seglen = np.linalg.norm(seg, axis=1)
        along = np.einsum("ij,ij->i", p - self.A, seg) / np.maximum(seglen, 1e-12)
        passed = (~self.B_stop) & (seglen > 1e-9) & (along >= seglen) & (dist < 4 * self.reach_tol)
        close = (dist < self.reach_tol) & (self.time >= self.tB - self.early)
        ok = act & (close | passed)
        ok &= self.time >= self.pause_until
        for i in np.flatnonzero(ok).tolist():
            while True:
                self._reached[i] += 1
                k = int(self._reached[i])
                self.reach_log[i].append((k, self.time))
                self.hold[i] = self.routes[i][k]
                for r, rng in self.randoms:
                    if rng.random() < r.probability:
                        self.pause_until[i] = self.time + float(r.delays.draw(rng))
                        self.causes[i]["random"] = self.time
                self._refresh(i)
                if not self.active[i] or self.time < self.pause_until[i]:
                    break
                # Several way-points at the same place (and time) at once.
                if (
                    np.linalg.norm(self.B[i] - p[i]) >= self.reach_tol
                    or self.time < self.tB[i] - self.early
                ):
                    break

    # ------------------------------------------------------------------ control
    def _disturb(self) -> None:
        t = self.time
        for i, d in self.stops:
            if d.at_time <= t and not self.broken[i]:
                if d.duration is None:
                    self.stop(i)
                elif t < d.at_time + d.duration:
                    self.pause_until[i] = max(self.pause_until[i], d.at_time + d.duration)
                    self.causes[i]["stop"] = t
        if self.spills:
            p = self.positions()
            mu = np.full(self.n, MU_FLOOR)
            for s in self.spills:
                if not s.start <= t < s.end:
                    continue
                for x0, y0, x1, y1 in s.boxes:
                    inside = (p[:, 0] >= x0) & (p[:, 0] <= x1) & (p[:, 1] >= y0) & (p[:, 1] <= y1)
                    mu = np.where(inside, np.minimum(mu, s.friction), mu)
            for i in np.flatnonzero(mu < MU_FLOOR).tolist():
                self.causes[i]["spill"] = t
            if not np.array_equal(mu, self.mu):
                self.mu = mu
                self._set_force_limits()
        xf = self.data.xfrc_applied
        xf[self.body, :3] = 0.0
        if self.winds:
            v = self.velocities()
            area = np.where(self.is_quad, DRAG_AREA_QUAD, DRAG_AREA_GROUND_PER_M * 2 * self.radius)
            for w, mask in self.winds:
                if not w.start <= t < w.end:
                    continue
                rel = np.asarray(w.velocity)[None, :] - v
                f = 0.5 * RHO_AIR * area[:, None] * np.linalg.norm(rel, axis=1)[:, None] * rel
                f[self.grounds, 2] = 0.0
                xf[self.body[mask], :3] += f[mask]
                for i in np.flatnonzero(mask).tolist():
                    self.causes[i]["wind"] = t

    def _control(self) -> None:
        """Ground robots' path following (and the quadcopters' velocity references)."""
        self._disturb()
        p = self.positions()
        if self.noise > 0:
            p = p + self.rng.normal(0.0, self.noise, p.shape) * self.noise_axes
        self._advance(p)
        t = self.time
        # Acceleration the controller uses: a_max, less where the floor is slippery
        # (the robot senses its wheels slip).
        grip = self.grip_share * self.mu * self.mass * 9.81
        a_c = np.minimum(self.a_max, 0.5 * grip / self.mass)
        to_B = self.B - p
        dB = np.linalg.norm(to_B, axis=1)
        dS = np.where(self.B_stop, dB, dB + self.dBS)
        ttg = self.tB - t
        v_ttg = np.where(ttg > self.control_period, dB / np.maximum(ttg, 1e-9), np.inf)
        v_des = np.minimum.reduce([self.v_max, v_ttg, np.sqrt(2 * 0.9 * a_c * dS)])
        paused = (~self.active) | self.broken | (t < self.pause_until)
        v_des = np.where(paused, 0.0, v_des)
        step_a = a_c * self.control_period
        move_dir = to_B / np.maximum(dB, 1e-12)[:, None]
        hold_err = self.hold - p
        ctrl = self.data.ctrl
        d = self.is_diff
        if len(self.diffs):
            # Differential drives: face the next way-point (inside the reach tolerance,
            # or held: the next move), turn in place before driving.
            far = (dB > self.reach_tol) & self.active
            face = np.where(far[:, None], move_dir, self.next_dir)
            yaw = self.headings()
            err = _wrap(np.arctan2(face[:, 1], face[:, 0]) - yaw)
            speed = np.linalg.norm(self.velocities(), axis=1)
            start_turn = d & (np.abs(err) > TURN_IN_PLACE) & (speed < 0.05) & ~self.broken
            self.turning = (self.turning | start_turn) & (np.abs(err) > TURN_DONE) & d
            # Moving with a large heading error: brake first.
            v_des = np.where(d & (self.turning | (np.abs(err) > TURN_IN_PLACE)), 0.0, v_des)
            # Held: creep onto the held point along the heading (no turning for it).
            heading = np.stack([np.cos(yaw), np.sin(yaw)], axis=1)
            creep = np.clip(np.einsum("ij,ij->i", hold_err[:, :2], heading), -0.1, 0.1)
            v_des = np.where(d & paused & ~self.broken, creep, v_des)
            v_new = np.clip(v_des, self.v_cmd - step_a, self.v_cmd + step_a)
            v_new = np.where(self.broken, 0.0, v_new)
            self.v_cmd = np.where(d, v_new, self.v_cmd)
            om = np.sign(err) * np.minimum.reduce(
                [self.omega_max, np.sqrt(2 * 2.0 * self.omega_max * np.abs(err)), 3.0 * np.abs(err)]
            )
            om = np.where(self.broken, 0.0, om)
            di = self.diffs
            v = v_new[di] * np.maximum(np.cos(err[di]), 0.0)
            half = 0.5 * self.track[di]
            ctrl[self.act[di, 0]] = v - om[di] * half
            ctrl[self.act[di, 1]] = v + om[di] * half
            ctrl[self.act[di, 2]] = 0.0
        h = self.holonomic
        if len(h):
            # Omni and quadcopters: a velocity vector, changed at most a_c per second.
            want = v_des[h, None] * move_dir[h]
            hold = paused[h] & ~self.broken[h]
            want = want + np.where(hold[:, None], 1.5 * hold_err[h], 0.0)
            dv = want - self.v_vec[h]
            nrm = np.linalg.norm(dv, axis=1)
            dv *= np.minimum(1.0, step_a[h] / np.maximum(nrm, 1e-12))[:, None]
            vec = self.v_vec[h] + dv
            vec[self.broken[h]] = 0.0
            self.v_vec[h] = vec
        if len(self.omnis):
            oi = self.omnis
            vel = self.v_vec[oi]
            ctrl[self.act[oi, 0]] = vel[:, 0]
            ctrl[self.act[oi, 1]] = vel[:, 1]
            yaw_o = self.data.qpos[self.qadr[oi, 2]]
            ctrl[self.act[oi, 2]] = np.clip(
                -3.0 * _wrap(yaw_o - self.yaw0[oi]), -self.omega_max[oi], self.omega_max[oi]
            )
        if len(self.quads):
            q = self.quads
            self.quad_ff = (self.v_vec[q] - self.quad_ref) / self.control_period
            self.quad_ref = self.v_vec[q].copy()

    def _quad_control(self) -> None:
        """Quadcopters: velocity -> acceleration -> thrust direction -> attitude
        (geometric controller on SO(3), T. Lee et al., CDC 2010), every physics step."""
        d = self.data
        q = self.quads
        qa = self.quad_q
        da = self.quad_d
        ref = self.quad_ref
        v = d.qvel[da[:, None] + np.arange(3)]
        w = d.qvel[da[:, None] + np.arange(3, 6)]  # body frame
        quat = d.qpos[qa[:, None] + np.arange(3, 7)]
        R = _quat_to_mat(quat)
        err = ref - v
        # Integral only vertically (payload, thrust loss): no horizontal windup.
        self.vel_int[:, 2] = np.clip(self.vel_int[:, 2] + err[:, 2] * self.timestep, -2.0, 2.0)
        a_max = self.a_max[q][:, None]
        acc = self.quad_ff + 4.0 * err + 2.0 * self.vel_int
        norm = np.linalg.norm(acc, axis=1, keepdims=True)
        acc = acc * np.minimum(1.0, a_max / np.maximum(norm, 1e-12))
        m_nom = np.array([self.models[i].mass for i in q])[:, None]
        F = m_nom * (acc + np.array([0, 0, 9.81]))
        b3d = F / np.linalg.norm(F, axis=1, keepdims=True)
        b1c = np.broadcast_to(np.array([1.0, 0, 0]), b3d.shape)
        b2d = np.cross(b3d, b1c)
        b2d /= np.linalg.norm(b2d, axis=1, keepdims=True)
        b1d = np.cross(b2d, b3d)
        Rd = np.stack([b1d, b2d, b3d], axis=2)
        E = np.einsum("nji,njk->nik", Rd, R) - np.einsum("nji,njk->nik", R, Rd)
        eR = 0.5 * np.stack([E[:, 2, 1], E[:, 0, 2], E[:, 1, 0]], axis=1)
        inertia = np.array([self.models[i].inertia for i in q])
        wn, zeta = 25.0, 0.9
        tau = -inertia * wn * wn * eR - inertia * 2 * zeta * wn * w
        thrust = np.einsum("ni,ni->n", F, R[:, :, 2])
        ctrl = d.ctrl
        act = self.act[q]
        ctrl[act[:, 0]] = np.where(self.broken[q], 0.0, thrust)
        for k in range(3):
            ctrl[act[:, 1 + k]] = tau[:, k]

    # ------------------------------------------------------------------ measure
    def _measure(self) -> None:
        """Distances of every pair (at control steps all pairs; in between the pairs
        that were within ``NEAR`` metres of their clearance or of the closest pair,
        which no other pair can undercut within one control period) and contacts."""
        p = self.positions()
        me = self.measure
        if self.n > 1:
            full = me.steps % self.control_every == 1 or self.control_every == 1
            if full:
                ii, jj, req = self.pair_i, self.pair_j, self.pair_req
            else:
                ii, jj, req = self.near_i, self.near_j, self.near_req
            if len(ii):
                diff = p[ii] - p[jj]
                dist = np.sqrt(np.einsum("ij,ij->i", diff, diff))
                margin = dist - req
                k = int(np.argmin(margin))
                if margin[k] < me.min_margin:
                    me.min_margin = float(margin[k])
                    me.min_pair = (int(ii[k]), int(jj[k]))
                    me.min_time = self.time
                dmin = float(dist.min())
                me.min_distance = min(me.min_distance, dmin)
                if full:
                    near = (margin < margin[k] + NEAR) | (dist < dmin + NEAR)
                    self.near_i, self.near_j, self.near_req = ii[near], jj[near], req[near]
        ncon = self.data.ncon
        if ncon:
            con = self.data.contact
            g1 = self.geom_robot[con.geom1[:ncon]]
            g2 = self.geom_robot[con.geom2[:ncon]]
            real = (g1 >= 0) & (g2 >= 0) & (g1 != g2) & (con.dist[:ncon] < 0)
            if real.any():
                me.contacts += 1
                for a, b in zip(g1[real].tolist(), g2[real].tolist(), strict=True):
                    me.contact_pairs.add((min(a, b), max(a, b)))

    def _sample(self) -> None:
        self.samples_t.append(self.time)
        self.samples_p.append(self.positions())
        self.samples_v.append(self.velocities())

    def cause(self, robot: int, window: float = 5.0) -> str:
        """The disturbance that acted on ``robot`` last within ``window`` seconds
        (``""``: none)."""
        recent = [(t, k) for k, t in self.causes[robot].items() if self.time - t <= window]
        return max(recent)[1] if recent else ""

    @property
    def samples(self) -> tuple[np.ndarray, np.ndarray]:
        """``(times (T,), positions (T, n, 3))`` recorded every control period."""
        return np.array(self.samples_t), np.array(self.samples_p)


# ---------------------------------------------------------------------- helpers
def _wrap(a: np.ndarray) -> np.ndarray:
    return (a + np.pi) % (2 * np.pi) - np.pi


def _corner(d_in: np.ndarray, d_out: np.ndarray) -> bool:
    """Whether the route turns (more than ~1 degree) or pauses between two moves."""
    a = float(np.linalg.norm(d_in))
    b = float(np.linalg.norm(d_out))
    if a < 1e-9 or b < 1e-9:
        return True
    return float(d_in @ d_out) / (a * b) < math.cos(math.radians(1.0))


def _first_dir(wp: np.ndarray, k: int, here: np.ndarray) -> np.ndarray | None:
    """Unit direction of the first non-zero move from ``here`` through ``wp[k:]``."""
    prev = here
    for m in range(k, len(wp)):
        d = wp[m] - prev
        ln = float(np.linalg.norm(d[:2]))
        if ln > 1e-9:
            return d / float(np.linalg.norm(d))
        prev = wp[m]
    return None


def _quat_to_mat(q: np.ndarray) -> np.ndarray:
    """(n, 4) MuJoCo quaternions (w, x, y, z) -> (n, 3, 3) rotation matrices."""
    w, x, y, z = q[:, 0], q[:, 1], q[:, 2], q[:, 3]
    return np.stack(
        [
            np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)], 1),
            np.stack([2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)], 1),
            np.stack([2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)], 1),
        ],
        axis=1,
    )
