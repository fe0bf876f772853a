"""Physical clearance for MAPF-POST: robot radii -> safety markers and precedences.

The contract: at every moment, robots ``i`` and ``j`` keep their centres at least
``D_ij = r_i + r_j + margin`` apart. The plan is turned into *claims*: a robot claims a
*lock point* ``w`` (a vertex of the plan) while its centre is strictly inside the disc of
radius ``lambda_j(w)`` around ``w``. Along the robot's path a claim is an interval of arc
length ``[s_in, s_out]`` (entering and leaving the disc). For every lock the claims of
different robots are put in one order (the plan's), and each claim may begin only after
the previous one has ended: a Type-2 arc from the earlier robot's *exit marker*
``s_out`` to the later robot's *entry marker* ``s_in``. Claims of one lock are then never
held at the same time, in any motion that passes the markers in that order.

Radii (``docs/post.md`` has the proofs):

* **tight** (2D/3D grids of cell ``c`` with ``2 r_max + margin < c``, and roadmaps
  whose used edges are laid out like that: see :func:`~hierplan_opt.schedule.tpg.
  _grid_like`): ``lambda_j = c/2 + r_j + margin/2`` (``c``: the longest used edge at
  the vertex; + a relative 1e-12). Every two points of used edges closer than
  ``D_ij`` lie on edges that share a vertex, both within their robot's radius of it
  (at a right or obtuse angle ``a, b < D_ij <= lambda``; on one edge one of its two end
  points works because ``lambda_i + lambda_j >= c + D_ij``). The exit marker lies
  ``lambda_j`` beyond the vertex, past the middle of the next edge, so a follower keeps
  exactly ``D_ij`` behind its leader.
* **general** (roadmaps, and grids whose cells are smaller than ``2 r_max + margin``):
  ``lambda_j(w) = rho_w + r_j + r_max + margin`` where ``rho_w`` is half the longest
  used segment at ``w``. A robot is always within ``rho_w`` of an end point ``w`` of its
  current segment, so the other robot, closer than ``D_ij``, is within
  ``rho_w + D_ij <= lambda_j(w)`` of it. Claims then reach across several vertices.
* **none** (every radius and the margin 0, or ``clearance=False``): point robots; the
  plain temporal plan graph (a robot may enter a vertex once the previous visitor has
  left it) is used instead.

Orders per lock: claims that start at a robot's start come first, claims that end at
its goal (the robot parks inside the disc for ever) last; the others follow the plan's
discrete time of entering the disc (on grids in the tight regime this is the order in
which the robots visit the vertex). Two start claims (or two goal claims) of one lock
must not conflict (their path pieces at least ``D_ij`` apart), else no schedule exists
and :class:`ClearanceError` says so in one line.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from hierplan_opt.core.errors import InputError
from hierplan_opt.core.instance import Instance

#: Relative widening of every claim radius: makes the coverage inequalities strict.
ETA = 1e-12
#: Tolerance on the segment parameter when claims of consecutive segments touch.
T_EPS = 1e-9

REGIMES = ("none", "tight", "general")


class ClearanceError(InputError):
    """The plan's geometry cannot keep the required distance between two robots."""


def finite_nonnegative(value: object, message: str) -> float:
    """``value`` as a float when it is a finite number >= 0, else ``InputError(message)``.

    Example
    -------
    >>> finite_nonnegative(2, "margin")
    2.0
    """
    if (
        isinstance(value, bool)
        or not isinstance(value, (int, float, np.floating, np.integer))
        or not math.isfinite(value)
        or value < 0
    ):
        raise InputError(message)
    return float(value)


#: Default margin for point robots, as a fraction of the shortest edge.
DEFAULT_MARGIN_FRACTION = 0.1


