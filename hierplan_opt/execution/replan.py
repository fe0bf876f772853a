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
import time
from dataclasses import replace
from typing import Any

import numpy as np

from hierplan_opt.core.errors import HierplanError
from hierplan_opt.core.graph import UNREACHABLE, Graph
from hierplan_opt.core.instance import Agent, Instance
from hierplan_opt.core.result import Result, Status
from hierplan_opt.execution.chain import Planned, plan_and_post
from hierplan_opt.execution.state import ExecState, descendants
from hierplan_opt.schedule.output import Schedule, build_schedule
from hierplan_opt.schedule.solve_graph import critical_path, earliest_times, windows
from hierplan_opt.schedule.stn import STN
from hierplan_opt.schedule.tpg import ENTER

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


def _last_happened(sim: ExecState, j: int) -> int:
    nodes = sim.S.tpg.agent_nodes(j)
    done = np.flatnonzero(~np.isnan(sim.t[nodes.start : nodes.stop]))
    return nodes.start + int(done[-1]) if len(done) else nodes.start - 1


def restrict_to_frontier(sim: ExecState, now: float) -> None:
    """Deactivate every node beyond the frontier (see the module text)."""
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
    blocked = descendants(stn, broken_nodes) if broken_nodes else set()
    first_blocked = []
    for j in range(K):
        fb = sim.geo_block.get(j, int(ends[j + 1]))
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


def _braking_vertex(sim: ExecState, j: int, h: int, now: float) -> int:
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


def _start_vertex(sim: ExecState, h: int) -> int:
    """The vertex a robot held at node ``h`` starts the new plan from."""
    S = sim.S
    tpg = S.tpg
    if S.is_vertex[h]:
        return int(tpg.node_vertex[h])
    lv = int(S.last_vertex[h])
    if np.any(tpg.node_kind[lv + 1 : h + 1] == ENTER):
        return int(tpg.node_vertex[int(S.next_vertex[h])])
    return int(tpg.node_vertex[lv])


#: ``solver="auto"`` re-plans with ECBS up to this many robots, LaCAM beyond.
AUTO_ECBS_ROBOTS = 100
#: ``auto`` then tries LaCAM with this many seeds when the first solver fails ...
FALLBACK_SEEDS = 4
#: ... each fallback with at most this many seconds.
FALLBACK_TIME_LIMIT = 5.0


def replan_solver(name: str, robots: int) -> str:
    """The solver a re-plan of ``robots`` robots uses: ``auto`` is ECBS up to
    :data:`AUTO_ECBS_ROBOTS` robots, else LaCAM (fast first plans).

    Example
    -------
    >>> replan_solver("auto", 50), replan_solver("auto", 300), replan_solver("cbs", 300)
    ('ecbs', 'lacam', 'cbs')
    """
    if name != "auto":
        return name
    return "ecbs" if robots <= AUTO_ECBS_ROBOTS else "lacam"


def _solve(sim: ExecState, inst2: Instance, margin: float) -> Planned:
    """The re-plan instance through the checked chain (:func:`.chain.plan_and_post`:
    solve, validate, MAPF-POST with the running schedule's margin); ``auto`` falls
    back to ECBS (after LaCAM) and LaCAM with other seeds when the first plan fails or
    MAPF-POST refuses it (robots that rotate through a cycle of cells cannot keep any
    clearance); point robots first try the same solver at margin 0, where MAPF-POST
    schedules rotations (they still never meet on one point)."""
    first = replan_solver(sim.solver, inst2.num_agents)
    tries = [(first, 0, margin)]
    if margin > 0 and all(a.kinematics.radius == 0 for a in inst2.agents):
        # Point robots: MAPF-POST schedules rotations at margin 0 (never on one point).
        tries.append((first, 0, 0.0))
    if sim.solver == "auto":  # other plans (one MAPF-POST refuses: rotations)
        if first == "lacam":
            tries.append(("ecbs", 0, margin))
        tries += [
            ("lacam", seed, margin)
            for seed in range(FALLBACK_SEEDS)
            if (first, seed) != ("lacam", 0)
        ]
    planned: Planned | None = None
    for name, seed, margin in tries:
        options: dict[str, Any] = {"anytime": 0} if name == "lacam" else {}
        try:
            limit = sim.replan_time_limit
            if planned is not None:  # a fallback
                limit = min(limit, FALLBACK_TIME_LIMIT)
            planned = plan_and_post(
                inst2,
                name,
                time_limit=limit,
                seed=seed,
                cost="soc",
                margin=margin,
                **options,
            )
        except HierplanError as exc:
            why = f"re-plan failed: {exc}"
            planned = Planned(Result(Status.ERROR, None, solver=name), None, name, 0.0, why=why)
            continue
        if planned.schedule is not None:
            return planned
        planned = replace(planned, why=f"re-plan: {planned.why}")
    assert planned is not None
    return planned


