"""The re-planning layer: a MAPF re-plan from the robots' current positions.

When the STN cannot absorb a disturbance (inconsistent with deadlines) or a broken-down
robot blocks others, the running schedule is cut at a *frontier* and a new plan is made:

1. **Frontier** (:func:`restrict_to_frontier`): every working robot finishes its
   current move to the next vertex of its path under the old TPG; a robot whose next
   events depend on a broken robot stops at its last event it can still reach. The
   frontier is closed under the TPG's predecessors (a robot's frontier is pushed on to
   the next vertex when another one needs its later events), so the robots reach it
   without waiting for each other for ever. Unaffected robots keep moving.
2. **Start vertices**: a robot at a vertex starts there; one held between vertices
   starts at the vertex whose surroundings it has claimed (it passed the claim's
   *enter* marker: the next vertex; else the previous one) and moves there first.
3. **MAPF**: the same map with the broken robots as obstacles (every vertex closer to
   one than ``r_b + r_max + margin``), each robot to its old goal (or staying where it
   is if its goal is blocked), solved by a registered solver (ECBS by default) and
   validated; then MAPF-POST again.
4. **Hand-over**: the new STN's start nodes are fixed at the times the robots reach
   their start vertices; a robot whose new path comes within ``r_i + r_j + margin``
   of another robot's way to its start vertex waits until that robot has got there.
"""

from __future__ import annotations

import logging
import math
import time
from typing import TYPE_CHECKING

import numpy as np

from hierplan_opt import registry
from hierplan_opt.core.errors import HierplanError
from hierplan_opt.core.graph import Graph
from hierplan_opt.core.instance import Agent, Instance
from hierplan_opt.core.validate import validate
from hierplan_opt.schedule.output import Schedule, build_schedule
from hierplan_opt.schedule.post import postprocess
from hierplan_opt.schedule.solve_graph import critical_path, earliest_times, windows
from hierplan_opt.schedule.stn import STN
from hierplan_opt.schedule.tpg import ENTER

if TYPE_CHECKING:
    from hierplan_opt.execution.simulate import _Sim

log = logging.getLogger(__name__)

#: Sampling step (metres) of a robot's way to its start vertex in the hand-over check.
SAMPLE = 0.05


def footprint_vertices(graph: Graph, point: np.ndarray, need: float) -> np.ndarray:
    """Passable vertices another robot may not use while a robot stands still at
    ``point`` (metres): every vertex closer than ``need`` (``r_b + r_other + margin``;
    for point robots the vertex it stands on), and of every edge that passes closer
    than ``need`` the end nearer to ``point`` (so no remaining edge comes close).

    Example
    -------
    >>> g = Graph.grid(3, 1)
    >>> footprint_vertices(g, np.array([0.5, 0.0]), 0.0).tolist()  # mid-edge point robot
    [0]
    >>> footprint_vertices(g, np.array([1.0, 0.0]), 0.7).tolist()
    [1]
    """
    scale = graph.cell_size if graph.kind == "grid" else 1.0
    pos = graph.coords * scale
    p = np.asarray(point, dtype=float)[: pos.shape[1]]
    d = np.linalg.norm(pos - p, axis=1)
    hit = graph.passable & ((d < need) | (d <= _EPS))
    src = np.repeat(np.arange(graph.n), np.diff(graph.indptr))
    dst = graph.indices
    a, b = pos[src], pos[dst]
    ab = b - a
    L = np.einsum("ij,ij->i", ab, ab)
    f = np.clip(np.einsum("ij,ij->i", p - a, ab) / np.where(L > 0, L, 1.0), 0.0, 1.0)
    ds = np.linalg.norm(a + f[:, None] * ab - p, axis=1)
    close = (ds < need) | (ds <= _EPS)
    tie = d[src] == d[dst]
    near_end = np.where(tie, np.minimum(src, dst), np.where(d[src] < d[dst], src, dst))
    hit[near_end[close]] = True
    return np.flatnonzero(hit & graph.passable)


#: Distances this small are one point (metres).
_EPS = 1e-9


def _last_happened(sim: _Sim, j: int) -> int:
    nodes = sim.S.tpg.agent_nodes(j)
    done = np.flatnonzero(~np.isnan(sim.t[nodes.start : nodes.stop]))
    return nodes.start + int(done[-1]) if len(done) else nodes.start - 1


