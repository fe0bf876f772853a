"""Run a schedule in MuJoCo physics and measure it.

:func:`make_plant` builds a :class:`~.plant.MujocoPlant` for an instance's robots at a
schedule's start way-points; :func:`follow` executes a schedule on it with the temporal
plan graph's gates (a robot holds before a way-point whose Type-2 predecessors have not
happened: the slack layer, nothing re-computed) and returns a :class:`PhysicsRun`: the
measured distances and contacts, each robot's arrival at each way-point against the
schedule, its tracking error and the real-time factor. The closed loop with the whole
execution hierarchy runs through the execution monitor (``simulate(...,
mode="physics")``), which drives the same plant.
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from hierplan_opt.core.instance import Instance
from hierplan_opt.io.values import plain
from hierplan_opt.physics.disturbances import PhysicalDisturbance, from_execution
from hierplan_opt.physics.models import robot_model
from hierplan_opt.physics.plant import MujocoPlant
from hierplan_opt.schedule.output import Schedule

log = logging.getLogger(__name__)

#: Agreement tolerances (seconds) of a robot's arrival at each way-point against the
#: schedule without disturbances, per robot type of the agreement test and bench (a
#: 4-robot swap, a 3-robot 3D swap). At pass-through way-points the schedule's piecewise
#: constant speeds can ask for speed changes beyond a_max (a Pioneer at 0.3 m/s^2 cannot
#: drop from 0.6 to 0.15 m/s within 0.2 m), so it arrives early there; at the goals the
#: arrival is within ``GOAL_TOL``.
AGREEMENT = {"youbot": 0.6, "pioneer": 1.5, "create2": 1.0, "quad": 0.6}
GOAL_TOL = 0.6


def waypoints_m(schedule: Schedule, robot: int) -> np.ndarray:
    """Robot's way-points in metres, shape (k, 3) (z = 0 on 2D maps)."""
    c = np.asarray(schedule.waypoints[robot].coords, dtype=float) * float(schedule.scale)
    out = np.zeros((len(c), 3))
    out[:, : c.shape[1]] = c
    return out


def make_plant(
    instance: Instance,
    schedule: Schedule,
    disturbances: Sequence[Any] = (),
    *,
    seed: int = 0,
    monitor: bool = False,
    **options: Any,
) -> MujocoPlant:
    """A plant with one robot per schedule robot (models from the instance's robot
    types; speeds and accelerations times the map's cell size), at its first way-point
    facing its first move; execution disturbances are turned into physical ones
    (:func:`~.disturbances.from_execution`). ``monitor``: the execution monitor imposes
    stops, breakdowns and random delays itself, the plant only the physical ones.

    Example
    -------
    >>> from hierplan_opt.core.graph import Graph
    >>> from hierplan_opt.core.instance import Kinematics
    >>> from hierplan_opt.api import solve
    >>> from hierplan_opt.schedule.post import postprocess
    >>> g = Graph.grid(4, 1)
    >>> inst = Instance.mapf(g, [(0, 0)], [(3, 0)],
    ...                      kinematics=Kinematics("y", v_max=0.8, a_max=1.0, radius=0.3))
    >>> sched = postprocess(inst, solve(inst, "cbs").plan)
    >>> make_plant(inst, sched).positions().round(2).tolist()
    [[0.0, 0.0, 0.0]]
    """
    dim = schedule.dim
    names = schedule.agent_names
    by_name = {a.name: a for a in instance.agents}
    kins = [by_name[n].kinematics if n in by_name else instance.agents[i].kinematics
            for i, n in enumerate(names)]  # fmt: skip
    scale = float(schedule.scale)
    kins = [
        replace(k, v_max=k.v_max * scale, a_max=k.a_max * scale if k.a_max else None) for k in kins
    ]
    models = [robot_model(k, dim) for k in kins]
    starts = np.array([waypoints_m(schedule, i)[0] for i in range(len(names))]).reshape(-1, 3)
    headings = np.array(
        [float(schedule.waypoints[i].theta[0]) if len(schedule.waypoints[i]) else 0.0
         for i in range(len(names))]
    )  # fmt: skip
    radius = np.array([m.radius for m in models])
    clearance = radius[:, None] + radius[None, :] + float(schedule.margin)
    if monitor:
        disturbances = [
            d for d in disturbances if type(d).__name__ not in ("Stop", "Breakdown", "RandomDelays")
        ]
    phys: list[PhysicalDisturbance] = from_execution(disturbances, scale)
    return MujocoPlant(
        models,
        starts,
        headings,
        names=names,
        disturbances=phys,
        clearance=clearance,
        seed=seed,
        **options,
    )


