"""Closed loop: the execution hierarchy (slack -> STN re-solve -> re-plan) over a Plant.

:func:`closed_loop` runs a schedule on any plant of the Plant protocol
(:mod:`hierplan_opt.execution.plant`; here the MuJoCo one) and watches it every ``dt``
seconds while the world keeps running:

* **gates**: a robot may drive up to the way-point before its first way-point whose
  Type-2 predecessors (another robot's way-point plus the arc's lower bound) have not
  happened (the temporal plan graph);
* **slack**: a robot that is free to go but later than its target at its next way-point
  by more than ``threshold`` seconds and by no more than that way-point's slack: nothing
  is re-computed (logged once per way-point, layer ``slack``);
* **stn**: later than the slack: the STN is re-solved incrementally
  (:func:`~hierplan_opt.schedule.solve_graph.fix_and_propagate`: what happened is fixed,
  the late robot's next node at its predicted time, successors pushed) and every robot
  gets its new target times (:meth:`Plant.retime`); layer ``stn``;
* **replan**: a robot that breaks down while others' gates wait for its remaining
  way-points (or an STN that became inconsistent): every working robot is released up
  to a *frontier* (the last vertex it can reach without the broken robot), and once all
  are there a new MAPF plan (broken robots' footprints as obstacles; ECBS, else LaCAM)
  and MAPF-POST schedule start from those vertices; layer ``replan``.

Every event names the disturbance behind it as the plant saw it (``spill``, ``stop``,
``random``, ``breakdown``, ``wind``; ``tracking``: the physics' own lag).
"""

from __future__ import annotations

import logging
import time
from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from hierplan_opt.core.errors import HierplanError
from hierplan_opt.core.graph import Graph
from hierplan_opt.core.instance import Agent, Instance
from hierplan_opt.physics.plant import MujocoPlant
from hierplan_opt.physics.run import Gates, PhysicsRun, make_plant, statistics, waypoints_m
from hierplan_opt.schedule.output import Schedule
from hierplan_opt.schedule.solve_graph import InconsistentSTNError, fix_and_propagate

log = logging.getLogger(__name__)

POLICIES = ("slack", "stn", "replan")
#: A re-plan's frontier not reached by every robot in this time: no re-plan.
HANDOVER_TIMEOUT = 60.0


@dataclass(frozen=True)
class LoopEvent:
    """One delay or disturbance and the layer that handled it (the fields of the
    execution report's events)."""

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


class _Phase:
    """One schedule being executed (the first, or one after a re-plan)."""

    def __init__(self, schedule: Schedule, agents: Sequence[int], offset: float) -> None:
        self.schedule = schedule
        self.agents = tuple(agents)  # phase robot j -> plant robot
        self.offset = offset
        self.gates = Gates(schedule)
        assert schedule.stn is not None
        self.stn = schedule.stn
        self.targets = np.asarray(schedule.times, dtype=float) + offset
        self.latest = np.asarray(schedule.latest, dtype=float) + offset
        self.routes = [waypoints_m(schedule, j) for j in range(len(agents))]
        self.nodes = [
            np.asarray(schedule.waypoints[j].node, dtype=np.int64) for j in range(len(agents))
        ]
        base = [np.asarray(schedule.waypoints[j].arrival, dtype=float) for j in range(len(agents))]
        self.planned = [b + offset for b in base]
        self.reach: list[list[float]] = [[] for _ in agents]
        self.logged: set[tuple[int, int, str]] = set()

    def waypoint_times(self, j: int) -> np.ndarray:
        """Robot j's way-point times from the node targets (turn way-points keep their
        offset from the node before them)."""
        nodes = self.nodes[j]
        out = self.planned[j].copy()
        shift = 0.0
        for k, v in enumerate(nodes.tolist()):
            if v >= 0:
                shift = float(self.targets[v]) - float(self.planned[j][k])
            out[k] = self.planned[j][k] + shift
        return out