def restrict_to_frontier(sim: _Sim, now: float) -> None:
    """Deactivate every node beyond the frontier (see the module text)."""
    from hierplan_opt.execution.simulate import _descendants

    S = sim.S
    tpg = S.tpg
    K = tpg.num_agents
    stn = sim.stn
    ends = tpg.agent_ptr
    broken_nodes: list[int] = []
    last = [_last_happened(sim, j) for j in range(K)]
    for j in range(K):
        if sim.broken[sim.gid[j]]:
            broken_nodes += list(range(last[j] + 1, int(ends[j + 1])))
    blocked = _descendants(stn, broken_nodes) if broken_nodes else set()
    first_blocked = []
    for j in range(K):
        fb = int(sim.geo_block.get(j, ends[j + 1]))
        for v in range(last[j] + 1, fb):
            if v in blocked:
                fb = v
                break
        first_blocked.append(fb)
    front = []
    for j in range(K):
        h = last[j]
        if sim.broken[sim.gid[j]] or h >= int(ends[j + 1]) - 1:
            front.append(h)
            continue
        f = _braking_vertex(sim, j, h, now)
        front.append(min(f, first_blocked[j] - 1))
    changed = True
    while changed:
        changed = False
        for j in range(K):
            for v in range(last[j] + 1, front[j] + 1):
                arcs = stn.in_arcs(v)
                for u in stn.arc_src[arcs].tolist():
                    k = int(tpg.node_agent[u])
                    if k != j and u > front[k]:
                        nf = int(min(S.next_vertex[u], ends[k + 1] - 1))
                        nf = max(min(nf, first_blocked[k] - 1), u)
                        if nf > front[k]:
                            front[k] = nf
                            changed = True
    for j in range(K):
        sim.active[front[j] + 1 : int(ends[j + 1])] = False
    sim.front = front


def _braking_vertex(sim: _Sim, j: int, h: int, now: float) -> int:
    """The first vertex node after ``h`` that robot ``j`` can still stop at: at least
    its braking distance ``v_max^2 / (2 a_max)`` ahead when it is moving (so a robot
    with bounded acceleration, which is never ahead of this run by more than it
    cannot help, brakes before it follows the new plan)."""
    S = sim.S
    tpg = S.tpg
    end = int(tpg.agent_ptr[j + 1]) - 1
    first = int(min(S.next_vertex[h + 1], end))
    kin = sim.instance.agents[sim.gid[j]].kinematics
    n = h + 1
    moving = not np.isnan(sim.phys[n]) and sim.phys[n] > now and not sim.broken[sim.gid[j]]
    if not moving or not kin.a_max:
        return first
    need = kin.v_max**2 / (2 * kin.a_max)
    pos = sim.traj_pos(sim.gid[j], now, n) * sim.scale
    ahead = float(np.linalg.norm(tpg.node_pos[n] - pos))
    for v in range(n, end + 1):
        if v > n:
            ahead += float(np.linalg.norm(tpg.node_pos[v] - tpg.node_pos[v - 1]))
        if v >= first and S.is_vertex[v] and ahead >= need - 1e-9:
            return v
    return end


def _start_vertex(sim: _Sim, h: int) -> int:
    """The vertex a robot held at node ``h`` starts the new plan from."""
    S = sim.S
    tpg = S.tpg
    if S.is_vertex[h]:
        return int(tpg.node_vertex[h])
    lv = int(S.last_vertex[h])
    if np.any(tpg.node_kind[lv + 1 : h + 1] == ENTER):
        return int(tpg.node_vertex[int(S.next_vertex[h])])
    return int(tpg.node_vertex[lv])


