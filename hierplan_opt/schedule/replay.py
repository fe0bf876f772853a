"""Checks of a schedule: continuous-time replay and STN bounds.

Replay: every robot moves in a straight line at constant speed between consecutive
way-points (and stays at its last one). For two robots the relative position is
piecewise linear in time, so the closest approach on each piece has a closed form;
the minimum over all pieces and pairs is the exact minimum distance of the replay.
Pairs of robots that never visit a common vertex are always on vertex-disjoint
segments of the map, at least the map's *clearance* apart (one cell on grids); they
are skipped on grids and on large roadmaps, and reported through the clearance.

Guaranteed distance (``delta > 0``): with the augmented TPG a robot comes within
``delta`` of a vertex only after the previous visitor is ``delta`` beyond it. At a
shared vertex this keeps two robots at least ``delta * a`` apart, where ``a = 1`` if
no two edges used at a vertex meet at less than 90 degrees, else ``sin`` of the
sharpest such angle. A robot that follows another along the same edge may catch up
between markers; while the leader travels ``2 delta`` around the next vertex (at most
``v_fast``), the follower still needs the marker and moves at least ``v_slow``, so the
gap stays at least ``2 delta v_slow / v_fast`` (the reference implementation's
``2 delta / (R* v_max)``). Markers of one move are ``ell - 2 delta`` apart, and
vertex-disjoint segments are ``clearance`` apart. The guarantee is the minimum of
these four terms, where ``v_slow`` and ``v_fast`` are the slowest and fastest
way-point-to-way-point speeds of the schedule. The maximum-safety LP raises
``v_slow`` (it minimises ``R = 1 / v_slow``). The derivation is a sketch, not a
proof; tests replay random plans against it.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np

from hierplan_opt.core.instance import Instance
from hierplan_opt.schedule.output import Schedule
from hierplan_opt.schedule.stn import STN
from hierplan_opt.schedule.tpg import TPG, VERTEX

TOL = 1e-6


# ---------------------------------------------------------------------- geometry
@dataclass(frozen=True)
class Geometry:
    """What the guarantee needs from the map and the plan's segments (metres)."""

    clearance: float  # min distance between vertex-disjoint used segments / points
    angle_factor: float  # 1, or sin of the sharpest (< 90 deg) angle at a used vertex
    shortest_move: float  # shortest geometric length of a move in the plan


def segment_distance(p1: np.ndarray, q1: np.ndarray, p2: np.ndarray, q2: np.ndarray) -> np.ndarray:
    """Distances between segments ``p1q1`` and ``p2q2`` (row-wise arrays, any dim).

    Example
    -------
    >>> a = np.array([[0.0, 0.0]]); b = np.array([[1.0, 0.0]])
    >>> segment_distance(a, b, np.array([[0.5, 2.0]]), np.array([[3.0, 2.0]])).tolist()
    [2.0]
    >>> segment_distance(a, b, np.array([[0.5, -1.0]]), np.array([[0.5, 1.0]])).tolist()
    [0.0]
    """
    d1 = q1 - p1
    d2 = q2 - p2
    r = p1 - p2
    a = np.einsum("ij,ij->i", d1, d1)
    e = np.einsum("ij,ij->i", d2, d2)
    f = np.einsum("ij,ij->i", d2, r)
    c = np.einsum("ij,ij->i", d1, r)
    b = np.einsum("ij,ij->i", d1, d2)
    denom = a * e - b * b
    safe_a = np.where(a > 0, a, 1.0)
    safe_e = np.where(e > 0, e, 1.0)
    with np.errstate(divide="ignore", invalid="ignore"):
        s = np.where(
            denom > 1e-12, np.clip((b * f - c * e) / np.where(denom > 0, denom, 1), 0, 1), 0
        )
    t = np.where(e > 0, (b * s + f) / safe_e, 0.0)
    low = t < 0
    high = t > 1
    t = np.clip(t, 0, 1)
    s = np.where(low, np.clip(-c / safe_a, 0, 1), s)
    s = np.where(high, np.clip((b - c) / safe_a, 0, 1), s)
    s = np.where(a > 0, s, 0.0)
    t = np.where((a <= 0) & (e > 0), np.clip(f / safe_e, 0, 1), t)
    diff = p1 + d1 * s[:, None] - p2 - d2 * t[:, None]
    return np.sqrt(np.einsum("ij,ij->i", diff, diff))


