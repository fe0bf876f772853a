"""Precedences that keep a robot behind the one it follows, whatever their speeds.

The schedule's precedences sit at the safety markers around shared vertices. They
order robots that *cross* at a vertex, whatever their speeds, but not a robot that
*follows* another along the same edge: between the markers the follower may catch up
with a leader that slows down. MAPF-POST bounds that case through the schedule's
speeds (``2 delta v_slow / v_fast``), a bound a refined robot that stops at corners no
longer obeys (a refined leader that dawdles mid-edge is caught: the verifier finds
such collisions without this module).

For every directed edge ``u -> w`` that robot ``j`` and later robot ``k`` both traverse
(and could occupy at the same time: ``earliest_k(u) < latest_j(w)``), this module adds
*following points*: ``k``'s points at ``x_i = i * ell / n`` along the edge
(``i = 0..n``) and ``j``'s points a path distance ``G`` further along *its* path, with
the precedence "``j`` passes ``x_i + G`` before ``k`` passes ``x_i``". While ``k`` is
between ``x_i`` and ``x_{i+1}``, ``j`` is then at least ``x_i + G`` along its path, so
the two are at least the distance between ``k``'s sub-segment and ``j``'s path from
that point to the end of the edge it is on (beyond, the markers of that vertex keep
the two apart) or to where ``j``'s windows let it be (``G - ell / n`` on a straight
line). ``G`` is at most the leader's lead in the schedule (so the schedule satisfies
the new precedences, and decoupling works as before); ``n`` (up to ``max_points``) and
``G`` are chosen to reach the schedule's safety distance when the schedule allows it,
with as much slack as possible.

The distance each pair is guaranteed is computed here (an argument, not a proof: a
leader whose path later comes back near the edge is covered by the other precedences
and the map's clearance); :func:`hierplan_opt.trajectory.verify.verify` measures the
real minimum.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from hierplan_opt.schedule.replay import segment_distance
from hierplan_opt.trajectory.events import EventNetwork

#: Largest number of sub-segments per followed edge.
MAX_POINTS = 8
#: Following points closer than this (metres of path) to an event reuse the event.
MERGE_TOL = 1e-9


@dataclass(frozen=True)
class Following:
    """What :func:`add_following` did."""

    pairs: int  # (leader, follower, edge) triples that got following points
    points: int  # new events
    arcs: int  # new precedences
    distance: float  # smallest distance the following points guarantee (inf: none)


def _arc_lengths(net: EventNetwork, j: int) -> np.ndarray:
    r = net.events(j)
    P = net.pos[r.start : r.stop]
    return np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(P, axis=0), axis=1))])


def _point_at(P: np.ndarray, S: np.ndarray, s: float) -> np.ndarray:
    k = int(np.clip(np.searchsorted(S, s, side="right") - 1, 0, len(S) - 2))
    seg = S[k + 1] - S[k]
    f = 0.0 if seg <= 0 else (s - S[k]) / seg
    return P[k] + min(max(f, 0.0), 1.0) * (P[k + 1] - P[k])


def _path_piece(P: np.ndarray, S: np.ndarray, s0: float, s1: float) -> np.ndarray:
    """The polyline from arc length ``s0`` to ``s1`` (points)."""
    s1 = min(s1, float(S[-1]))
    s0 = min(s0, s1)
    a, b = int(np.searchsorted(S, s0, side="right")), int(np.searchsorted(S, s1, side="left"))
    return np.vstack([_point_at(P, S, s0)[None], P[a:b], _point_at(P, S, s1)[None]])


def add_following(
    net: EventNetwork,
    target: float | None = None,
    max_points: int = MAX_POINTS,
    split: float = 0.5,
) -> tuple[EventNetwork, Following]:
    """``net`` with following points and their precedences (see the module docstring).

    ``target`` is the distance to guarantee (default: the schedule's safety distance);
    0 adds nothing. The decoupled windows of ``net`` (with ``split``) tell which robots
    can be on an edge together and how far a leader can be at most; the windows of the
    returned network are tighter, so both stay sound.

    Example
    -------
    >>> from hierplan_opt.core.graph import Graph
    >>> from hierplan_opt.core.instance import Instance
    >>> from hierplan_opt.core.plan import Plan
    >>> from hierplan_opt.schedule import postprocess
    >>> from hierplan_opt.trajectory.events import from_schedule
    >>> g = Graph.grid(5, 1)
    >>> inst = Instance.mapf(g, [(1, 0), (0, 0)], [(4, 0), (3, 0)])
    >>> net = from_schedule(postprocess(inst, Plan.from_paths([[1, 2, 3, 4], [0, 1, 2, 3]])))
    >>> net2, info = add_following(net)
    >>> info.pairs, info.distance >= net.safety_distance
    (2, True)
    """
    target = net.safety_distance if target is None else float(target)
    if not target > 0 or net.num_agents < 2:
        return net, Following(0, 0, 0, math.inf)
    from hierplan_opt.trajectory.windows import decouple

    K = net.num_agents
    S = [_arc_lengths(net, j) for j in range(K)]
    Pj = [net.pos[net.events(j).start : net.events(j).stop] for j in range(K)]
    Tj = [net.times[net.events(j).start : net.events(j).stop] for j in range(K)]
    w0 = decouple(net, split)
    # A robot passes an event after every earlier event's window opens and before every
    # later event's window closes.
    LO = [np.maximum.accumulate(w0.lo[net.events(j).start : net.events(j).stop]) for j in range(K)]
    VX = [np.array([net.kind[e] == "vertex" for e in net.events(j)], dtype=bool) for j in range(K)]
    HI = [
        np.minimum.accumulate(w0.hi[net.events(j).start : net.events(j).stop][::-1])[::-1]
        for j in range(K)
    ]

    # ---- directed edges and who traverses them, in order ---------------------------------
    edges: dict[tuple, list[tuple[float, int, int, int]]] = {}
    for j in range(K):
        r = net.events(j)
        vs = [i for i in range(len(r)) if net.kind[r.start + i] == "vertex"]
        for a, b in zip(vs[:-1], vs[1:], strict=True):
            key = (
                tuple(np.round(Pj[j][a], 6).tolist()),
                tuple(np.round(Pj[j][b], 6).tolist()),
            )
            edges.setdefault(key, []).append((float(Tj[j][a]), j, a, b))

    new_pts: list[list[float]] = [[] for _ in range(K)]
    pairs: list[tuple[int, float, int, float]] = []  # (leader, s_leader, follower, s_follower)
    guaranteed = math.inf
    npairs = 0
    for trav in edges.values():
        if len(trav) < 2:
            continue
        trav.sort()
        for (_, j, aj, bj), (_, k, ak, bk) in zip(trav[:-1], trav[1:], strict=True):
            if j == k:
                continue
            if LO[k][ak] >= HI[j][bj]:
                continue  # k enters the edge only after j has left it
            best = _choose(
                (S[j], Pj[j], Tj[j], LO[j], VX[j]),
                aj,
                (S[k], Pj[k], Tj[k], HI[k]),
                ak,
                bk,
                target,
                max_points,
            )
            if best is None:
                continue
            g, G, n = best
            guaranteed = min(guaranteed, g)
            npairs += 1
            sj0, sk0 = float(S[j][aj]), float(S[k][ak])
            ell = float(S[k][bk] - S[k][ak])
            for i in range(n + 1):
                x = ell * i / n
                s_lead = min(sj0 + x + G, float(S[j][-1]))
                s_follow = sk0 + x
                new_pts[j].append(s_lead)
                new_pts[k].append(s_follow)
                pairs.append((j, s_lead, k, s_follow))
    if not pairs:
        return net, Following(0, 0, 0, guaranteed)
    return _insert(net, S, Pj, Tj, new_pts, pairs, npairs, guaranteed)


def _choose(
    leader: tuple[np.ndarray, ...],
    aj: int,
    follower: tuple[np.ndarray, ...],
    ak: int,
    bk: int,
    target: float,
    max_points: int,
) -> tuple[float, float, int] | None:
    """``(guaranteed distance, G, n)`` for one leader/follower/edge, or None.

    ``leader`` is ``(arc lengths, positions, schedule times, earliest passage, is a
    vertex)`` of the leader's events, ``follower`` the first three and the latest passage.
    """
    Sj, Pj, Tj, LOj, Vj = leader
    Sk, Pk, Tk, HIk = follower
    sj0, sk0 = float(Sj[aj]), float(Sk[ak])
    ell = float(Sk[bk] - sk0)
    u, w = Pk[ak], Pk[bk]
    best: tuple[float, float, int] | None = None
    for n in range(1, max_points + 1):
        xs = ell * np.arange(n + 1) / n
        t_follow = np.interp(sk0 + xs, Sk, Tk)
        lead = np.interp(t_follow, Tj, Sj)  # leader's path position in the schedule
        G_max = float(np.min(lead - sj0 - xs))
        if G_max <= 0:
            continue

        def guarantee(G: float, xs: np.ndarray = xs, n: int = n) -> float:
            # Sub-segment i of the follower against the leader's path from x_i + G on.
            A, B, C, D = [], [], [], []
            for i in range(n):
                s0 = sj0 + xs[i] + G
                # The follower leaves sub-segment i by the latest passage of its next
                # event; until then the leader cannot pass an event whose window is
                # still closed.
                q = int(np.searchsorted(Sk, sk0 + xs[i + 1] - 1e-9))
                t_by = float(HIk[min(q, len(Sk) - 1)])
                r = int(np.searchsorted(LOj, t_by, side="right"))
                s_cap = float(Sj[r]) if r < len(Sj) else float(Sj[-1])
                # Past the end of the edge it is on, the leader is kept away by the
                # markers of that vertex (and the clearance of the map).
                nxt = Sj[Vj & (Sj > s0 + 1e-9)]
                if len(nxt):
                    s_cap = min(s_cap, float(nxt[0]))
                poly = _path_piece(Pj, Sj, s0, max(s_cap, s0))
                if len(poly) == 1:
                    poly = np.vstack([poly, poly])
                m = len(poly) - 1
                a = u + (w - u) * (xs[i] / ell)
                b = u + (w - u) * (xs[i + 1] / ell)
                A.append(np.repeat(a[None], m, axis=0))
                B.append(np.repeat(b[None], m, axis=0))
                C.append(poly[:-1])
                D.append(poly[1:])
            d = segment_distance(np.vstack(A), np.vstack(B), np.vstack(C), np.vstack(D))
            return float(d.min())

        # Euclidean distance is at most path distance: no n with G_max - ell/n below the
        # target can reach it, whatever the geometry.
        if n == max_points:  # the fallback: as close to the target as the lead allows
            best = (guarantee(G_max), G_max, n)
        if G_max - ell / n < target:
            continue
        # On a straight line G = target + ell/n is exactly enough; around a corner the
        # smallest sufficient G lies between that and G_max (bisection).
        lo = target + ell / n
        if guarantee(lo) >= target:
            return target, lo, n
        if guarantee(G_max) < target:
            continue
        hi = G_max
        for _ in range(10):
            mid = 0.5 * (lo + hi)
            if guarantee(mid) >= target:
                hi = mid
            else:
                lo = mid
        return target, hi, n
    return best


def _insert(
    net: EventNetwork,
    S: list[np.ndarray],
    Pj: list[np.ndarray],
    Tj: list[np.ndarray],
    new_pts: list[list[float]],
    pairs: list[tuple[int, float, int, float]],
    npairs: int,
    guaranteed: float,
) -> tuple[EventNetwork, Following]:
    K = net.num_agents
    # Per robot: sorted arc lengths of old events and new points (merged when equal).
    old_ids: list[int] = []
    agent_l: list[int] = []
    sig_l: list[float] = []
    ptr = [0]
    lookup: list[dict[float, int]] = []
    for j in range(K):
        r = net.events(j)
        base = np.asarray(S[j])
        extra = np.unique(np.round(np.asarray(new_pts[j], dtype=float), 9))
        keep = []
        for s in extra.tolist():
            k = int(np.searchsorted(base, s))
            near = any(
                0 <= q < len(base) and abs(float(base[q]) - s) <= MERGE_TOL for q in (k - 1, k)
            )
            if not near:
                keep.append(s)
        sig = np.concatenate([base, np.asarray(keep, dtype=float)])
        ids = np.concatenate([np.arange(r.start, r.stop), np.full(len(keep), -1)])
        order = np.argsort(sig, kind="stable")
        sig, ids = sig[order], ids[order]
        table = {}
        for q in range(len(sig)):
            table[round(float(sig[q]), 9)] = len(sig_l) + q
        lookup.append(table)
        old_ids.extend(ids.tolist())
        agent_l.extend([j] * len(sig))
        sig_l.extend(sig.tolist())
        ptr.append(len(sig_l))
    old = np.asarray(old_ids, dtype=np.int64)
    virt = old < 0
    src_old = np.where(virt, 0, old)
    agent = np.asarray(agent_l, dtype=np.int64)
    sig_all = np.asarray(sig_l, dtype=float)
    pos = net.pos[src_old].copy()
    times = net.times[src_old].copy()
    for q in np.flatnonzero(virt).tolist():
        j = int(agent[q])
        pos[q] = _point_at(Pj[j], S[j], float(sig_all[q]))
        times[q] = float(np.interp(sig_all[q], S[j], Tj[j]))
    old_to_new = np.empty(net.num_events, dtype=np.int64)
    old_to_new[old[~virt]] = np.flatnonzero(~virt)

    def find(j: int, s: float) -> int:
        key = round(s, 9)
        if key in lookup[j]:
            return lookup[j][key]
        base = S[j]
        k = int(np.argmin(np.abs(base - s)))
        return int(old_to_new[net.events(j).start + k])

    add_src = np.array([find(j, sj) for j, sj, _, _ in pairs], dtype=np.int64)
    add_dst = np.array([find(k, sk) for _, _, k, sk in pairs], dtype=np.int64)
    kinds = tuple("follow" if v else net.kind[int(o)] for v, o in zip(virt, old, strict=True))
    label_old = net.label
    names = net.agent_names

    def label(v: int) -> str:
        if virt[v]:
            c = ", ".join(f"{x:.6g}" for x in pos[v] / net.scale)
            return f"{names[int(agent[v])]} following point ({c})"
        return label_old(int(old[v]))

    def pick(a: np.ndarray, fill: float) -> np.ndarray:
        out = a[src_old].astype(float)
        out[virt] = fill
        return out

    new = EventNetwork(
        agent_names=names,
        agent_ptr=np.asarray(ptr, dtype=np.int64),
        agent=agent,
        kind=kinds,
        pos=pos,
        coord=pos / net.scale,
        times=times,
        earliest=np.where(virt, np.minimum(0.0, times), net.earliest[src_old]),
        latest=np.where(virt, np.inf, net.latest[src_old]),
        release=pick(net.release, 0.0),
        deadline=pick(net.deadline, np.inf),
        arc_src=np.concatenate([old_to_new[net.arc_src], add_src]),
        arc_dst=np.concatenate([old_to_new[net.arc_dst], add_dst]),
        arc_lb=np.concatenate([net.arc_lb, np.zeros(len(pairs))]),
        arc_ub=np.concatenate([net.arc_ub, np.full(len(pairs), np.inf)]),
        waypoint=np.where(virt, -1, net.waypoint[src_old]),
        scale=net.scale,
        safety_distance=net.safety_distance,
        label=label,
    )
    for name in new.__dataclass_fields__:
        val = getattr(new, name)
        if isinstance(val, np.ndarray):
            val.setflags(write=False)
    # Self-arcs (a leader point merged with the follower's own event) cannot happen:
    # leader and follower are different robots.
    return new, Following(npairs, int(virt.sum()), len(pairs), guaranteed)