class Gates:
    """The TPG's Type-2 arcs on the schedule's way-points: how far each robot may go.

    ``gate(i, reached, reach_time, now)`` is the last way-point index robot ``i`` may
    drive to: the one before its first way-point that has a Type-2 predecessor (another
    robot's way-point plus a lower bound) not yet passed.
    """

    def __init__(self, schedule: Schedule) -> None:
        stn = schedule.stn
        K = schedule.num_agents
        self.preds: list[list[list[tuple[int, int, float]]]] = [
            [[] for _ in range(len(schedule.waypoints[i]))] for i in range(K)
        ]
        if stn is None:
            return
        nodes = []
        for i in range(K):
            nd = np.asarray(schedule.waypoints[i].node, dtype=np.int64)
            nodes.append(nd)
        agent = stn.tpg.node_agent
        src, dst = stn.arc_src, stn.arc_dst
        cross = np.flatnonzero(agent[src] != agent[dst])
        for k in cross.tolist():
            u, v = int(src[k]), int(dst[k])
            ru, rv = int(agent[u]), int(agent[v])
            iu = _index_at_or_after(nodes[ru], u)
            iv = _index_at_or_after(nodes[rv], v)
            if iv is None:
                continue
            if iu is None:
                iu = len(nodes[ru]) - 1
            self.preds[rv][iv].append((ru, iu, float(stn.lb[k])))

    def gate(self, i: int, reached: int, reach_times: Sequence[Sequence[float]], now: float) -> int:
        pre = self.preds[i]
        j = reached + 1
        while j < len(pre):
            for r, idx, lb in pre[j]:
                rt = reach_times[r]
                if idx >= len(rt) or rt[idx] + lb > now + 1e-9:
                    return j - 1
            j += 1
        return len(pre) - 1


def _index_at_or_after(nodes: np.ndarray, u: int) -> int | None:
    ok = np.flatnonzero((nodes >= 0) & (nodes >= u))
    return int(ok[0]) if len(ok) else None


@dataclass(frozen=True, eq=False)
class PhysicsRun:
    """A physics run of a schedule (read-only).

    ``reach`` per robot: the time it reached each of its way-points (NaN: never);
    ``planned``: the schedule's times; ``samples_t`` (T,), ``samples_p`` (T, n, 3): every
    robot's position at every control step; ``statistics``: see :func:`statistics`.
    """

    names: tuple[str, ...]
    reach: tuple[np.ndarray, ...]
    planned: tuple[np.ndarray, ...]
    samples_t: np.ndarray
    samples_p: np.ndarray
    statistics: dict[str, Any] = field(default_factory=dict)

    def report(self) -> dict[str, Any]:
        """Plain values (YAML)."""
        return {"statistics": plain(self.statistics, digits=6)}


def follow(
    instance: Instance,
    schedule: Schedule,
    disturbances: Sequence[Any] = (),
    *,
    seed: int = 0,
    dt: float = 0.1,
    horizon: float | None = None,
    plant: MujocoPlant | None = None,
    **options: Any,
) -> PhysicsRun:
    """Execute ``schedule`` in physics with the TPG's gates (no re-computation).

    Runs until every working robot reached its last way-point, or ``horizon``
    simulated seconds (default: 3 x makespan + 30 s).

    Example
    -------
    >>> from hierplan_opt.core.graph import Graph
    >>> from hierplan_opt.core.instance import Kinematics
    >>> from hierplan_opt.api import solve
    >>> from hierplan_opt.schedule.post import postprocess
    >>> g = Graph.grid(4, 1)
    >>> inst = Instance.mapf(g, [(0, 0)], [(3, 0)],
    ...                      kinematics=Kinematics("y", v_max=0.8, a_max=1.0, radius=0.3))
    >>> run = follow(inst, postprocess(inst, solve(inst, "cbs").plan))
    >>> run.statistics["finished"], run.statistics["contacts"]
    (1, 0)
    """
    wall0 = time.perf_counter()
    p = (
        plant
        if plant is not None
        else make_plant(instance, schedule, disturbances, seed=seed, **options)
    )
    K = schedule.num_agents
    gates = Gates(schedule)
    routes = [waypoints_m(schedule, i) for i in range(K)]
    planned = [np.asarray(schedule.waypoints[i].arrival, dtype=float) for i in range(K)]
    for i in range(K):
        p.assign(i, routes[i], planned[i])
    reach_times: list[list[float]] = [[] for _ in range(K)]
    if horizon is None:
        horizon = 3.0 * float(schedule.makespan) + 30.0
    last = [len(r) - 1 for r in routes]
    while p.time < horizon:
        for i in range(K):
            r = p.reached(i)
            while len(reach_times[i]) <= r:
                reach_times[i].append(p.time)
        for i in range(K):
            g = gates.gate(i, p.reached(i), reach_times, p.time)
            if g != p.gate[i]:
                p.release(i, g)
        done = all(p.reached(i) >= last[i] or p.broken[i] for i in range(K))
        if done:
            break
        p.step(dt)
    wall = time.perf_counter() - wall0
    reach = []
    for i in range(K):
        arr = np.full(len(routes[i]), np.nan)
        for k, t in p.reach_log[i]:
            if k < len(arr) and np.isnan(arr[k]):
                arr[k] = t
        reach.append(arr)
    st, sp = p.samples
    stats = statistics(p, schedule, reach, planned, st, sp, wall)
    return PhysicsRun(tuple(schedule.agent_names), tuple(reach), tuple(planned), st, sp, stats)