def _start_options(sim: ExecState, h: int) -> list[int]:
    """The vertices a robot held at node ``h`` may start the new plan from, best
    first: the vertex it stands on; between two vertices the one it has claimed
    (:func:`_start_vertex`), then the other end of its edge."""
    S = sim.S
    tpg = S.tpg
    first = _start_vertex(sim, h)
    if S.is_vertex[h]:
        return [first]
    ends = [int(tpg.node_vertex[int(S.last_vertex[h])])]
    nxt = int(S.next_vertex[h])
    if nxt < tpg.num_nodes and int(tpg.node_agent[nxt]) == int(tpg.node_agent[h]):
        ends.append(int(tpg.node_vertex[nxt]))
    return [first] + [v for v in ends if v != first]


def _distinct_starts(options: dict[int, list[int]]) -> dict[int, int] | None:
    """One start vertex per robot, all distinct: robots on a vertex keep it; a robot
    between two vertices takes its first option nobody else has (None: impossible).

    Example
    -------
    >>> _distinct_starts({0: [5], 1: [5, 6], 2: [7, 8]})
    {0: 5, 1: 6, 2: 7}
    >>> _distinct_starts({0: [5], 1: [5]}) is None
    True
    """
    taken: dict[int, int] = {}
    for gid, opts in options.items():
        if len(opts) == 1:
            if opts[0] in taken.values():
                return None
            taken[gid] = opts[0]
    used = set(taken.values())
    for gid, opts in options.items():
        if gid in taken:
            continue
        free = [v for v in opts if v not in used]
        if not free:
            return None
        taken[gid] = free[0]
        used.add(free[0])
    return dict(sorted(taken.items()))