def closed_loop(
    instance: Instance,
    schedule: Schedule,
    disturbances: Sequence[Any] = (),
    *,
    policy: str = "replan",
    seed: int = 0,
    dt: float = 0.1,
    threshold: float = 1.0,
    horizon: float | None = None,
    solver: str = "auto",
    replan_time_limit: float = 30.0,
    plant: MujocoPlant | None = None,
    **options: Any,
) -> tuple[PhysicsRun, list[LoopEvent]]:
    """Execute ``schedule`` in physics with the execution hierarchy (module text).

    Returns the run (measured statistics, plus ``events``, ``handled`` per layer,
    ``stn_resolves``, ``replans`` in its statistics) and the events.

    Example
    -------
    >>> from hierplan_opt.core.graph import Graph
    >>> from hierplan_opt.core.instance import Kinematics
    >>> from hierplan_opt.api import solve
    >>> from hierplan_opt.schedule.post import postprocess
    >>> g = Graph.grid(4, 1)
    >>> inst = Instance.mapf(g, [(0, 0)], [(3, 0)],
    ...                      kinematics=Kinematics("y", v_max=0.8, a_max=1.0, radius=0.3))
    >>> run, events = closed_loop(inst, postprocess(inst, solve(inst, "cbs").plan))
    >>> run.statistics["finished"], run.statistics["contacts"]
    (1, 0)
    """
    if policy not in POLICIES:
        raise HierplanError(f"physics closed loop: unknown policy {policy!r} (use {POLICIES})")
    wall0 = time.perf_counter()
    p = (
        plant
        if plant is not None
        else make_plant(instance, schedule, disturbances, seed=seed, **options)
    )
    K = schedule.num_agents
    names = schedule.agent_names
    events: list[LoopEvent] = []
    counts = {"stn_resolves": 0, "replans": 0}
    phase = _Phase(schedule, range(K), 0.0)
    for j in range(K):
        p.assign(j, phase.routes[j], phase.planned[j])
    # Reach times per plant robot and way-point of the first schedule (the report).
    first_reach = [np.full(len(r), np.nan) for r in phase.routes]
    seen_broken = np.zeros(K, dtype=bool)
    handover: dict[int, int] | None = None  # robot -> frontier way-point (re-plan)
    handover_since = 0.0
    if horizon is None:
        horizon = 3.0 * float(schedule.makespan) + 60.0
    goals_xy = [waypoints_m(schedule, j)[-1] for j in range(K)]

    def log_event(t: float, j: int, kind: str, layer: str, delay: float, detail: str) -> None:
        events.append(LoopEvent(t, names[j] if j >= 0 else "-", kind, layer, delay, detail))

    while p.time < horizon:
        now = p.time
        # 1. Progress.
        for jj, r in enumerate(phase.agents):
            rr = p.reached(r)
            reach = phase.reach[jj]
            while len(reach) <= rr:
                reach.append(now)
                if (
                    phase is not None
                    and phase.offset == 0.0
                    and len(reach) - 1 < len(first_reach[r])
                ):
                    first_reach[r][len(reach) - 1] = now
        # 2. Breakdowns.
        for r in range(K):
            if p.broken[r] and not seen_broken[r]:
                seen_broken[r] = True
                waiting = _waits_for(phase, r, p)
                if not waiting:
                    log_event(now, r, "breakdown", "slack", 0.0, "no robot waits for it")
                elif policy != "replan":
                    log_event(
                        now,
                        r,
                        "breakdown",
                        "none",
                        0.0,
                        f"{len(waiting)} robots wait for it; re-plan is off",
                    )
                elif handover is None:
                    handover = _frontier(phase, p)
                    handover_since = now
                    log_event(
                        now,
                        r,
                        "breakdown",
                        "replan",
                        0.0,
                        f"blocks {', '.join(names[phase.agents[w]] for w in waiting)}",
                    )
        # 3. Hand-over: every working robot at its frontier -> new plan.
        if handover is not None:
            ready = all(
                p.reached(phase.agents[jj]) >= f or p.broken[phase.agents[jj]]
                for jj, f in handover.items()
            )
            if not ready and now - handover_since > HANDOVER_TIMEOUT:
                stuck = [
                    names[phase.agents[jj]]
                    for jj, f in handover.items()
                    if p.reached(phase.agents[jj]) < f and not p.broken[phase.agents[jj]]
                ]
                log_event(
                    now,
                    -1,
                    "replan",
                    "none",
                    0.0,
                    f"frontier not reached in {HANDOVER_TIMEOUT:.0f} s: {', '.join(stuck)}",
                )
                handover = None
                policy = "stn"
            if ready and handover is not None:
                t0 = time.perf_counter()
                new = _replan(instance, phase, p, handover, goals_xy, solver, replan_time_limit)
                counts["replans"] += 1
                handover = None
                if new is None:
                    log_event(now, -1, "replan", "none", 0.0, "re-plan found no plan")
                else:
                    phase = new
                    log_event(
                        now,
                        -1,
                        "replan",
                        "replan",
                        0.0,
                        f"{len(new.agents)} robots re-planned in {time.perf_counter() - t0:.2f} s",
                    )
        # 4. Gates (capped at the frontier during a hand-over).
        for jj, r in enumerate(phase.agents):
            if p.broken[r]:
                continue
            g = phase.gates.gate(jj, p.reached(r), phase.reach, now)
            if handover is not None:
                g = min(g, handover.get(jj, g))
            if g != p.gate[r]:
                p.release(r, g)
        # 5. Lateness: slack or STN re-solve.
        if handover is None and _lateness(phase, p, now, threshold, policy, counts, log_event):
            handover = _frontier(phase, p)
            handover_since = now
        done = (
            all(
                p.reached(phase.agents[jj]) >= len(phase.routes[jj]) - 1
                or p.broken[phase.agents[jj]]
                for jj in range(len(phase.agents))
            )
            and handover is None
        )
        if done:
            break
        p.step(dt)
    wall = time.perf_counter() - wall0
    # Arrival at the goal: the last way-point of the robot's last phase.
    reach = [fr.copy() for fr in first_reach]
    for jj, r in enumerate(phase.agents):
        if phase.offset == 0:
            break
        stayed = bool(np.all(np.linalg.norm(phase.routes[jj] - goals_xy[r], axis=1) < 1e-6))
        if stayed and not np.isnan(first_reach[r][-1]):
            continue  # at its goal before the re-plan and kept there
        if len(phase.reach[jj]) >= len(phase.routes[jj]):
            reach[r][-1] = phase.reach[jj][-1]
        else:
            reach[r][-1] = np.nan
    planned = [np.asarray(schedule.waypoints[j].arrival, dtype=float) for j in range(K)]
    st_t, st_p = p.samples
    stats = statistics(p, schedule, reach, planned, st_t, st_p, wall)
    handled: dict[str, int] = {}
    for e in events:
        handled[e.layer] = handled.get(e.layer, 0) + 1
    stats.update(counts)
    stats["handled"] = handled
    stats["events"] = [e.as_dict() for e in events]
    stats["policy"] = policy
    run = PhysicsRun(tuple(names), tuple(reach), tuple(planned), st_t, st_p, stats)
    return run, events