def plan_geometry(instance: Instance, tpg: TPG) -> Geometry:
    """Clearance, sharpest-angle factor and shortest move of the plan's segments."""
    g = instance.graph
    scale = g.cell_size if g.kind == "grid" else 1.0
    V = tpg.node_vertex[tpg.node_kind == VERTEX]
    A = tpg.node_agent[tpg.node_kind == VERTEX]
    same = A[1:] == A[:-1]
    us, vs = V[:-1][same], V[1:][same]
    if len(us):
        pu = g.coords[us] * scale
        pv = g.coords[vs] * scale
        shortest = float(np.linalg.norm(pv - pu, axis=1).min())
    else:
        shortest = math.inf
    if g.kind == "grid":
        # Vertex-disjoint unit segments / points of a lattice are >= one cell apart,
        # and used edges meet at 90 or 180 degrees.
        return Geometry(float(g.cell_size), 1.0, shortest)
    segs = {(min(a, b), max(a, b)) for a, b in zip(us.tolist(), vs.tolist(), strict=True)}
    moving = set(A[np.flatnonzero(same)].tolist()) if len(us) else set()
    for j in range(tpg.num_agents):
        if j not in moving:
            v = int(tpg.node_vertex[tpg.agent_ptr[j]])
            segs.add((v, v))
    seg = np.array(sorted(segs), dtype=np.int64).reshape(-1, 2)
    P = g.coords[seg[:, 0]].astype(float)
    Q = g.coords[seg[:, 1]].astype(float)
    # Clearance over vertex-disjoint pairs.
    clearance = math.inf
    m = len(seg)
    if m > 1:
        ii, jj = np.triu_indices(m, 1)
        disjoint = (
            (seg[ii, 0] != seg[jj, 0])
            & (seg[ii, 0] != seg[jj, 1])
            & (seg[ii, 1] != seg[jj, 0])
            & (seg[ii, 1] != seg[jj, 1])
        )
        ii, jj = ii[disjoint], jj[disjoint]
        for k0 in range(0, len(ii), 200_000):
            sl = slice(k0, k0 + 200_000)
            d = segment_distance(P[ii[sl]], Q[ii[sl]], P[jj[sl]], Q[jj[sl]])
            if d.size:
                clearance = min(clearance, float(d.min()))
    # Sharpest angle between two distinct used edges at a common vertex.
    dirs: dict[int, list[np.ndarray]] = {}
    for a, b in seg.tolist():
        if a == b:
            continue
        d = g.coords[b] - g.coords[a]
        n = float(np.linalg.norm(d))
        dirs.setdefault(a, []).append(d / n)
        dirs.setdefault(b, []).append(-d / n)
    factor = 1.0
    for ds in dirs.values():
        for x, y in itertools.combinations(ds, 2):
            cos = float(np.dot(x, y))
            if cos > 1e-12:
                factor = min(factor, math.sqrt(max(0.0, 1.0 - cos * cos)))
    return Geometry(clearance, factor, shortest)


def speed_range(schedule: Schedule) -> tuple[float, float]:
    """Slowest and fastest way-point-to-way-point speed of moving segments (m/s)."""
    slow, fast = math.inf, 0.0
    for wp in schedule.waypoints:
        if len(wp) < 2:
            continue
        dist = np.linalg.norm(np.diff(wp.coords, axis=0), axis=1) * schedule.scale
        dt = np.diff(wp.arrival)
        mv = dist > 1e-12
        if mv.any():
            sp = dist[mv] / np.maximum(dt[mv], 1e-300)
            slow = min(slow, float(sp.min()))
            fast = max(fast, float(sp.max()))
    return slow, fast


def guaranteed_distance(delta: float, geometry: Geometry, v_slow: float, v_fast: float) -> float:
    """The safety distance the augmented TPG guarantees (0 for the plain TPG).

    Example
    -------
    >>> guaranteed_distance(0.25, Geometry(1.0, 1.0, 1.0), 1.0, 1.0)
    0.25
    >>> guaranteed_distance(0.25, Geometry(1.0, 1.0, 1.0), 0.25, 1.0)
    0.125
    """
    if delta <= 0:
        return 0.0
    if not math.isfinite(v_slow) or v_fast <= 0:  # no robot moves
        return float(geometry.clearance) if math.isfinite(geometry.clearance) else math.inf
    return float(
        min(
            geometry.clearance,
            delta * geometry.angle_factor,
            2.0 * delta * v_slow / v_fast,
            geometry.shortest_move - 2.0 * delta,
        )
    )


# ---------------------------------------------------------------------- replay
@dataclass(frozen=True)
class ReplayReport:
    """Result of :func:`replay`: the minimum distance, where and when it happens."""

    min_distance: float
    agents: tuple[str, str] | None
    time: float | None
    pairs_checked: int
    pairs_skipped: int
    skipped_bound: float  # skipped pairs are at least this far apart


def _trajectory(schedule: Schedule, j: int) -> tuple[np.ndarray, np.ndarray]:
    wp = schedule.waypoints[j]
    return wp.arrival, wp.coords * schedule.scale


def _pair_min(ta: np.ndarray, pa: np.ndarray, tb: np.ndarray, pb: np.ndarray):  # noqa: ANN202
    tau = np.union1d(ta, tb)
    ra = np.stack([np.interp(tau, ta, pa[:, k]) for k in range(pa.shape[1])], axis=1)
    rb = np.stack([np.interp(tau, tb, pb[:, k]) for k in range(pb.shape[1])], axis=1)
    r = ra - rb
    if len(tau) == 1:
        d = float(np.linalg.norm(r[0]))
        return d, float(tau[0])
    r0 = r[:-1]
    dr = r[1:] - r[:-1]
    dd = np.einsum("ij,ij->i", dr, dr)
    s = np.where(dd > 0, np.clip(-np.einsum("ij,ij->i", r0, dr) / np.where(dd > 0, dd, 1), 0, 1), 0)
    closest = r0 + dr * s[:, None]
    dist = np.sqrt(np.einsum("ij,ij->i", closest, closest))
    k = int(np.argmin(dist))
    last = float(np.linalg.norm(r[-1]))
    if last < dist[k]:
        return last, float(tau[-1])
    return float(dist[k]), float(tau[k] + s[k] * (tau[k + 1] - tau[k]))