def shortest_edge(graph) -> float:
    """The shortest straight edge of a map in metres (grids: the cell size).

    Example
    -------
    >>> from hierplan_opt.core.graph import Graph
    >>> shortest_edge(Graph.grid(3, 2, cell_size=0.5))
    0.5
    """
    if graph.kind == "grid":
        return float(graph.cell_size)
    src = np.repeat(np.arange(graph.n), np.diff(graph.indptr))
    dst = np.asarray(graph.indices)
    if not len(src):
        return 1.0
    d = np.linalg.norm((graph.coords[dst] - graph.coords[src]) * graph.scale, axis=1)
    d = d[d > 0]
    return float(d.min()) if len(d) else 1.0


def default_margin(instance: Instance) -> float:
    """The margin :func:`~hierplan_opt.schedule.postprocess` uses when none is given.

    ``0.1 x`` the shortest edge (:func:`shortest_edge`) when at least two robots are
    points (radius 0), so that every pair has a stated positive separation; else 0 (the
    radii already separate every pair: robots with a size keep ``r_i + r_j``).

    Example
    -------
    >>> from hierplan_opt.core.graph import Graph
    >>> g = Graph.grid(4, 1, cell_size=2.0)
    >>> default_margin(Instance.mapf(g, [(0, 0), (3, 0)], [(1, 0), (2, 0)]))
    0.2
    """
    points = sum(1 for a in instance.agents if a.kinematics.radius <= 0)
    if points < 2:
        return 0.0
    return float(round(DEFAULT_MARGIN_FRACTION * shortest_edge(instance.graph), 12))


@dataclass(frozen=True)
class PairClearance:
    """The contract for one pair of robot types: required distance, and whether the
    schedule guarantees it."""

    types: tuple[str, str]
    required: float
    guaranteed: bool

    def as_dict(self) -> dict[str, object]:
        return {
            "types": list(self.types),
            "required": self.required,
            "guaranteed": self.guaranteed,
        }


@dataclass(frozen=True, eq=False)
class Requirement:
    """Radii, robot types and margin of a fleet: ``D_ij = r_i + r_j + margin``.

    Example
    -------
    >>> from hierplan_opt.core.graph import Graph
    >>> from hierplan_opt.core.instance import Kinematics
    >>> g = Graph.grid(4, 1)
    >>> kin = [Kinematics("a", radius=0.2), Kinematics("b", radius=0.3)]
    >>> req = Requirement.of(Instance.mapf(g, [(0, 0), (3, 0)], [(1, 0), (2, 0)],
    ...                                    kinematics=kin), margin=0.1)
    >>> round(req.required(0, 1), 9), req.regime(g)
    (0.6, 'tight')
    """

    radius: np.ndarray
    types: tuple[str, ...]
    margin: float
    enforced: bool = True

    @classmethod
    def of(cls, instance: Instance, margin: float = 0.0, *, enforced: bool = True) -> Requirement:
        margin = finite_nonnegative(
            margin, f"margin must be a finite number >= 0 (metres), got {margin!r}"
        )
        radius = np.array([a.kinematics.radius for a in instance.agents], dtype=float)
        radius.setflags(write=False)
        types = tuple(a.kinematics.robot_type for a in instance.agents)
        return cls(radius, types, float(margin), bool(enforced))

    def required(self, i: int, j: int) -> float:
        return float(self.radius[i] + self.radius[j] + self.margin)

    @property
    def point_robots(self) -> bool:
        """True when no pair needs a positive distance (radii and margin all 0)."""
        return self.margin == 0 and not np.any(self.radius > 0)

    @property
    def min_required(self) -> float:
        """The smallest ``D_ij`` over all pairs (0 with fewer than two robots)."""
        if len(self.radius) < 2:
            return 0.0
        r = np.sort(self.radius)
        return float(r[0] + r[1] + self.margin)

    def regime(self, graph) -> str:
        """``none`` (point robots or not enforced), ``tight`` or ``general``."""
        if not self.enforced or self.point_robots:
            return "none"
        if graph.kind == "grid" and 2 * float(self.radius.max()) + self.margin < graph.cell_size:
            return "tight"
        return "general"

    def report(self) -> tuple[PairClearance, ...]:
        """Per unordered pair of robot types present: required distance and guarantee.

        A type's radius is the largest radius among its robots (the worst case).
        """
        rad: dict[str, float] = {}
        count: dict[str, int] = {}
        for t, r in zip(self.types, self.radius.tolist(), strict=True):
            rad[t] = max(rad.get(t, 0.0), r)
            count[t] = count.get(t, 0) + 1
        names = sorted(rad)
        out = []
        for a, b in itertools.combinations_with_replacement(names, 2):
            if a == b and count[a] < 2:
                continue
            req = rad[a] + rad[b] + self.margin
            out.append(PairClearance((a, b), round(req, 12), bool(self.enforced or req == 0)))
        return tuple(out)

    def guaranteed_distance(self) -> float:
        """The distance every pair keeps: ``min D_ij`` when enforced, else 0."""
        return self.min_required if self.enforced else 0.0