def _lateness(
    phase: _Phase,
    p: MujocoPlant,
    now: float,
    threshold: float,
    policy: str,
    counts: dict[str, int],
    log_event: Any,
) -> bool:
    """Slack or STN re-solve for robots late at their next way-point; True: the STN
    became inconsistent and the re-plan layer is to take over."""
    for jj, r in enumerate(phase.agents):
        if p.broken[r]:
            continue
        k = p.reached(r) + 1
        if k == 0 or k >= len(phase.routes[jj]) or p.gate[r] < k:
            # Not at its start yet (a start node is fixed at the phase's start), done,
            # or waiting at a gate (the TPG's own waiting).
            continue
        v = int(phase.nodes[jj][k])
        if v < 0:
            continue
        late = now - float(phase.targets[v])
        if late <= threshold:
            continue
        slack = float(phase.latest[v] - phase.targets[v])
        kind = p.cause(r) or "tracking"
        if late <= slack or policy == "slack":
            key = (jj, k, "slack")
            if key not in phase.logged:
                phase.logged.add(key)
                log_event(
                    now,
                    r,
                    kind,
                    "slack",
                    late,
                    f"way-point {k}: {late:.2f} s late, slack {slack:.2f} s",
                )
            continue
        # STN re-solve: happened nodes fixed, this one at its predicted time.
        remaining = float(np.linalg.norm(phase.routes[jj][k] - p.positions()[r]))
        predicted = now + remaining / max(float(p.v_max[r]), 1e-9) + threshold
        # Fixed: this node at its predicted time (what happened stays as the targets
        # had it: the executed times may break the STN's lower bounds by a little,
        # physics being no model of them).
        fixed = {v: predicted}
        try:
            new_t = fix_and_propagate(
                phase.stn,
                phase.targets - phase.offset,
                {u: t - phase.offset for u, t in fixed.items()},
            )
        except InconsistentSTNError as exc:
            if policy == "replan":
                log_event(now, r, kind, "replan", late, f"STN inconsistent: {exc}")
                return True
            log_event(now, r, kind, "none", late, f"STN inconsistent: {exc}")
            continue
        phase.targets = new_t + phase.offset
        counts["stn_resolves"] += 1
        for j2, r2 in enumerate(phase.agents):
            p.retime(r2, phase.waypoint_times(j2))
        log_event(
            now, r, kind, "stn", late, f"way-point {k}: {late:.2f} s late, slack {slack:.2f} s"
        )
    return False


def _waits_for(phase: _Phase, r: int, p: MujocoPlant) -> list[int]:
    """Phase robots whose remaining way-points have a Type-2 predecessor among robot
    r's way-points it has not reached."""
    if r not in phase.agents:
        return []
    jr = phase.agents.index(r)
    done = p.reached(r)
    out = []
    for jj, pre in enumerate(phase.gates.preds):
        if jj == jr:
            continue
        k0 = p.reached(phase.agents[jj]) + 1
        if any(rr == jr and idx > done for wp in pre[k0:] for rr, idx, _lb in wp):
            out.append(jj)
    return out