def replan(sim: ExecState, t_r: float) -> tuple[Schedule, STN, tuple[int, ...], np.ndarray] | None:
    """A new plan and schedule from the current positions (None when impossible)."""
    t_begin = time.perf_counter()
    inst = sim.instance
    g = inst.graph
    S = sim.S
    tpg = S.tpg
    reason = sim.replan_reason
    if g.kind != "grid":
        sim.log_event(t_r, "-", "replan", "none", 0.0, "re-planning needs a grid map")
        return None
    K = tpg.num_agents
    margin = sim.schedule0.margin
    radius = np.array([a.kinematics.radius for a in inst.agents], dtype=float)
    r_max = float(radius.max())
    extra_blocked = np.zeros(g.n, dtype=bool)
    options: dict[int, list[int]] = {}
    holds: dict[int, tuple[float, np.ndarray, float]] = {}
    goals: dict[int, int] = {}
    for j in range(K):
        gid = sim.gid[j]
        h = _last_happened(sim, j)
        if sim.broken[gid]:
            continue
        options[gid] = _start_options(sim, h)
        goals[gid] = int(tpg.node_vertex[int(tpg.agent_ptr[j + 1]) - 1])
    starts = _distinct_starts(options)
    if starts is None:
        sim.log_event(t_r, "-", "replan", "none", 0.0, "two robots would start at one vertex")
        return None
    for j in range(K):
        gid = sim.gid[j]
        if gid not in starts:
            continue
        h = _last_happened(sim, j)
        t_h = float(np.nanmax([sim.t[h], sim.traj[gid][-1][0]]))
        p_h = sim.traj[gid][-1][1]
        v_max = inst.agents[gid].kinematics.v_max
        dist = float(np.linalg.norm((g.coords[starts[gid]] - p_h) * sim.scale))
        holds[gid] = (max(t_h, t_r), p_h, dist / v_max)
    for gid in np.flatnonzero(sim.broken).tolist():
        # Where it physically stands (its footprint), not the vertex it had claimed.
        p = sim.traj[gid][-1][1] * sim.scale
        extra_blocked[footprint_vertices(g, p, radius[gid] + r_max + margin)] = True
    for s in starts.values():
        extra_blocked[s] = False  # never block a robot's own start
    gid2 = tuple(sorted(starts))
    if not gid2:
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
    inst2 = Instance(graph, agents, (), None, f"{inst.name}-replan")
    planned = _solve(sim, inst2, margin)
    if planned.schedule is None:
        sim.log_event(t_r, "-", "replan", "none", 0.0, planned.why)
        return None
    res, solver, sched = planned.result, planned.solver, planned.schedule
    solve_time = planned.solve_time
    assert res.plan is not None
    sim.replans.append((inst2, res.plan))
    assert sched.stn is not None
    stn = sched.stn
    tpg2 = stn.tpg
    release = np.array(stn.release, dtype=float)
    deadline = np.array(stn.deadline, dtype=float)
    t_hand = time.perf_counter()
    # Hand-over: robots first reach their start vertices (in index order when two
    # ways to a start vertex come close), then new paths wait for nearby hand-overs.
    ready: dict[int, float] = {}
    ways = {gid: _way(sim, gid, t_r, g.coords[starts[gid]]) * sim.scale for gid in gid2}
    near = _Near(ways, gid2)
    rad2 = radius[np.array(gid2)]
    deps: list[tuple[str, int, int, int]] = []
    # The last piece of each way (into its start vertex) against the earlier ways.
    last = np.array([ways[gid][-2:] if len(ways[gid]) > 1 else ways[gid][[0, 0]] for gid in gid2])
    close_last = near.first_close(last[:, 0], last[:, 1], np.arange(len(gid2)), rad2, margin)
    for k, gid in enumerate(gid2):
        t_h, p_h, move = holds[gid]
        depart = t_h
        for a in sorted(a for a in close_last.get(k, {}) if a < k):
            depart = max(depart, ready[gid2[a]])
            deps.append(("depart", gid, -1, gid2[a]))
        if depart > t_h + 1e-12:
            sim.record(gid, depart, p_h)
        ready[gid] = depart + move
    for j, gid in enumerate(gid2):
        v0 = int(tpg2.agent_ptr[j])
        release[v0] = ready[gid]
        deadline[v0] = np.inf
    # Each new path's first piece that comes close to another robot's way waits until
    # that robot has reached its start vertex.
    ptr = tpg2.agent_ptr
    owner = tpg2.node_agent
    nxt = np.minimum(np.arange(tpg2.num_nodes) + 1, np.repeat(ptr[1:] - 1, np.diff(ptr)))
    close = near.first_close(tpg2.node_pos, tpg2.node_pos[nxt], owner, rad2, margin)
    for j, gid in enumerate(gid2):
        for a, v in sorted(close.get(j, {}).items()):
            if a == j:
                continue
            release[v] = max(release[v], ready[gid2[a]])
            deps.append(("node", gid, v, gid2[a]))
    sim.handover[len(sim.phases)] = deps
    new_stn = stn.with_bounds(release=release, deadline=deadline)
    sched, times = rescheduled(sched, new_stn)
    sim.replan_margins.append(float(sched.margin))
    at = f", margin {sched.margin:g} m" if sched.margin < margin else ""
    t_end = time.perf_counter()
    layer = sim.frontier_time + (t_end - t_begin)
    handover = t_end - t_hand
    sim.replan_timing.append(
        {
            "time": t_r,
            "robots": len(gid2),
            "solver": solver,
            "frontier": sim.frontier_time,
            "solve": solve_time,
            "post": planned.post_time,
            "handover": handover,
            "layer": layer,
        }
    )
    sim.log_event(
        t_r,
        "-",
        "replan",
        "replan",
        0.0,
        f"{reason}: new plan for {len(gid2)} robots ({solver}, cost {res.cost}{at}, solve "
        f"{solve_time:.3g} s, whole layer {layer:.3g} s)",
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
    sim: ExecState,
    t_r: float,
    g: Graph,
    graph: Graph,
    gid2: tuple[int, ...],
    starts: dict[int, int],
    goals: dict[int, int],
) -> None:
    """A robot whose goal is blocked by a broken robot, or cut off from its start,
    heads for the nearest vertex it can reach instead (logged)."""

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
        sim.log_event(
            t_r,
            sim.names[gid],
            "goal",
            "replan",
            0.0,
            f"its goal {g.location(goal)} is blocked or cut off: it heads for {g.location(v)}",
        )


def _way(sim: ExecState, gid: int, t_r: float, start: np.ndarray) -> np.ndarray:
    """A robot's positions from ``t_r`` to its start vertex (instance coordinates)."""
    tr = sim.traj[gid]
    ts = np.array([t for t, _ in tr])
    ps = np.array([p for _, p in tr])
    keep = ts >= t_r
    at = np.array([np.interp(t_r, ts, ps[:, k]) for k in range(ps.shape[1])])
    pts = np.vstack([at[None, :], ps[keep], start[None, :]])
    return pts