# ---------------------------------------------------------------------- geometry
@dataclass(frozen=True, eq=False)
class Segments:
    """Every robot's path as straight segments (waits merged), in metres.

    Segment ``k`` goes from visit ``origin[k]`` to visit ``origin[k] + 1`` of robot
    ``agent[k]``; robots without moves get one zero-length segment at their vertex.
    ``s0``/``length`` are arc length (``Graph.edge_length`` units) at the origin and
    along the segment; ``tau0`` is the plan's timestep at which the robot arrives at the
    origin, ``tau_move`` the step at which the move starts, ``tau_next`` the step it
    leaves the destination (``inf`` for the robot's last vertex).
    """

    agent: np.ndarray
    origin: np.ndarray
    a: np.ndarray
    b: np.ndarray
    s0: np.ndarray
    length: np.ndarray
    tau0: np.ndarray
    tau_move: np.ndarray
    tau_next: np.ndarray
    first: np.ndarray  # bool: the robot's first segment
    last: np.ndarray  # bool: the robot's last segment
    moving: np.ndarray  # bool: a real move (not a parked robot's point)


@dataclass(frozen=True, eq=False)
class Claims:
    """Claims and the precedences between them (output of :func:`claim_precedences`).

    Per claim: ``agent``, ``lock`` (index into the lock points), arc lengths ``s_in``
    and ``s_out``, segment and segment parameter of both ends, and flags ``start``
    (held from time 0) and ``final`` (held for ever). ``src``/``dst`` index the claims:
    the robot of ``dst`` may enter at ``s_in[dst]`` once the robot of ``src`` has
    reached ``s_out[src]``; where ``dst_wait`` is set, ``dst`` is a start claim and its
    robot must not leave its start before that (a *wait* node at the start).
    """

    agent: np.ndarray
    lock: np.ndarray
    s_in: np.ndarray
    s_out: np.ndarray
    seg_in: np.ndarray
    seg_out: np.ndarray
    t_in: np.ndarray
    t_out: np.ndarray
    start: np.ndarray
    final: np.ndarray
    tau_in: np.ndarray
    src: np.ndarray
    dst: np.ndarray
    dst_wait: np.ndarray


def claim_radii(
    req: Requirement, regime: str, lock_rho: np.ndarray, cell: float
) -> tuple[np.ndarray, np.ndarray]:
    """``lambda_j(w) = base_w + extra_j``: returns ``(base per lock, extra per agent)``."""
    r = req.radius
    if regime == "tight":
        scale = max(float(lock_rho.max(initial=0.0)), cell, 1e-300)
        base = lock_rho.astype(float)  # half the longest used edge at the vertex
        extra = r + req.margin / 2.0 + ETA * scale
    else:
        scale = max(float(lock_rho.max(initial=0.0)), float(r.max(initial=0.0)), req.margin)
        base = lock_rho.astype(float)
        extra = r + float(r.max(initial=0.0)) + req.margin + ETA * max(scale, 1e-300)
    return base, extra