def replan(sim: _Sim, t_r: float) -> tuple[Schedule, STN, tuple[int, ...], np.ndarray] | None:
    """A new plan and schedule from the current positions (None when impossible)."""
    inst = sim.instance
    g = inst.graph
    S = sim.S
    tpg = S.tpg
    reason = sim.replan_reason
    if g.kind != "grid":
        sim._log(t_r, "-", "replan", "none", 0.0, "re-planning needs a grid map")
        return None
    K = tpg.num_agents
    margin = sim.schedule0.margin
    radius = np.array([a.kinematics.radius for a in inst.agents], dtype=float)
    r_max = float(radius.max())
    extra_blocked = np.zeros(g.n, dtype=bool)
    starts: dict[int, int] = {}
    holds: dict[int, tuple[float, np.ndarray, float]] = {}
    goals: dict[int, int] = {}
    for j in range(K):
        gid = sim.gid[j]
        h = _last_happened(sim, j)
        if sim.broken[gid]:
            continue
        s = _start_vertex(sim, h)
        starts[gid] = s
        t_h = float(np.nanmax([sim.t[h], sim.traj[gid][-1][0]]))
        p_h = sim.traj[gid][-1][1]
        v_max = inst.agents[gid].kinematics.v_max
        dist = float(np.linalg.norm((g.coords[s] - p_h) * sim.scale))
        holds[gid] = (max(t_h, t_r), p_h, dist / v_max)
        goals[gid] = int(tpg.node_vertex[int(tpg.agent_ptr[j + 1]) - 1])
    for gid in np.flatnonzero(sim.broken).tolist():
        # Where it physically stands (its footprint), not the vertex it had claimed.
        p = sim.traj[gid][-1][1] * sim.scale
        extra_blocked[footprint_vertices(g, p, radius[gid] + r_max + margin)] = True
    for s in starts.values():
        extra_blocked[s] = False  # never block a robot's own start
    gid2 = tuple(sorted(starts))
    if not gid2:
        return None
    if len(set(starts.values())) < len(starts):
        sim._log(t_r, "-", "replan", "none", 0.0, "two robots would start at one vertex")
        return None
    dims = g.shape
    assert dims is not None
    blocked = (~g.passable | extra_blocked).reshape(tuple(reversed(dims)))
    graph = Graph.grid(*dims, blocked=blocked, cell_size=g.cell_size)
    _substitute_goals(sim, t_r, g, graph, gid2, starts, goals)
    agents = tuple(
        Agent(inst.agents[k].name, starts[k], goals[k], None, inst.agents[k].kinematics)
        for k in gid2
    )
    try:
        inst2 = Instance(graph, agents, (), None, f"{inst.name}-replan")
        fn = registry.get(sim.solver).load()
        t0 = time.perf_counter()
        res = fn(inst2, time_limit=sim.replan_time_limit, seed=0, objective="soc")
        solve_time = time.perf_counter() - t0
    except HierplanError as exc:
        sim._log(t_r, "-", "replan", "none", 0.0, f"re-plan failed: {exc}")
        return None
    if res.plan is None:
        sim._log(t_r, "-", "replan", "none", 0.0, f"re-plan found no plan ({res.status})")
        return None
    bad = validate(inst2, res.plan)
    if bad:
        sim._log(t_r, "-", "replan", "none", 0.0, f"re-plan invalid: {bad[0]}")
        return None
    try:
        sched = postprocess(inst2, res.plan, margin=margin, check_plan=False)
    except HierplanError as exc:
        sim._log(t_r, "-", "replan", "none", 0.0, f"MAPF-POST of the re-plan failed: {exc}")
        return None
    sim.replans.append((inst2, res.plan))
    assert sched.stn is not None
    stn = sched.stn
    tpg2 = stn.tpg
    release = np.array(stn.release, dtype=float)
    deadline = np.array(stn.deadline, dtype=float)
    # Hand-over: robots first reach their start vertices (in index order when two
    # ways to a start vertex come close), then new paths wait for nearby hand-overs.
    ready: dict[int, float] = {}
    ways: dict[int, np.ndarray] = {}
    deps: list[tuple[str, int, int, int]] = []
    for k, gid in enumerate(gid2):
        t_h, p_h, move = holds[gid]
        ways[gid] = _way(sim, gid, t_r, g.coords[starts[gid]]) * sim.scale
        depart = t_h
        for gid_a in gid2[:k]:
            need = radius[gid] + radius[gid_a] + margin
            if _close(ways[gid_a], ways[gid][-2:], need):
                depart = max(depart, ready[gid_a])
                deps.append(("depart", gid, -1, gid_a))
        if depart > t_h + 1e-12:
            sim._record(gid, depart, p_h)
        ready[gid] = depart + move
    for j, gid in enumerate(gid2):
        v0 = int(tpg2.agent_ptr[j])
        release[v0] = ready[gid]
        deadline[v0] = np.inf
    for j, gid in enumerate(gid2):
        nodes = np.arange(int(tpg2.agent_ptr[j]), int(tpg2.agent_ptr[j + 1]))
        pts = tpg2.node_pos[nodes]
        for gid_a in gid2:
            if gid_a == gid:
                continue
            need = radius[gid] + radius[gid_a] + margin
            for i in range(len(nodes)):
                seg = pts[i : i + 2]
                if _close(ways[gid_a], seg, need):
                    v = int(nodes[i])
                    release[v] = max(release[v], ready[gid_a])
                    deps.append(("node", gid, v, gid_a))
                    break
    sim.handover[len(sim.phases)] = deps
    new_stn = stn.with_bounds(release=release, deadline=deadline)
    sched, times = rescheduled(sched, new_stn)
    sim._log(
        t_r,
        "-",
        "replan",
        "replan",
        0.0,
        f"{reason}: new plan for {len(gid2)} robots ({sim.solver}, cost {res.cost}, "
        f"{solve_time:.3g} s)",
    )
    return sched, new_stn, gid2, times


