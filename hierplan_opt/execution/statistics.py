"""Statistics of an execution: distances over continuous time, arrivals, layers.

The executed trajectories are piecewise linear in time, so the minimum distance of two
robots is exact (the closed form of :mod:`hierplan_opt.schedule.replay`, with its
exact pruning of pairs that stay far apart). ``collisions`` counts pairs whose centres
came closer than ``r_i + r_j`` (their footprints overlapped) or onto one point (any
radius, 0 included): :func:`hierplan_opt.schedule.replay.collides`, the one
definition; ``distance_kept`` says whether every pair kept the guaranteed ``r_i + r_j + margin``
(never with a collision, also at radius 0 and margin 0).
"""

from __future__ import annotations

import math
from collections import Counter
from dataclasses import replace
from typing import Any

import numpy as np

from hierplan_opt.core.instance import Instance
from hierplan_opt.execution.follow import follow_run, required_distance
from hierplan_opt.execution.robot import robot_run
from hierplan_opt.execution.state import DISTURBANCE_KINDS, ExecState, Execution
from hierplan_opt.schedule.output import Schedule, Waypoints
from hierplan_opt.schedule.replay import closest_pair, collides, pair_separations

#: Distance tolerance (metres, relative).
TOL = 1e-9


def executed_schedule(
    names: tuple[str, ...], traj: list[np.ndarray], base: Schedule, policy: str
) -> Schedule:
    """The executed way-points as a :class:`Schedule` (``hierplan post`` layout)."""
    wps = []
    for tr in traj:
        coords = tr[:, 1:]
        t = tr[:, 0]
        d = np.diff(coords, axis=0)
        theta = np.zeros(len(t))
        moving = np.linalg.norm(d, axis=1) > 1e-12
        if len(d):
            ang = np.arctan2(d[:, 1], d[:, 0])
            last = 0.0
            for k in range(len(d)):
                if moving[k]:
                    last = float(ang[k])
                theta[k + 1] = last
            theta[0] = float(ang[int(np.argmax(moving))]) if moving.any() else 0.0
        for x in (coords, t, theta):
            x.setflags(write=False)
        node = np.full(len(t), -1)
        wps.append(Waypoints(coords, theta, t, t, t, node, ("executed",) * len(t)))
    finals = np.array([w.arrival[-1] for w in wps])
    return Schedule(
        agent_names=names,
        waypoints=tuple(wps),
        makespan=float(finals.max()) if len(finals) else 0.0,
        flowtime=float(finals.sum()),
        safety_distance=base.safety_distance,
        objective="executed",
        method=policy,
        delta=base.margin,
        earliest=np.zeros(0),
        latest=np.zeros(0),
        times=np.zeros(0),
        critical_path=(),
        scale=base.scale,
        stats={},
        stn=None,
        margin=base.margin,
        clearance=base.clearance,
    )


def distances(
    schedule: Schedule, instance: Instance, required: Any = None, slack: float = 0.0
) -> tuple[float, int, bool, float, float | None]:
    """``(min distance, collisions, distance kept, worst gap, above)`` over every pair.

    ``required(i, j)`` (default ``r_i + r_j + margin``) is the distance a pair must
    keep; ``slack`` is subtracted from every measured distance (a sampling bound). The
    minimum is over every pair (:func:`~hierplan_opt.schedule.replay.closest_pair`:
    pairs pruned as far apart are measured when no pair checked came as close);
    ``inf`` when there are too many to measure, and then ``above`` is the distance every
    pair stayed beyond (else None). Pairs are pruned as
    :func:`~hierplan_opt.schedule.replay.pair_separations` does, watching one cell.

    Example
    -------
    >>> from hierplan_opt import Graph, Plan
    >>> from hierplan_opt.schedule import postprocess
    >>> inst = Instance.mapf(Graph.grid(3, 2), [(0, 0), (0, 1)], [(2, 0), (2, 1)])
    >>> distances(postprocess(inst, Plan.from_paths([[0, 1, 2], [3, 4, 5]]), margin=0), inst)
    (1.0, 0, True, 1.0, None)
    """
    K = schedule.num_agents
    radius = np.array([a.kinematics.radius for a in instance.agents], dtype=float)
    m = float(schedule.margin)
    times = [np.asarray(w.arrival, dtype=float) for w in schedule.waypoints]
    pos = [np.asarray(w.coords, dtype=float) * schedule.scale for w in schedule.waypoints]
    if K < 2:
        return math.inf, 0, True, math.inf, None
    sep = pair_separations(times, pos, radius, m, watch=schedule.scale, slack=slack)
    worst, collisions = math.inf, 0
    for k, (a, b) in enumerate(sep.pairs.tolist()):
        d = float(sep.distance[k])
        body = radius[a] + radius[b]
        need = body + m if required is None else float(required(a, b))
        worst = min(worst, d - need)
        if collides(d, body):
            collisions += 1
    closest = closest_pair(sep, times, pos, slack)
    # A collision is never a kept distance: at radius 0 and margin 0 two robots on one
    # point have gap 0 >= 0, yet they collided (``collides``).
    kept = collisions == 0 and bool(worst >= -TOL * max(1.0, float(radius.max()) * 2 + m))
    if closest is None:  # every pair stayed beyond the bound; too many to measure
        return math.inf, collisions, kept, float(worst), sep.skipped_bound
    return closest[0], collisions, kept, float(worst), None