def _segment_disc(
    a: np.ndarray, b: np.ndarray, w: np.ndarray, lam: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Parameters ``[t1, t2]`` (clipped to [0, 1]) where ``a + t (b - a)`` is strictly
    inside the disc ``|x - w| < lam``; ``t1 >= t2`` when it never is."""
    d = b - a
    aw = a - w
    qa = np.einsum("ij,ij->i", d, d)
    qb = 2.0 * np.einsum("ij,ij->i", d, aw)
    qc = np.einsum("ij,ij->i", aw, aw) - lam * lam
    t1 = np.ones(len(a))
    t2 = np.zeros(len(a))
    point = qa <= 0
    inside_pt = point & (qc < 0)
    t1[inside_pt] = 0.0
    t2[inside_pt] = 1.0
    mv = ~point
    disc = qb[mv] * qb[mv] - 4.0 * qa[mv] * qc[mv]
    ok = disc > 0
    sq = np.sqrt(np.where(ok, disc, 0.0))
    lo = (-qb[mv] - sq) / (2.0 * qa[mv])
    hi = (-qb[mv] + sq) / (2.0 * qa[mv])
    lo = np.where(ok, np.clip(lo, 0.0, 1.0), 1.0)
    hi = np.where(ok, np.clip(hi, 0.0, 1.0), 0.0)
    t1[mv] = lo
    t2[mv] = hi
    return t1, t2


def _candidates(
    seg: Segments, locks: np.ndarray, reach: np.ndarray, bucket: float
) -> tuple[np.ndarray, np.ndarray]:
    """(segment, lock) pairs whose bounding boxes, widened by ``reach`` per segment,
    share a hash bucket with the lock (a superset of the pairs within ``reach``)."""
    dim = locks.shape[1]
    origin = np.minimum(seg.a.min(axis=0), locks.min(axis=0)) - 1.0
    lo = np.floor((np.minimum(seg.a, seg.b) - reach[:, None] - origin) / bucket).astype(np.int64)
    hi = np.floor((np.maximum(seg.a, seg.b) + reach[:, None] - origin) / bucket).astype(np.int64)
    span = hi - lo + 1
    lock_cell = np.floor((locks - origin) / bucket).astype(np.int64)
    dims = np.maximum(lock_cell.max(axis=0), hi.max(axis=0)) + 1
    strides = np.ones(dim, dtype=np.int64)
    for k in range(1, dim):
        strides[k] = strides[k - 1] * dims[k - 1]
    lock_key = lock_cell @ strides
    order = np.argsort(lock_key, kind="stable")
    keys_sorted = lock_key[order]
    # Enumerate every bucket of every segment's box.
    count = np.prod(span, axis=1)
    seg_rep = np.repeat(np.arange(len(count)), count)
    local = np.arange(int(count.sum())) - np.repeat(np.cumsum(count) - count, count)
    cell = np.zeros((len(seg_rep), dim), dtype=np.int64)
    rem = local.copy()
    for k in range(dim):
        sp = span[seg_rep, k]
        cell[:, k] = lo[seg_rep, k] + rem % sp
        rem //= sp
    key = cell @ strides
    start = np.searchsorted(keys_sorted, key, side="left")
    stop = np.searchsorted(keys_sorted, key, side="right")
    n = stop - start
    pair_seg = np.repeat(seg_rep, n)
    offs = np.arange(int(n.sum())) - np.repeat(np.cumsum(n) - n, n)
    pair_lock = order[np.repeat(start, n) + offs]
    return pair_seg, pair_lock


def claim_precedences(
    seg: Segments,
    lock_pos: np.ndarray,
    base: np.ndarray,
    extra: np.ndarray,
    req: Requirement,
    *,
    describe,
) -> Claims:
    """Claims of every robot on every lock point and the precedences between them."""
    reach = base.max(initial=0.0) + extra[seg.agent]
    bucket = max(float(base.max(initial=0.0) + extra.max(initial=0.0)), 1e-12) * 2.0
    ps, pl = _candidates(seg, lock_pos, reach, bucket)
    lam = base[pl] + extra[seg.agent[ps]]
    t1, t2 = _segment_disc(seg.a[ps], seg.b[ps], lock_pos[pl], lam)
    keep = t2 > t1
    ps, pl, t1, t2 = ps[keep], pl[keep], t1[keep], t2[keep]
    # ---- merge pieces of consecutive segments into claims (one per disc passage)
    ag = seg.agent[ps]
    order = np.lexsort((ps, pl, ag))
    ps, pl, t1, t2, ag = ps[order], pl[order], t1[order], t2[order], ag[order]
    new = np.ones(len(ps), dtype=bool)
    if len(ps) > 1:
        cont = (
            (ag[1:] == ag[:-1])
            & (pl[1:] == pl[:-1])
            & (ps[1:] == ps[:-1] + 1)
            & (t2[:-1] >= 1.0 - T_EPS)
            & (t1[1:] <= T_EPS)
        )
        new[1:] = ~cont
    head = np.flatnonzero(new)
    tail = np.concatenate([head[1:] - 1, [len(ps) - 1]]) if len(head) else head
    c_agent = ag[head]
    c_lock = pl[head]
    seg_in, seg_out = ps[head], ps[tail]
    t_in, t_out = t1[head], t2[tail]
    t_in = np.where(t_in <= T_EPS, 0.0, t_in)
    t_out = np.where(t_out >= 1.0 - T_EPS, 1.0, t_out)
    s_in = seg.s0[seg_in] + t_in * seg.length[seg_in]
    s_out = seg.s0[seg_out] + t_out * seg.length[seg_out]
    start = seg.first[seg_in] & (t_in == 0.0)
    final = seg.last[seg_out] & (t_out == 1.0)
    tau_in = np.where(t_in == 0.0, seg.tau0[seg_in], seg.tau_move[seg_in] + t_in)
    tau_out = np.where(t_out == 1.0, seg.tau_next[seg_out], seg.tau_move[seg_out] + t_out)
    none = np.zeros(0, np.int64)
    claims = Claims(
        c_agent, c_lock, s_in, s_out, seg_in, seg_out, t_in, t_out, start, final, tau_in,
        none, none, none.astype(bool),
    )  # fmt: skip
    src, dst, wait = _order_claims(claims, tau_out, seg, req, describe)
    return Claims(
        c_agent, c_lock, s_in, s_out, seg_in, seg_out, t_in, t_out, start, final, tau_in,
        src, dst, wait,
    )  # fmt: skip


def _claim_distance(c: Claims, seg: Segments, p: int, q: int, ends: str = "") -> float:
    """Smallest distance between the path pieces of claims ``p`` and ``q``; with
    ``ends="p-start"`` (``"p-end"``) between the start (end) point of ``p`` and ``q``."""
    # not at the top: `hierplan solve` loads this module (radii), not the geometry
    from hierplan_opt.schedule.geometry import segment_distance

    def pieces(k: int) -> tuple[np.ndarray, np.ndarray]:
        idx = np.arange(int(c.seg_in[k]), int(c.seg_out[k]) + 1)
        lo = np.zeros(len(idx))
        hi = np.ones(len(idx))
        lo[0] = c.t_in[k]
        hi[-1] = c.t_out[k]
        d = seg.b[idx] - seg.a[idx]
        return seg.a[idx] + lo[:, None] * d, seg.a[idx] + hi[:, None] * d

    a1, b1 = pieces(p)
    if ends == "p-start":
        a1, b1 = a1[:1], a1[:1]
    elif ends == "p-end":
        a1, b1 = b1[-1:], b1[-1:]
    a2, b2 = pieces(q)
    i, j = np.meshgrid(np.arange(len(a1)), np.arange(len(a2)), indexing="ij")
    i, j = i.ravel(), j.ravel()
    return float(segment_distance(a1[i], b1[i], a2[j], b2[j]).min())


def _order_claims(
    c: Claims, tau_out: np.ndarray, seg: Segments, req: Requirement, describe
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Precedences between the claims of every lock (see the module docstring)."""
    n = len(c.agent)
    level = np.where(c.start, 0, np.where(c.final, 2, 1))
    order = np.lexsort((c.agent, c.tau_in, level, c.lock))
    lock_s = c.lock[order]
    # Fast path: a lock with at most one start claim and one goal claim, none of them
    # both, is a chain: consecutive claims of different robots.
    multi = np.zeros(int(c.lock.max(initial=-1)) + 1, dtype=bool)
    if n > 1:
        same_lock = lock_s[1:] == lock_s[:-1]
        lev = level[order]
        dup = same_lock & (lev[1:] == lev[:-1]) & (lev[1:] != 1)
        multi[lock_s[1:][dup]] = True
    multi[c.lock[c.start & c.final]] = True
    src: list[np.ndarray] = []
    dst: list[np.ndarray] = []
    wait: list[np.ndarray] = []
    if n > 1:
        a, b = order[:-1], order[1:]
        chain = (c.lock[a] == c.lock[b]) & ~multi[c.lock[a]] & (c.agent[a] != c.agent[b])
        src.append(a[chain])
        dst.append(b[chain])
        wait.append(np.zeros(int(chain.sum()), dtype=bool))
    for lock in np.flatnonzero(multi).tolist():
        g = order[lock_s == lock]
        s_, d_, w_ = _order_group(c, tau_out, seg, req, g, describe)
        src.append(s_)
        dst.append(d_)
        wait.append(w_)
    if not src:
        none = np.zeros(0, np.int64)
        return none, none, none.astype(bool)
    return (
        np.concatenate(src).astype(np.int64),
        np.concatenate(dst).astype(np.int64),
        np.concatenate(wait).astype(bool),
    )


def _order_group(
    c: Claims,
    tau_out: np.ndarray,
    seg: Segments,
    req: Requirement,
    g: np.ndarray,
    describe,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Precedences of one lock with several start or goal claims.

    Start claims go first, in the order the robots leave the disc in the plan; a later
    one's robot *waits at its start* until the earlier one has left (its start point
    must be ``D_ij`` away from the earlier robot's piece). Goal claims go last, in the
    order of entering; a later one may enter once the earlier robot stands at its goal
    (which must be ``D_ij`` away from the later robot's piece). A robot that never leaves
    the disc must be ``D_ij`` away from every other claim of the lock.
    """
    lock = int(c.lock[g[0]])
    starts = sorted((int(k) for k in g if c.start[k] and not c.final[k]), key=lambda k: tau_out[k])
    finals = [int(k) for k in g if c.final[k] and not c.start[k]]
    middle = [int(k) for k in g if not c.start[k] and not c.final[k]]
    fixed = [int(k) for k in g if c.start[k] and c.final[k]]

    def need(p: int, q: int) -> float:
        return req.required(int(c.agent[p]), int(c.agent[q]))

    def check(p: int, q: int, ends: str, kind: str) -> None:
        if c.agent[p] == c.agent[q]:
            return
        d = _claim_distance(c, seg, p, q, ends)
        if d < need(p, q):
            raise ClearanceError(describe(kind, (int(c.agent[p]), int(c.agent[q])), lock, d))

    for k in fixed:
        for q in (int(x) for x in g):
            if q != k:
                check(k, q, "", "stays")
    for i, q in enumerate(starts):
        for p in starts[i + 1 :]:
            check(p, q, "p-start", "start")  # p waits at its start while q leaves
    for i, q in enumerate(finals):
        for p in finals[:i]:
            check(p, q, "p-end", "goal")  # p stands at its goal while q comes
    src: list[int] = []
    dst: list[int] = []
    wait: list[bool] = []

    def link(p: int, q: int, at_start: bool) -> None:
        if c.agent[p] != c.agent[q]:
            src.append(p)
            dst.append(q)
            wait.append(at_start)

    chain = [*starts, *middle, *finals]
    for k in range(len(chain) - 1):
        link(chain[k], chain[k + 1], k + 1 < len(starts))
    return np.array(src, np.int64), np.array(dst, np.int64), np.array(wait, bool)


def describe_types(req: Requirement, agents: Sequence[int]) -> str:
    """``types youbot and pioneer`` / ``type youbot`` for the robots given."""
    names = sorted({req.types[a] for a in agents})
    if len(names) == 1:
        return f"type {names[0]}"
    return "types " + ", ".join(names[:-1]) + " and " + names[-1]