def scheduled_positions(schedule: Schedule, t: np.ndarray) -> np.ndarray:
    """(T, n, 3) where the schedule has every robot at times ``t`` (straight lines at
    constant speed between way-points, before the first: at the first)."""
    K = schedule.num_agents
    out = np.zeros((len(t), K, 3))
    for i in range(K):
        wp = waypoints_m(schedule, i)
        at = np.asarray(schedule.waypoints[i].arrival, dtype=float)
        # Repeated times (turns in place): np.interp needs increasing x; keep the last.
        for a in range(3):
            out[:, i, a] = np.interp(t, at, wp[:, a])
    return out


def statistics(
    plant: MujocoPlant,
    schedule: Schedule,
    reach: Sequence[np.ndarray],
    planned: Sequence[np.ndarray],
    samples_t: np.ndarray,
    samples_p: np.ndarray,
    wall: float,
) -> dict[str, Any]:
    """Measured statistics of a run: ``contacts`` (physics steps with a robot-robot
    contact), ``contact_pairs``, ``min_distance`` and ``min_margin`` (smallest distance
    minus the pair's required clearance; >= 0: kept), ``guaranteed_distance`` (the
    schedule's), ``finished`` / ``unfinished`` robots (broken ones excepted: ``broken``),
    ``makespan`` (last arrival), ``lateness_max`` (latest way-point against the
    schedule), ``tracking_error_max`` / ``tracking_error_rms`` and per robot
    ``tracking``, ``real_time_factor`` (simulated s per wall s), ``sim_time``, ``wall``,
    ``disturbed`` (robot -> the disturbance kinds that acted on it)."""
    K = len(reach)
    me = plant.measure
    finished = sum(1 for i in range(K) if len(reach[i]) and not np.isnan(reach[i][-1]))
    broken = int(plant.broken.sum())
    arrival = np.array([r[-1] if len(r) else np.nan for r in reach])
    late = [r - pl for r, pl in zip(reach, planned, strict=True)]
    late_all = np.concatenate([x[~np.isnan(x)] for x in late]) if K else np.zeros(0)
    sched_p = scheduled_positions(schedule, samples_t)
    err = np.linalg.norm(samples_p - sched_p, axis=2)  # (T, n)
    tracking = {
        plant.names[i]: {
            "max": float(err[:, i].max()) if len(err) else 0.0,
            "rms": float(np.sqrt(np.mean(err[:, i] ** 2))) if len(err) else 0.0,
        }
        for i in range(K)
    }
    sim = float(plant.time)
    return {
        "contacts": int(me.contacts),
        "contact_pairs": sorted([plant.names[a], plant.names[b]] for a, b in me.contact_pairs),
        "min_distance": float(me.min_distance),
        "min_margin": float(me.min_margin),
        "min_pair": [plant.names[x] for x in me.min_pair] if me.min_pair[0] >= 0 else [],
        "guaranteed_distance": float(schedule.safety_distance),
        "distance_kept": bool(me.min_margin >= -1e-9),
        "finished": int(finished),
        "unfinished": int(K - finished - broken),
        "broken": broken,
        "makespan": float(np.nanmax(arrival)) if finished else math.nan,
        "planned_makespan": float(schedule.makespan),
        "lateness_max": float(late_all.max()) if len(late_all) else 0.0,
        "earliness_max": float(max(0.0, -late_all.min())) if len(late_all) else 0.0,
        "tracking_error_max": float(err.max()) if err.size else 0.0,
        "tracking_error_rms": float(np.sqrt(np.mean(err**2))) if err.size else 0.0,
        "tracking": tracking,
        "sim_time": sim,
        "wall": float(wall),
        "real_time_factor": sim / wall if wall > 0 else math.inf,
        "physics_steps": int(me.steps),
        "disturbed": {plant.names[i]: sorted(plant.causes[i]) for i in range(K) if plant.causes[i]},
    }