def rescheduled(sched: Schedule, stn: STN, **stats: float) -> tuple[Schedule, np.ndarray]:
    """``sched`` on ``stn`` (other node bounds): its earliest schedule, windows and
    critical path (``stats`` added to the schedule's), and the times."""
    times = earliest_times(stn)
    early, late = windows(stn, times)
    new = build_schedule(
        stn,
        times,
        early,
        late,
        critical_path(stn, times),
        objective="makespan",
        method="graph",
        scale=sched.scale,
        safety_distance=sched.safety_distance,
        margin=sched.margin,
        clearance=sched.clearance,
        stats={**sched.stats, **stats},
    )
    return new, times


def _substitute_goals(
    sim: _Sim,
    t_r: float,
    g: Graph,
    graph: Graph,
    gid2: tuple[int, ...],
    starts: dict[int, int],
    goals: dict[int, int],
) -> None:
    """A robot whose goal is blocked by a broken robot, or cut off from its start,
    heads for the nearest vertex it can reach instead (logged)."""
    from hierplan_opt.core.graph import UNREACHABLE

    taken = {goals[k] for k in gid2}
    for gid in gid2:
        goal = goals[gid]
        reach = graph.dist_to(starts[gid]) < UNREACHABLE
        if graph.passable[goal] and reach[goal]:
            continue
        closeness = np.where(reach & graph.passable, g.dist_to(goal), UNREACHABLE).astype(float)
        for v in taken - {goal}:
            closeness[v] = np.inf
        closeness[~(reach & graph.passable)] = np.inf
        v = int(np.argmin(closeness))
        if not np.isfinite(closeness[v]):
            v = starts[gid]
        taken.discard(goal)
        taken.add(v)
        goals[gid] = v
        sim.substituted[gid] = (goal, v)
        sim._log(
            t_r,
            sim.names[gid],
            "goal",
            "replan",
            0.0,
            f"its goal {g.location(goal)} is blocked or cut off: it heads for {g.location(v)}",
        )


def _way(sim: _Sim, gid: int, t_r: float, start: np.ndarray) -> np.ndarray:
    """A robot's positions from ``t_r`` to its start vertex (instance coordinates)."""
    tr = sim.traj[gid]
    ts = np.array([t for t, _ in tr])
    ps = np.array([p for _, p in tr])
    keep = ts >= t_r
    at = np.array([np.interp(t_r, ts, ps[:, k]) for k in range(ps.shape[1])])
    pts = np.vstack([at[None, :], ps[keep], start[None, :]])
    return pts


def _close(way: np.ndarray, seg: np.ndarray, need: float) -> bool:
    """Whether polyline ``way`` comes within ``need`` (+ sampling) of ``seg``."""
    if need <= 0:
        return False
    samples = [way[:1]]
    for a, b in zip(way[:-1], way[1:], strict=True):
        n = max(1, int(math.ceil(np.linalg.norm(b - a) / SAMPLE)))
        f = np.linspace(0, 1, n + 1)[1:, None]
        samples.append(a + f * (b - a))
    pts = np.vstack(samples)
    if len(seg) == 1:
        d = np.linalg.norm(pts - seg[0], axis=1)
    else:
        a, b = seg[0], seg[1]
        ab = b - a
        L = float(ab @ ab)
        s = np.clip(((pts - a) @ ab) / L, 0, 1) if L > 0 else np.zeros(len(pts))
        d = np.linalg.norm(pts - (a + s[:, None] * ab), axis=1)
    return bool(d.min() < need + SAMPLE)