def _frontier(phase: _Phase, p: MujocoPlant) -> dict[int, int]:
    """Per working phase robot: the next vertex way-point ahead that it can reach with
    the broken robots never moving again, closed under the gates (a fixpoint: a robot's
    frontier never needs another robot's way-point beyond that one's frontier)."""
    n = len(phase.agents)
    reached = [p.reached(r) for r in phase.agents]
    broken = [bool(p.broken[r]) for r in phase.agents]
    limit = [reached[j] if broken[j] else len(phase.routes[j]) - 1 for j in range(n)]
    kinds = [phase.schedule.waypoints[j].kind for j in range(n)]
    front = list(limit)
    changed = True
    while changed:
        changed = False
        for j in range(n):
            if broken[j]:
                continue
            lim = limit[j]
            for k in range(reached[j] + 1, lim + 1):
                if any(idx > front[rr] for rr, idx, _lb in phase.gates.preds[j][k]):
                    lim = k - 1
                    break
            # The next vertex ahead (the robots stop soon and the re-plan starts early),
            # else as far as it may go.
            f = next((k for k in range(reached[j] + 1, lim + 1) if kinds[j][k] == "vertex"), lim)
            f = max(f, reached[j])
            if lim != limit[j] or f != front[j]:
                limit[j], front[j] = lim, f
                changed = True
    return {j: front[j] for j in range(n) if not broken[j]}


def _replan(
    instance: Instance,
    phase: _Phase,
    p: MujocoPlant,
    front: dict[int, int],
    goals_xy: list[np.ndarray],
    solver: str,
    time_limit: float,
) -> _Phase | None:
    """A new MAPF plan and schedule from the frontier vertices (broken robots'
    footprints blocked), assigned to the plant."""
    from hierplan_opt.api import solve
    from hierplan_opt.schedule.post import postprocess

    g = instance.graph
    if g.kind != "grid" or g.shape is None:
        return None
    sched0 = phase.schedule
    scale = float(sched0.scale)
    pos_v = g.coords * scale
    posv3 = np.zeros((g.n, 3))
    posv3[:, : pos_v.shape[1]] = pos_v
    r_all = p.radius
    r_max = float(r_all.max())
    margin = float(sched0.margin)
    extra = np.zeros(g.n, dtype=bool)
    here = p.positions()
    for r in np.flatnonzero(p.broken).tolist():
        near = np.linalg.norm(posv3 - here[r], axis=1) < r_all[r] + r_max + margin
        extra |= near & g.passable
    agents: list[Agent] = []
    robots: list[int] = []
    starts: dict[int, int] = {}
    for jj, f in front.items():
        r = phase.agents[jj]
        d = np.linalg.norm(posv3 - phase.routes[jj][f], axis=1)
        d[~g.passable] = np.inf
        s = int(np.argmin(d))
        starts[r] = s
    for s in starts.values():
        extra[s] = False
    blocked = (~g.passable | extra).reshape(tuple(reversed(g.shape)))
    graph = Graph.grid(*g.shape, blocked=blocked, cell_size=g.cell_size)
    by_name = {a.name: a for a in instance.agents}
    for r, s in starts.items():
        dg = np.linalg.norm(posv3 - goals_xy[r], axis=1)
        dg[~graph.passable] = np.inf
        goal = int(np.argmin(dg))
        name = p.names[r]
        kin = by_name[name].kinematics if name in by_name else instance.agents[r].kinematics
        agents.append(Agent(name, s, goal, None, kin))
        robots.append(r)
    if len(set(starts.values())) < len(starts):
        return None
    inst2 = Instance(graph, tuple(agents), (), None, f"{instance.name}-replan")
    name = solver if solver != "auto" else ("ecbs" if len(agents) <= 100 else "lacam")
    res = None
    for s_name in dict.fromkeys([name, "lacam"]):
        try:
            res = solve(inst2, s_name, time_limit=time_limit, objective="soc")
        except HierplanError as exc:
            log.info("re-plan with %s failed: %s", s_name, exc)
            res = None
        if res is not None and res.plan is not None:
            break
    if res is None or res.plan is None:
        return None
    try:
        sched = postprocess(inst2, res.plan, margin=margin)
    except HierplanError as exc:
        log.info("MAPF-POST of the re-plan failed: %s", exc)
        return None
    sched = replace(sched)
    new = _Phase(sched, robots, p.time + 0.5)
    for jj, r in enumerate(robots):
        p.assign(r, new.routes[jj], new.planned[jj])
    return new


__all__ = ["POLICIES", "LoopEvent", "closed_loop"]