def replay(
    schedule: Schedule, instance: Instance | None = None, *, all_pairs: bool | None = None
) -> ReplayReport:
    """Exact minimum centre distance between any two robots in a constant-velocity replay.

    With ``instance`` given, pairs that never share a vertex are skipped on grids (they
    stay at least one cell apart); ``all_pairs=True`` checks every pair.

    Example
    -------
    >>> from hierplan_opt.core.graph import Graph
    >>> from hierplan_opt.core.plan import Plan
    >>> from hierplan_opt.schedule import postprocess
    >>> g = Graph.grid(3, 2)
    >>> inst = Instance.mapf(g, [(0, 0), (0, 1)], [(2, 0), (2, 1)])
    >>> s = postprocess(inst, Plan.from_paths([[0, 1, 2], [3, 4, 5]]), delta=0.25)
    >>> replay(s).min_distance  # two robots side by side, one cell apart
    1.0
    """
    K = schedule.num_agents
    stn = schedule.stn
    if all_pairs is None:
        all_pairs = instance is None or instance.graph.kind != "grid" or stn is None
    pairs: list[tuple[int, int]]
    skipped_bound = math.inf
    if all_pairs:
        pairs = [(a, b) for a in range(K) for b in range(a + 1, K)]
    else:
        assert stn is not None and instance is not None
        tpg = stn.tpg
        vk = tpg.node_kind == VERTEX
        by_vertex: dict[int, set[int]] = {}
        for v, a in zip(tpg.node_vertex[vk].tolist(), tpg.node_agent[vk].tolist(), strict=True):
            by_vertex.setdefault(v, set()).add(a)
        ps: set[tuple[int, int]] = set()
        for agents in by_vertex.values():
            if len(agents) > 1:
                ag = sorted(agents)
                ps.update(itertools.combinations(ag, 2))
        pairs = sorted(ps)
        skipped_bound = float(instance.graph.cell_size)
    total = K * (K - 1) // 2
    best = (math.inf, None, None)
    trajs = [_trajectory(schedule, j) for j in range(K)]
    for a, b in pairs:
        d, t = _pair_min(trajs[a][0], trajs[a][1], trajs[b][0], trajs[b][1])
        if d < best[0]:
            best = (d, (schedule.agent_names[a], schedule.agent_names[b]), t)
    return ReplayReport(best[0], best[1], best[2], len(pairs), total - len(pairs), skipped_bound)


def check_bounds(stn: STN, times: np.ndarray, tol: float = TOL) -> list[str]:
    """Every STN bound the node ``times`` break (an empty list when all hold).

    Example
    -------
    >>> from hierplan_opt.core.graph import Graph
    >>> from hierplan_opt.core.plan import Plan
    >>> from hierplan_opt.schedule.tpg import build_tpg
    >>> from hierplan_opt.schedule.stn import build_stn
    >>> g = Graph.grid(2, 1)
    >>> inst = Instance.mapf(g, [(0, 0)], [(1, 0)])
    >>> stn = build_stn(inst, build_tpg(inst, Plan.from_paths([[0, 1]])))
    >>> check_bounds(stn, np.array([0.0, 1.0])), len(check_bounds(stn, np.array([0.0, 0.5])))
    ([], 1)
    """
    out = []
    tpg = stn.tpg
    diff = times[stn.arc_dst] - times[stn.arc_src]
    bad_lo = np.flatnonzero(diff < stn.lb - tol)
    bad_hi = np.flatnonzero(diff > stn.ub + tol)
    for k in bad_lo.tolist():
        u, v = int(stn.arc_src[k]), int(stn.arc_dst[k])
        out.append(
            f"{tpg.label(u)} -> {tpg.label(v)}: {diff[k]:.6g} s < lower bound {stn.lb[k]:.6g} s"
        )
    for k in bad_hi.tolist():
        u, v = int(stn.arc_src[k]), int(stn.arc_dst[k])
        out.append(
            f"{tpg.label(u)} -> {tpg.label(v)}: {diff[k]:.6g} s > upper bound {stn.ub[k]:.6g} s"
        )
    for v in np.flatnonzero(times < stn.release - tol).tolist():
        out.append(f"{tpg.label(v)}: time {times[v]:.6g} before its release {stn.release[v]:.6g}")
    for v in np.flatnonzero(times > stn.deadline + tol).tolist():
        out.append(f"{tpg.label(v)}: time {times[v]:.6g} after its deadline {stn.deadline[v]:.6g}")
    return out