def unsafe(stats: dict[str, Any]) -> bool:
    """Whether a run's ``statistics`` show a collision or the guaranteed distance not
    kept: the exit code 1 of ``simulate`` and ``run``, over the base run and every Monte
    Carlo run.

    Example
    -------
    >>> unsafe({"collisions": 0, "distance_kept": True}), unsafe({"collisions": 1,
    ...                                                           "distance_kept": False})
    (False, True)
    """
    return bool(stats["collisions"]) or not stats["distance_kept"]


def outcomes(
    instance: Instance,
    sim: ExecState,
    arrival: np.ndarray,
    finals: list[np.ndarray],
    goal_tol: float = 1e-6,
) -> tuple[np.ndarray, dict[str, str], list[str]]:
    """``(at_goal, why, stranded)``: which robots ended at a goal of their own (or of
    their team), why each other one did not, and the working robots among them (those
    that did not break down).

    ``finals`` are the robots' last positions (instance coordinates); a robot is at a
    goal within ``goal_tol`` (instance coordinates; a physical plant stops within its
    ``reach_tol`` metres, that is ``reach_tol / scale`` here).
    """
    g = instance.graph
    K = len(sim.names)
    at_goal = np.zeros(K, dtype=bool)
    why: dict[str, str] = {}
    stranded: list[str] = []
    for k in range(K):
        a = instance.agents[k]
        if a.goal is not None:
            goals = [a.goal]
        elif a.team is not None and instance.teams:
            goals = list(instance.teams[a.team].targets)
        else:
            goals = []
        p = np.asarray(finals[k], dtype=float)
        here = [v for v in goals if float(np.linalg.norm(g.coords[v] - p)) <= goal_tol]
        if here and not np.isnan(arrival[k]):
            at_goal[k] = True
            continue
        name = sim.names[k]
        where = _where(g, p)
        if sim.broken[k]:
            why[name] = f"broke down at {where}"
            continue
        stranded.append(name)
        if k in sim.substituted:
            goal, sub = sim.substituted[k]
            why[name] = (
                f"its goal {g.location(goal)} was blocked or cut off: substituted "
                f"{g.location(sub)}, ended at {where}"
            )
        elif np.isnan(arrival[k]):
            why[name] = f"blocked: never arrived, stopped at {where}"
        else:
            why[name] = f"ended at {where}, not a goal of its own"
    return at_goal, why, stranded


def _where(g: Any, p: np.ndarray) -> str:
    r = np.round(p, 3)
    if np.allclose(r, np.round(r)):
        return str(tuple(int(x) for x in np.round(r)))
    return "(" + ", ".join(f"{x:g}" for x in r.tolist()) + ")"