def near_pairs(q: np.ndarray, p: np.ndarray, reach: float) -> tuple[np.ndarray, np.ndarray]:
    """Every pair ``(i, k)`` with ``|q[i] - p[k]| < reach`` (index arrays), by hashing
    ``p`` into a grid of cells ``reach`` wide: near-linear in ``len(q) + len(p)`` plus
    the pairs found.

    Example
    -------
    >>> q = np.array([[0.0, 0.0], [5.0, 5.0]])
    >>> p = np.array([[0.5, 0.0], [3.0, 0.0], [5.0, 5.2]])
    >>> [x.tolist() for x in near_pairs(q, p, 1.0)]
    [[0, 1], [0, 2]]
    """
    empty = np.zeros(0, dtype=np.int64)
    if not len(q) or not len(p) or reach <= 0:
        return empty, empty
    lo = np.minimum(q.min(axis=0), p.min(axis=0))
    cq = np.floor((q - lo) / reach).astype(np.int64)
    cp = np.floor((p - lo) / reach).astype(np.int64)
    span = int(max(cq.max(), cp.max())) + 3
    dim = q.shape[1]
    weights = span ** np.arange(dim, dtype=np.int64)
    kp = (cp + 1) @ weights
    order = np.argsort(kp, kind="stable")
    kp_sorted = kp[order]
    offsets = np.array(np.meshgrid(*[[-1, 0, 1]] * dim, indexing="ij")).reshape(dim, -1).T
    qi_all, pk_all = [], []
    for off in offsets:
        key = (cq + 1 + off) @ weights
        left = np.searchsorted(kp_sorted, key, side="left")
        right = np.searchsorted(kp_sorted, key, side="right")
        count = right - left
        total = int(count.sum())
        if not total:
            continue
        qi = np.repeat(np.arange(len(q)), count)
        start = np.repeat(left - np.cumsum(count) + count, count)
        qi_all.append(qi)
        pk_all.append(order[start + np.arange(total)])
    if not qi_all:
        return empty, empty
    qi = np.concatenate(qi_all)
    pk = np.concatenate(pk_all)
    keep = np.linalg.norm(q[qi] - p[pk], axis=1) < reach
    return qi[keep], pk[keep]


class _Near:
    """The robots' ways to their start vertices, sampled every :data:`SAMPLE` metres
    and hashed into a grid (:func:`near_pairs`), to find the segments that come close
    to them (hand-over)."""

    def __init__(self, ways: dict[int, np.ndarray], gid2: tuple[int, ...]) -> None:
        pts, own = [], []
        for k, gid in enumerate(gid2):
            way = ways[gid]
            a, b = way[:-1], way[1:]
            n = np.maximum(1, np.ceil(np.linalg.norm(b - a, axis=1) / SAMPLE).astype(int))
            samples = [way[:1]]
            for m, (p, q) in enumerate(zip(a, b, strict=True)):
                f = np.arange(1, n[m] + 1)[:, None] / n[m]
                samples.append(p + f * (q - p))
            block = np.vstack(samples)
            pts.append(block)
            own.append(np.full(len(block), k))
        self.pts = np.vstack(pts)
        self.own = np.concatenate(own)

    def first_close(
        self,
        a: np.ndarray,
        b: np.ndarray,
        seg_owner: np.ndarray,
        radius: np.ndarray,
        margin: float,
    ) -> dict[int, dict[int, int]]:
        """``{owner: {way: first segment}}``: for each owner of segments ``a[s] -> b[s]``
        (in order) and each way that comes within ``r + r' + margin`` (plus the
        sampling step; point robots: within the sampling step) of one of them, the
        first such segment."""
        if not len(a):
            return {}
        mid = (a + b) / 2
        half = np.linalg.norm(b - a, axis=1) / 2
        r_max = float(radius.max())
        reach = half + r_max * 2 + margin + 2 * SAMPLE
        seg, pt = near_pairs(mid, self.pts, float(reach.max()))
        if not len(seg):
            return {}
        p = self.pts[pt]
        ab = b[seg] - a[seg]
        L = np.einsum("ij,ij->i", ab, ab)
        f = np.clip(np.einsum("ij,ij->i", p - a[seg], ab) / np.where(L > 0, L, 1.0), 0, 1)
        d = np.linalg.norm(a[seg] + f[:, None] * ab - p, axis=1)
        so, wo = seg_owner[seg], self.own[pt]
        need = radius[so] + radius[wo] + margin
        ok = d < need + SAMPLE
        out: dict[int, dict[int, int]] = {}
        for s_, o, w in zip(seg[ok].tolist(), so[ok].tolist(), wo[ok].tolist(), strict=True):
            first = out.setdefault(o, {})
            if w not in first or s_ < first[w]:
                first[w] = s_
        return out