#: A measured acceleration counts as a violation above ``a_max`` times ``1 + ACCEL_TOL``
#: (the engine's velocities differenced over one control period: the servos' lag).
ACCEL_TOL = 0.05


def type_a_max(instance: Instance, schedule: Schedule) -> np.ndarray:
    """Per schedule robot, the ``a_max`` of its robot type in m/s^2 (times the map's
    cell size); NaN for a type without one (the physics model then picks its own)."""
    by_name = {a.name: a for a in instance.agents}
    out = np.full(schedule.num_agents, np.nan)
    for i, n in enumerate(schedule.agent_names):
        k = by_name[n].kinematics if n in by_name else instance.agents[i].kinematics
        if k.a_max:
            out[i] = float(k.a_max) * float(schedule.scale)
    return out


def accelerations(plant: MujocoPlant, a_max: np.ndarray) -> dict[str, Any]:
    """The robots' accelerations measured from the engine's velocities (sampled every
    control period, differenced) against ``a_max`` (m/s^2 per robot; NaN: not checked):
    ``max_acceleration_ratio`` (largest |dv/dt| / a_max; NaN when no robot has an
    a_max), ``acceleration_violations`` (control periods, per robot, above
    ``a_max (1 + ACCEL_TOL)``), ``worst_acceleration`` (robot, time, measured m/s^2)
    when there is one, ``acceleration_checked`` (how many robots were checked)."""
    t = np.asarray(plant.samples_t, dtype=float)
    v = np.asarray(plant.samples_v, dtype=float).reshape(len(t), plant.n, 3)
    a_max = np.asarray(a_max, dtype=float).reshape(plant.n)
    checked = np.flatnonzero(np.isfinite(a_max) & (a_max > 0))
    out: dict[str, Any] = {
        "acceleration_checked": len(checked),
        "max_acceleration_ratio": math.nan,
        "acceleration_violations": 0,
    }
    if not len(checked):
        return out
    if len(t) < 2:
        out["max_acceleration_ratio"] = 0.0
        return out
    acc = np.linalg.norm(np.diff(v[:, checked], axis=0), axis=2) / np.diff(t)[:, None]
    ratio = acc / a_max[checked][None, :]
    out["max_acceleration_ratio"] = float(ratio.max())
    over = ratio > 1.0 + ACCEL_TOL
    out["acceleration_violations"] = int(over.sum())
    if over.any():
        k, c = np.unravel_index(int(np.argmax(ratio)), ratio.shape)
        out["worst_acceleration"] = {
            "agent": plant.names[int(checked[c])],
            "time": float(t[k + 1]),
            "measured": float(acc[k, c]),
        }
    return out


def measured(
    plant: MujocoPlant, schedule: Schedule, wall: float, a_max: np.ndarray | None = None
) -> dict[str, Any]:
    """What the plant measured, for an execution report: ``contacts`` (physics steps
    with a robot-robot contact) and ``contact_pairs``, ``measured_min_distance`` and
    ``measured_min_margin`` (every pair, every physics step), ``tracking_error_max`` /
    ``tracking_error_rms`` (against the first schedule), ``real_time_factor``,
    ``physics_steps``, ``disturbed``, and with ``a_max`` (per robot, m/s^2, NaN: the
    type has none; :func:`type_a_max`) the measured accelerations
    (:func:`accelerations`)."""
    me = plant.measure
    st_t, st_p = plant.samples
    err = np.linalg.norm(st_p - scheduled_positions(schedule, st_t), axis=2)
    sim = float(plant.time)
    dyn = accelerations(plant, a_max) if a_max is not None else {}
    return dyn | {
        "contacts": int(me.contacts),
        "contact_pairs": sorted([plant.names[a], plant.names[b]] for a, b in me.contact_pairs),
        "measured_min_distance": float(me.min_distance),
        "measured_min_margin": float(me.min_margin),
        "tracking_error_max": float(err.max()) if err.size else 0.0,
        "tracking_error_rms": float(np.sqrt(np.mean(err**2))) if err.size else 0.0,
        "real_time_factor": sim / wall if wall > 0 else math.inf,
        "physics_steps": int(me.steps),
        "disturbed": {
            plant.names[i]: sorted(plant.causes[i]) for i in range(plant.n) if plant.causes[i]
        },
    }