def finish(
    sim: ExecState,
    instance: Instance,
    schedule: Schedule,
    policy: str,
    mode: str,
    seed: int,
    dt: float,
    plant: Any = None,
) -> Execution:
    """Build the :class:`Execution` of a finished simulation (``plant``: the closed
    loop's plant, whose sampled motion is in ``sim.traj``)."""
    traj = []
    for g in range(sim.K):
        pts = sim.traj[g]
        t = np.array([p[0] for p in pts], dtype=float)
        xy = np.array([p[1] for p in pts], dtype=float).reshape(len(pts), -1)
        # Drop repeated time stamps (keep the last position at each time).
        keep = np.ones(len(t), dtype=bool)
        keep[:-1] = t[1:] > t[:-1] + 1e-12
        traj.append(np.column_stack([t[keep], xy[keep]]))
    arrival = sim.arrival.copy()
    slack, required, guaranteed = 0.0, None, schedule.safety_distance
    if sim.follow is not None:
        traj, slack = follow_run(sim, dt)
        required = required_distance(sim)
        guaranteed = min(t.safety_distance for t in sim.follows.values())
    robot = None
    if mode in ("robot", "replay") and plant is None:
        robot = robot_run(sim, instance, dt)
        traj, arrival = robot.trajectories, robot.arrival
        # Along the polylines (the refined timing only paces): the schedule's distance.
        slack, required, guaranteed = 0.0, None, schedule.safety_distance
    for tr in traj:
        tr.setflags(write=False)
    base = schedule
    if sim.replan_margins and min(sim.replan_margins) < schedule.margin:
        # A re-plan ran at a smaller margin (point robots at margin 0: rotations): the
        # distance guaranteed from then on is that margin's.
        low = min(sim.replan_margins)
        base = replace(schedule, margin=low)
        guaranteed = min(guaranteed, low)
    exe = executed_schedule(sim.names, traj, base, policy)
    d_min, collisions, kept, worst, above = distances(exe, instance, required, slack)
    # A physical plant stops within its reach tolerance (metres) of a way-point.
    goal_tol = max(1e-6, float(getattr(plant, "reach_tol", 0.0)) / float(schedule.scale))
    done, why, stranded = outcomes(instance, sim, arrival, [tr[-1, 1:] for tr in traj], goal_tol)
    events = [e for e in sim.log if e.kind in DISTURBANCE_KINDS]
    handled = Counter(e.layer for e in events)
    replans = sum(e.kind == "replan" and e.layer == "replan" for e in sim.log)
    stats: dict[str, Any] = {
        "policy": policy,
        "mode": mode,
        "collisions": collisions,
        "min_distance": d_min,
        # inf: every pair stayed farther apart than this (too many to measure exactly).
        "min_distance_above": above,
        "guaranteed_distance": guaranteed,
        "trajectories": "refined" if sim.follow is not None else "constant velocity",
        "distance_bound": slack,
        "distance_kept": bool(kept),
        "worst_gap": worst,
        # Not reached while a working robot is away from its goal (never hidden).
        "makespan": float(arrival[done].max()) if done.any() and not stranded else math.nan,
        "planned_makespan": schedule.makespan,
        "arrival_avg": float(arrival[done].mean()) if done.any() else math.nan,
        "arrival_max": float(arrival[done].max()) if done.any() else math.nan,
        "arrival_sum": float(arrival[done].sum()),
        "finished": int(done.sum()),
        "unfinished": [sim.names[g] for g in np.flatnonzero(~done).tolist()],
        "why_unfinished": why,
        "stranded": stranded,
        "broken": [sim.names[g] for g in np.flatnonzero(sim.broken).tolist()],
        "substituted": [sim.names[g] for g in sorted(sim.substituted)],
        "disturbances": len(events),
        "stn_resolves": sim.counts["stn_resolves"],
        "reorders": sim.counts["reorders"],
        "replans": replans,
        "handled": {k: handled.get(k, 0) for k in ("slack", "stn", "replan", "reorder", "none")},
        "runtime": dict(sim.runtime),
        "replan_runtime": [dict(r) for r in sim.replan_timing],
    }
    if plant is not None:
        stats["acceleration_violations"] = int(getattr(plant, "violations", 0))
        stats["max_acceleration_ratio"] = float(getattr(plant, "max_ratio", math.nan))
        stats["loop"] = "closed"
    if robot is not None:
        stats["acceleration_violations"] = len(robot.violations)
        stats["max_acceleration_ratio"] = robot.max_ratio
        if robot.violations:
            t, g, need = max(robot.violations, key=lambda x: x[2])
            stats["worst_acceleration"] = {"agent": sim.names[g], "time": t, "needed": need}
    if "acceleration_violations" in stats:
        # robots without a_max accelerate freely: nothing to check them against
        stats.setdefault(
            "acceleration_checked", sum(bool(a.kinematics.a_max) for a in instance.agents)
        )
    arrival.setflags(write=False)
    return Execution(
        policy=policy,
        mode=mode,
        seed=seed,
        agent_names=sim.names,
        trajectories=tuple(traj),
        schedule=exe,
        phases=tuple(sim.phases),
        log=tuple(sim.log),
        statistics=stats,
        arrival=arrival,
        replans=tuple(sim.replans),
        robot_times=(
            robot.event_times
            if robot is not None
            else (sim.phases[0].times if plant is not None and sim.phases else None)
        ),
    )
