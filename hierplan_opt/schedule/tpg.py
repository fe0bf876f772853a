"""Temporal plan graph (TPG) of a discrete plan, with safety markers chosen from the radii.

A node is an event "robot j passes a point of its path": one *vertex node* per visit of
a location (consecutive waits merged) and *markers* on the moves. Type-1 arcs run along
each robot's path; a Type-2 arc ``u -> w`` says that robot B may pass ``w`` only after
robot A has *left* ``u`` (reached it and, at a vertex where it turns in place, finished
turning).

* **Point robots** (every radius and the margin 0, or ``clearance=False``): the plain
  TPG. For every location the visits are sorted by their entry timestep; for two
  *consecutive* visits by different robots (A before B) of location v an arc from A's
  *next* visit (A has reached the vertex after v, so it has left v) to B's visit of v:
  B may reach v only once A has left it. Later visitors follow transitively through
  the Type-1 chains in between, so the arcs are built from per-location visit lists
  with one ``lexsort`` (near-linear in the plan size, never a scan over pairs of
  robots). Robots that rotate along a cycle (each entering the vertex the next one
  leaves at the same step) would each wait for the next one to arrive first; their
  arcs go through markers a tenth of the move past the vertex instead (B may reach v
  once A is that far past it, and pass that far past v once A has reached w).
* **Robots with a size** (``r_i + r_j + margin > 0``): markers from the clearance claims
  of :mod:`hierplan_opt.schedule.clearance`. A robot claims a vertex while its centre is
  within ``lambda`` of it; the claims of one vertex are ordered as in the plan, and a
  Type-2 arc runs from the earlier robot's *exit marker* to the later robot's *entry
  marker*. On a grid with ``2 r_max + margin < cell`` the exit marker lies
  ``cell/2 + r + margin/2`` beyond the vertex, i.e. past the middle of the next edge;
  with cells smaller than the robots it lies several vertices further on.
  Every motion that passes the markers in the TPG's order keeps the centres of robots
  ``i`` and ``j`` at least ``r_i + r_j + margin`` apart (proof in ``docs/post.md``).
  When the claims wait for each other in a cycle (e.g. a rotation), no such schedule
  exists and :class:`~hierplan_opt.schedule.clearance.ClearanceError` says why.

Nodes of robot j are contiguous, in path order: ``agent_ptr[j]:agent_ptr[j+1]``.
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from hierplan_opt.core.errors import InputError
from hierplan_opt.core.instance import Instance
from hierplan_opt.core.plan import Plan
from hierplan_opt.core.reprs import short_repr
from hierplan_opt.schedule.clearance import (
    ClearanceError,
    Requirement,
    Segments,
    claim_precedences,
    claim_radii,
    describe_types,
)
from hierplan_opt.schedule.dag import csr, find_cycle, topo_order

#: Node kinds: a visited vertex; markers that end a claim (precedence source), begin
#: one (precedence target), or both; and a robot's start again where it waits, at
#: rest, for an earlier robot to leave before it sets off.
VERTEX = 0
LEAVE = 1
ENTER = 2
MARKER = 3
WAIT = 4
KIND_NAMES = ("vertex", "leave", "enter", "marker", "wait")

#: Arc types.
TYPE1 = 1
TYPE2 = 2


@dataclass(frozen=True, eq=False)
class TPG:
    """A temporal plan graph as flat numpy arrays (read-only).

    Attributes
    ----------
    agent_ptr : (K+1,) int
        Nodes of agent ``j`` are ``agent_ptr[j]:agent_ptr[j+1]`` in path order.
    node_agent, node_kind, node_vertex : (N,) int
        Robot, kind (:data:`VERTEX`, :data:`LEAVE`, :data:`ENTER`, :data:`MARKER`,
        :data:`WAIT`) and the vertex the node is at (markers: the vertex their move
        starts from).
    node_step : (N,) int
        Discrete timestep of the event in the plan (vertex nodes: entry step; markers:
        the step at which their move starts).
    node_pos : (N, dim) float
        Geometric position in metres (``Graph.position`` units: grid cells times the
        cell size, or roadmap coordinates).
    node_coord : (N, dim) float
        Position in instance coordinates (grid cells; roadmap coordinates).
    node_s : (N,) float
        Path length travelled by the robot up to the node (``Graph.edge_length`` units).
    node_turn : (N,) float
        Heading change (radians, >= 0) the robot makes at the node before moving on.
    node_heading : (N,) float
        Heading (radians, in the x-y plane) when the robot leaves the node (its last
        node: the heading it arrived with). A robot starts facing its first move.
    arc_src, arc_dst : (M,) int
        Arcs; Type-1 arcs are exactly the pairs of consecutive nodes of one robot.
    arc_type : (M,) int
        :data:`TYPE1` or :data:`TYPE2`.
    arc_lock : (M,) int
        For Type-2 arcs the vertex whose surroundings the two robots share (the
        location of the plain TPG, the claimed vertex with radii); -1 for Type-1.
    requirement : Requirement
        Radii, robot types and margin (``D_ij = r_i + r_j + margin``).
    regime : str
        ``none`` (point robots or ``clearance=False``), ``tight`` or ``general``
        (see :mod:`hierplan_opt.schedule.clearance`).
    """

    __repr__ = short_repr  # arrays and long tuples summarised (core/reprs)

    agent_ptr: np.ndarray
    node_agent: np.ndarray
    node_kind: np.ndarray
    node_vertex: np.ndarray
    node_step: np.ndarray
    node_pos: np.ndarray
    node_coord: np.ndarray
    node_s: np.ndarray
    node_turn: np.ndarray
    node_heading: np.ndarray
    arc_src: np.ndarray
    arc_dst: np.ndarray
    arc_type: np.ndarray
    arc_lock: np.ndarray
    requirement: Requirement
    regime: str
    agent_names: tuple[str, ...]
    location_names: _LocationNames

    @property
    def margin(self) -> float:
        """Extra clearance beyond the radii (metres)."""
        return self.requirement.margin

    @property
    def delta(self) -> float:
        """Deprecated name of :attr:`margin` (kept for readers of earlier schedules)."""
        return self.requirement.margin

    @property
    def num_nodes(self) -> int:
        return len(self.node_agent)

    @property
    def num_arcs(self) -> int:
        return len(self.arc_src)

    @property
    def num_agents(self) -> int:
        return len(self.agent_ptr) - 1

    @property
    def num_type2(self) -> int:
        return int(np.count_nonzero(self.arc_type == TYPE2))

    def agent_nodes(self, j: int) -> range:
        """Node ids of robot ``j`` in path order."""
        return range(int(self.agent_ptr[j]), int(self.agent_ptr[j + 1]))

    def start_nodes(self) -> np.ndarray:
        return self.agent_ptr[:-1]

    def final_nodes(self) -> np.ndarray:
        return self.agent_ptr[1:] - 1

    @cached_property
    def _type2_in(self) -> tuple[np.ndarray, np.ndarray]:
        t2 = np.flatnonzero(self.arc_type == TYPE2)
        order, ptr = csr(self.num_nodes, self.arc_dst[t2])
        return t2[order], ptr

    def type2_predecessors(self, v: int) -> np.ndarray:
        """Nodes of other robots that must have been *left* before node ``v`` happens.

        Example
        -------
        >>> from hierplan_opt import Graph
        >>> inst = Instance.mapf(Graph.grid(3, 1), [(0, 0), (1, 0)], [(1, 0), (2, 0)])
        >>> tpg = build_tpg(inst, Plan.from_paths([[0, 1], [1, 2]]))  # agent0 follows
        >>> [tpg.label(int(u)) for u in tpg.type2_predecessors(1)]  # agent1 left (1, 0)
        ['agent1 at (2, 0)']
        """
        arcs, ptr = self._type2_in
        return self.arc_src[arcs[ptr[v] : ptr[v + 1]]]

    def label(self, v: int) -> str:
        """A short human-readable name of node ``v``, e.g. ``agent1 at (2, 0)``."""
        who = self.agent_names[int(self.node_agent[v])]
        loc = self.location_names[int(self.node_vertex[v])]
        if int(self.node_kind[v]) == VERTEX:
            return f"{who} at {loc}"
        if int(self.node_kind[v]) == WAIT:
            return f"{who} sets off from {loc}"
        first = int(self.agent_ptr[int(self.node_agent[v])])
        u = v - 1
        while u > first and int(self.node_kind[u]) != VERTEX:
            u -= 1
        return f"{who} {float(self.node_s[v] - self.node_s[u]):.4g} past {loc}"


# ---------------------------------------------------------------------- visits
@dataclass(frozen=True, eq=False)
class _Visits:
    """Every robot's visits (waits merged) and moves, concatenated over robots."""

    V: np.ndarray  # vertex of each visit
    T: np.ndarray  # entry timestep
    A: np.ndarray  # robot
    ptr: np.ndarray  # visits of robot j: ptr[j]:ptr[j+1]
    is_first: np.ndarray
    is_last: np.ndarray
    pos: np.ndarray  # metres
    s: np.ndarray  # arc length at the visit
    turn: np.ndarray  # heading change before leaving
    heading: np.ndarray
    mv: np.ndarray  # visit index of each move's origin
    elen: np.ndarray  # declared length of each move
    head: np.ndarray  # heading of each move


def _compress(path: tuple[int, ...]) -> tuple[np.ndarray, np.ndarray]:
    """Visited vertices with waits merged, and the timestep each visit starts."""
    p = np.asarray(path, dtype=np.int64)
    keep = np.ones(len(p), dtype=bool)
    keep[1:] = p[1:] != p[:-1]
    steps = np.flatnonzero(keep)
    return p[steps], steps


def _wrap(a: np.ndarray) -> np.ndarray:
    """Angles wrapped to [-pi, pi)."""
    return (a + math.pi) % (2 * math.pi) - math.pi


def _visits(instance: Instance, plan: Plan) -> _Visits:
    g = instance.graph
    K = plan.num_agents
    scale = g.scale
    verts_l, steps_l = [], []
    for p in plan.paths:
        vv, ss = _compress(p)
        verts_l.append(vv)
        steps_l.append(ss)
    counts = np.array([len(v) for v in verts_l], dtype=np.int64)
    V = np.concatenate(verts_l)
    T = np.concatenate(steps_l)
    A = np.repeat(np.arange(K), counts)
    ptr = np.zeros(K + 1, dtype=np.int64)
    ptr[1:] = np.cumsum(counts)
    nvis = len(V)
    is_last = np.zeros(nvis, dtype=bool)
    is_last[ptr[1:] - 1] = True
    is_first = np.zeros(nvis, dtype=bool)
    is_first[ptr[:-1]] = True
    with np.errstate(over="ignore", invalid="ignore"):
        pos = g.coords[V] * scale
    mv = np.flatnonzero(~is_last)
    a_v, b_v = V[mv], V[mv + 1]
    with np.errstate(over="ignore", invalid="ignore"):
        d = pos[mv + 1] - pos[mv]
        geo = np.linalg.norm(d, axis=1)
    elen = _edge_lengths(g, a_v, b_v)
    _check_geometry(instance, pos, mv, V, geo, elen)
    # Heading of each move (x-y plane); vertical 3D moves keep the previous heading.
    flat = np.hypot(d[:, 0], d[:, 1]) > 1e-12 * np.maximum(geo, 1e-300)
    head = np.where(flat, np.arctan2(d[:, 1], d[:, 0]), np.nan)
    head = _fill_headings(head, A[mv])
    vis_head = np.zeros(nvis)
    vis_head[mv] = head
    last_with_move = ptr[1:] - 1
    has_move = counts > 1
    vis_head[last_with_move[has_move]] = head[np.searchsorted(mv, last_with_move[has_move] - 1)]
    vis_turn = np.zeros(nvis)
    kk = np.flatnonzero(~is_first[mv])  # moves that are not their robot's first
    vis_turn[mv[kk]] = np.abs(_wrap(head[kk] - head[kk - 1]))
    step_len = np.zeros(nvis)
    step_len[mv + 1] = elen
    cs = np.cumsum(step_len)
    vis_s = cs - np.repeat(cs[ptr[:-1]], counts)
    return _Visits(V, T, A, ptr, is_first, is_last, pos, vis_s, vis_turn, vis_head, mv, elen, head)


def _check_geometry(
    instance: Instance,
    pos: np.ndarray,
    mv: np.ndarray,
    V: np.ndarray,
    geo: np.ndarray,
    elen: np.ndarray,
) -> None:
    """Refuse positions and lengths that cannot be represented, and roadmap edges
    declared shorter than the straight segment the robots drive along."""
    g = instance.graph
    bad = np.flatnonzero(~np.isfinite(pos).all(axis=1))
    if len(bad):
        v = int(V[bad[0]])
        what = f"cell_size {g.cell_size:g}" if g.kind == "grid" else "its coordinates"
        raise InputError(
            f"the position of {_loc(g, v)} in metres is not a finite number ({what}); "
            "MAPF-POST cannot represent this map"
        )
    bad = np.flatnonzero(~np.isfinite(geo))
    if len(bad):
        u, w = int(V[mv[bad[0]]]), int(V[mv[bad[0]] + 1])
        raise InputError(
            f"the distance from {_loc(g, u)} to {_loc(g, w)} is not a finite number; "
            "MAPF-POST cannot represent this map"
        )
    short = np.flatnonzero(elen < geo * (1.0 - 1e-9))
    if len(short):
        k = int(short[0])
        u, w = int(V[mv[k]]), int(V[mv[k] + 1])
        raise InputError(
            f"roadmap edge {_loc(g, u)} -> {_loc(g, w)} is {elen[k]:g} long but its end "
            f"points are {geo[k]:g} apart; robots drive straight between way-points, so an "
            "edge may not be shorter than the straight segment (fix the length or omit it)"
        )


# ---------------------------------------------------------------------- build
def build_tpg(
    instance: Instance, plan: Plan, margin: float = 0.0, *, clearance: bool = True
) -> TPG:
    """The temporal plan graph of a *valid* plan, with markers for the robots' radii.

    Parameters
    ----------
    margin : float
        Extra clearance in metres: robots ``i`` and ``j`` keep their centres at least
        ``r_i + r_j + margin`` apart (radii from the robots' kinematics).
    clearance : bool
        False builds the plain TPG (order of the plan only, no distance guarantee).

    Raises :class:`~hierplan_opt.schedule.clearance.ClearanceError` (an
    :class:`InputError`) when the plan cannot keep that distance.

    Example
    -------
    >>> from hierplan_opt.core.graph import Graph
    >>> g = Graph.grid(3, 3, obstacles=[(0, 0), (2, 0), (0, 2), (2, 2)])
    >>> inst = Instance.mapf(g, [(0, 1), (1, 0)], [(2, 1), (1, 2)])
    >>> v = g.vertex
    >>> plan = Plan.from_paths([[v((0, 1)), v((1, 1)), v((2, 1))],
    ...                         [v((1, 0)), v((1, 0)), v((1, 1)), v((1, 2))]])
    >>> tpg = build_tpg(inst, plan)
    >>> tpg.num_nodes, tpg.num_arcs, tpg.num_type2
    (6, 5, 1)
    >>> [tpg.label(int(u)) + " -> " + tpg.label(int(w))
    ...  for u, w, t in zip(tpg.arc_src, tpg.arc_dst, tpg.arc_type) if t == 2]
    ['agent0 at (2, 1) -> agent1 at (1, 1)']
    >>> wide = build_tpg(inst, plan, margin=0.2)  # markers 0.6 m from (1, 1)
    >>> [wide.label(int(u)) + " -> " + wide.label(int(w))
    ...  for u, w, t in zip(wide.arc_src, wide.arc_dst, wide.arc_type) if t == 2]
    ['agent0 0.6 past (1, 1) -> agent1 0.4 past (1, 0)']
    """
    req = Requirement.of(instance, margin, enforced=clearance)
    if plan.num_agents != instance.num_agents:
        raise InputError(
            f"the plan has {plan.num_agents} paths but the instance {instance.num_agents} agents"
        )
    vis = _visits(instance, plan)
    regime = req.regime(instance.graph)
    if regime == "general" and instance.graph.kind != "grid" and _grid_like(vis, req):
        regime = "tight"
    if regime == "none":
        tpg = _plain(instance, vis, req)
    else:
        tpg = _with_claims(instance, vis, req, regime)
    return _freeze(tpg)


#: Point robots in a rotation: the markers sit this fraction of the move past a vertex.
ROTATION_MARK = 0.1


def _plain(instance: Instance, vis: _Visits, req: Requirement) -> TPG:
    """Plain TPG: for consecutive visitors A, B of a location v, an arc from A's *next*
    visit (A has reached the vertex after v, so it has left v) to B's visit of v.
    Rotations (robots that each enter, in one step, the vertex the next one leaves)
    get markers instead: see :func:`_rotation_arcs`."""
    g = instance.graph
    order = np.lexsort((vis.T, vis.V))
    same_loc = vis.V[order[1:]] == vis.V[order[:-1]]
    other = vis.A[order[1:]] != vis.A[order[:-1]]
    sel = np.flatnonzero(same_loc & other)
    prev_vis = order[sel]
    next_vis = order[sel + 1]
    if np.any(vis.is_last[prev_vis]):
        raise InputError("the plan has a vertex conflict (validate it first)")
    src, dst = prev_vis + 1, next_vis
    nvis = len(vis.V)
    # Arcs between visits that happen in one step can only close a cycle among
    # themselves (every other arc goes forward in the plan's steps): a rotation.
    same = np.flatnonzero(vis.T[src] == vis.T[dst])
    rot = np.zeros(0, dtype=np.int64)
    if len(same):
        topo = topo_order(nvis, src[same], dst[same])
        on_cycle = np.zeros(nvis, dtype=bool)
        on_cycle[topo.cyclic] = True
        rot = same[on_cycle[src[same]] & on_cycle[dst[same]]]
    keep = np.ones(len(src), dtype=bool)
    keep[rot] = False
    coords = g.coords[vis.V].astype(float)
    names = tuple(a.name for a in instance.agents)
    cross = _crossings(g, vis, names)
    if not len(rot) and not len(cross[0]):
        t1 = np.flatnonzero(~vis.is_last)
        return _plain_tpg(
            vis, req, g, names, coords, t1, src, dst, vis.V[dst], np.zeros(nvis, np.int8)
        )
    return _rotation_arcs(
        vis, req, g, names, coords, src[keep], dst[keep], src[rot], dst[rot], cross
    )


#: Crossing points closer than this fraction of a move to either end are left to the
#: vertex arcs (the robots meet at a vertex there, not in the open).
CROSS_END = 1e-9
#: Passing times closer than this (steps) are a tie: the "past" marker goes half way on.
TIE = 1e-6
#: Markers of one move closer than this fraction of it are one node (rounding).
SNAP = 1e-9


def _crossings(
    g, vis: _Visits, names: Sequence[str] = ()
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Plain-TPG arcs for roadmap edges that meet in the open (point robots).

    Robots on roadmap edges can meet at points that the vertex arcs do not order:

    * two edges *cross* at a point X that is no end of either;
    * an edge passes *through a vertex* C that is not one of its ends, where other
      robots stand (from their arrival until they move on);
    * two edges *overlap*: collinear, sharing a stretch R of positive length.

    The passages of each such point or stretch are ordered as in the plan: by the time
    the plan's uniform motion enters it (the step of the move plus the fraction of the
    move; a stay at C from the step of the arrival; ties by robot). Each later robot may
    enter (a marker on its move, or its arrival at C) only once the earlier one has left:
    reached the end of its move (or of its move away from C), when that ends before the
    later one's move begins; otherwise once it is past (a marker half way from where it
    leaves to where it is when the later one enters, in the plan's motion), so that arcs
    between passages that do not overlap in the plan go forward in its time. Returns the
    arcs as (source's move origin, its fraction of that move; target's move origin,
    fraction), a fraction of 1 meaning the visit that move ends at. Grids join axis
    neighbours only: nothing to add. A robot that stays at C for good (its goal) comes
    after every robot that passes C, whenever the plan has them pass; one that stands on
    C for the whole plan while another passes, and two used vertices at one point, are
    refused (:class:`ClearanceError`, one line).

    Example
    -------
    >>> from hierplan_opt.core.graph import Graph
    >>> g = Graph.roadmap({"A": (0, 0), "B": (2, 2), "C": (0, 2), "D": (2, 0)},
    ...                   [("A", "B"), ("C", "D")])
    >>> inst = Instance.mapf(g, ["A", "C"], ["B", "D"])
    >>> plan = Plan.from_paths([[g.vertex("A"), g.vertex("B")],
    ...                         [g.vertex("C"), g.vertex("C"), g.vertex("D")]])
    >>> [a.tolist() for a in _crossings(g, _visits(inst, plan))]  # r1 once r0 is at B
    [[0], [1.0], [2], [0.5]]
    """
    none = (np.zeros(0, np.int64), np.zeros(0), np.zeros(0, np.int64), np.zeros(0))
    mv = vis.mv
    if g.kind == "grid" or len(mv) < 1 or len(np.unique(vis.A)) < 2:
        return none
    a, b = vis.V[mv], vis.V[mv + 1]
    lo, hi = np.minimum(a, b), np.maximum(a, b)
    edges, inv = np.unique(np.stack([lo, hi], axis=1), axis=0, return_inverse=True)
    inv = inv.ravel()
    P = g.coords[edges[:, 0]].astype(float) * g.scale
    Q = g.coords[edges[:, 1]].astype(float) * g.scale
    verts = np.unique(vis.V)
    C = g.coords[verts].astype(float) * g.scale
    tol = 1e-9 * max(1.0, float(np.abs(np.concatenate([P, Q, C])).max(initial=0.0)))
    _refuse_shared_points(g, verts, C, tol)
    touch = _touches(edges, P, Q, verts, C, tol)
    if not any(touch):
        return none
    crossing, on_edge, overlap = touch
    by_edge: dict[int, list[int]] = {}
    for k, e in enumerate(inv.tolist()):
        by_edge.setdefault(e, []).append(k)

    def moves(e: int, f0: float, f1: float) -> list[_Pass]:
        """Passages of the moves along edge ``e`` over its stretch [f0, f1] (from its
        lower end)."""
        out = []
        for k in by_edge.get(e, ()):
            o = int(mv[k])
            fin, fout = (f0, f1) if vis.V[o] == edges[e, 0] else (1.0 - f1, 1.0 - f0)
            t0 = float(vis.T[o + 1] - 1)
            out.append(_Pass(t0 + fin, int(vis.A[o]), o, fin, t0 + fout, o, fout, False))
        return out

    regions: list[list[_Pass]] = []
    for e1, e2, s1, s2 in crossing:
        regions.append(moves(e1, s1, s1) + moves(e2, s2, s2))
    stays: dict[int, list[_Pass]] = {c: [] for c in on_edge}
    for i in np.flatnonzero(np.isin(vis.V, list(on_edge))).tolist():
        out = np.inf if vis.is_last[i] else float(vis.T[i + 1] - 1)
        stays[int(vis.V[i])].append(
            _Pass(float(vis.T[i]), int(vis.A[i]), i - 1, 1.0, out, i, 0.0, True)
        )
    for v, passing in on_edge.items():
        regions.append(stays[v] + [p for e, s in passing for p in moves(e, s, s)])
    for e1, e2, (u0, u1), (w0, w1) in overlap:
        regions.append(moves(e1, u0, u1) + moves(e2, w0, w1))
    arcs: list[tuple[int, float, int, float]] = []
    for passes in regions:
        # a robot that stays for good (at its goal) comes last: the others pass first
        passes.sort(key=lambda p: (p.t_in if p.t_out < np.inf else np.inf, not p.stay, p.robot))
        for pa, pb in zip(passes[:-1], passes[1:], strict=True):
            if pa.robot == pb.robot or (pa.stay and pb.stay):
                continue  # along one path; or a vertex's visits (the vertex arcs)
            if pb.in_origin < 0 or vis.A[pb.in_origin] != pb.robot:
                # b starts there: first in its order unless it never leaves
                raise ClearanceError(_stands_in_the_way(g, vis, names, pb, pa))
            begins = vis.T[pb.in_origin + 1] - 1  # the step b's move there begins
            if vis.T[pa.out_origin + 1] <= begins:  # a's move ends before b's begins
                arcs.append((pa.out_origin, 1.0, pb.in_origin, pb.f_in))
            else:
                room = 1.0 - pa.f_out
                lead = pb.t_in - pa.t_out
                # exact ties (up to rounding): half way on, never on the point itself
                past = pa.f_out + (min(lead, room) if lead > TIE else room) / 2
                arcs.append((pa.out_origin, past, pb.in_origin, pb.f_in))
    if not arcs:
        return none
    so, sf, do, df = zip(*dict.fromkeys(arcs), strict=True)
    return np.array(so, np.int64), np.array(sf), np.array(do, np.int64), np.array(df)


@dataclass(frozen=True)
class _Pass:
    """One robot's passage of a meeting point or stretch (see :func:`_crossings`): the
    plan's time it enters, the move (origin visit) and fraction where it enters (a
    fraction of 1: the visit the move ends at), the time it leaves (inf: never), the move
    and fraction where it has left (0 on the move away from a vertex), and whether it
    stays at a vertex (the vertex arcs order two stays)."""

    t_in: float
    robot: int
    in_origin: int
    f_in: float
    t_out: float
    out_origin: int
    f_out: float
    stay: bool


def _stands_in_the_way(g, vis: _Visits, names: Sequence[str], stay: _Pass, other: _Pass) -> str:
    """One line: a robot stands for the whole plan where another robot's edge runs."""

    def name(r: int) -> str:
        return names[r] if r < len(names) else f"agent{r}"

    c = _loc(g, int(vis.V[stay.out_origin]))
    o = other.out_origin
    a, b = _loc(g, int(vis.V[o])), _loc(g, int(vis.V[o + 1]))
    return (
        f"robot {name(stay.robot)} stands on {c} for the whole plan and robot "
        f"{name(other.robot)} drives through it (roadmap edge {a} - {b} runs through {c}): "
        "point robots would meet there; replan (or split the edge at the vertex)"
    )


def _refuse_shared_points(g, verts: np.ndarray, C: np.ndarray, tol: float) -> None:
    """Refuse, in one line, two visited vertices at one point: point robots on them
    would be on one point although the plan has them on different vertices."""
    if len(verts) < 2:
        return
    order = np.lexsort(C.T[::-1])
    gap = np.abs(np.diff(C[order], axis=0)).max(axis=1)
    same = np.flatnonzero(gap <= tol)
    if not len(same):
        return
    u, w = int(verts[order[same[0]]]), int(verts[order[same[0] + 1]])
    raise ClearanceError(
        f"roadmap vertices {_loc(g, u)} and {_loc(g, w)} are at one point: robots on them "
        "would meet although the plan has them apart; merge the two vertices"
    )


_Touches = tuple[
    list[tuple[int, int, float, float]],
    dict[int, list[tuple[int, float]]],
    list[tuple[int, int, tuple[float, float], tuple[float, float]]],
]


def _touches(
    edges: np.ndarray, P: np.ndarray, Q: np.ndarray, verts: np.ndarray, C: np.ndarray, tol: float
) -> _Touches:
    """Where the used edges ``P[e]Q[e]`` meet away from common vertices: crossings
    ``(e1, e2, s1, s2)`` (fractions from each edge's first end), vertices on an edge's
    inside ``{vertex: [(e, s), ...]}``, and collinear overlaps ``(e1, e2, (u0, u1),
    (w0, w1))`` (the shared stretch as fractions of each edge)."""
    # not at the top: the geometry is only needed for roadmaps
    from hierplan_opt.schedule.geometry import segment_closest

    box_lo, box_hi = np.minimum(P, Q), np.maximum(P, Q)
    D = Q - P
    L2 = np.einsum("ij,ij->i", D, D)
    crossing: list[tuple[int, int, float, float]] = []
    overlap: list[tuple[int, int, tuple[float, float], tuple[float, float]]] = []
    for ii, jj in _box_pairs(box_lo, box_hi, box_lo, box_hi, tol):
        keep = jj > ii
        ii, jj = ii[keep], jj[keep]
        dot = np.einsum("ij,ij->i", D[ii], D[jj])
        parallel = L2[ii] * L2[jj] - dot * dot <= (1e-9 * L2[ii]) * L2[jj]
        # on one line: both ends of jj within tol of ii's line (else they may cross)
        on_line = parallel.copy()
        for X in (P[jj], Q[jj]):
            u = np.einsum("ij,ij->i", X - P[ii], D[ii]) / L2[ii]
            off = X - P[ii] - u[:, None] * D[ii]
            on_line &= np.einsum("ij,ij->i", off, off) <= tol * tol
        share = (edges[ii, 0] == edges[jj, 0]) | (edges[ii, 0] == edges[jj, 1])
        share |= (edges[ii, 1] == edges[jj, 0]) | (edges[ii, 1] == edges[jj, 1])
        x = ~share & ~on_line
        ci, cj = ii[x], jj[x]
        d, s, t = segment_closest(P[ci], Q[ci], P[cj], Q[cj])
        hit = (d <= tol) & (s > CROSS_END) & (s < 1 - CROSS_END)
        hit &= (t > CROSS_END) & (t < 1 - CROSS_END)
        crossing += zip(
            ci[hit].tolist(), cj[hit].tolist(), s[hit].tolist(), t[hit].tolist(), strict=True
        )
        overlap += _overlaps(ii[on_line], jj[on_line], P, D, L2, tol)
    on_edge: dict[int, list[tuple[int, float]]] = {}
    for ee, vv in _box_pairs(box_lo, box_hi, C, C, tol):
        keep = (edges[ee, 0] != verts[vv]) & (edges[ee, 1] != verts[vv])
        ee, vv = ee[keep], vv[keep]
        s = np.einsum("ij,ij->i", C[vv] - P[ee], D[ee]) / L2[ee]
        near = P[ee] + s[:, None] * D[ee] - C[vv]
        hit = (np.einsum("ij,ij->i", near, near) <= tol * tol) & (s > CROSS_END)
        hit &= s < 1 - CROSS_END
        for e, v, f in zip(ee[hit].tolist(), verts[vv[hit]].tolist(), s[hit].tolist(), strict=True):
            on_edge.setdefault(v, []).append((e, f))
    return crossing, on_edge, overlap


#: Candidate pairs per batch of :func:`_box_pairs`.
BOX_BATCH = 2_000_000


def _box_pairs(
    lo_a: np.ndarray, hi_a: np.ndarray, lo_b: np.ndarray, hi_b: np.ndarray, tol: float
) -> Iterator[tuple[np.ndarray, np.ndarray]]:
    """Batches ``(ia, ib)`` of the pairs of boxes ``a``, ``b`` that overlap (within
    ``tol``): a sweep along x, so short edges on a large map pair with their
    neighbours only, not with every edge."""
    order = np.argsort(lo_b[:, 0], kind="stable")
    xs = lo_b[order, 0]
    width = float((hi_b[:, 0] - lo_b[:, 0]).max(initial=0.0))
    start = np.searchsorted(xs, lo_a[:, 0] - tol - width, "left")
    n = np.searchsorted(xs, hi_a[:, 0] + tol, "right") - start
    a0 = 0
    while a0 < len(lo_a):
        cum = np.cumsum(n[a0:])
        a1 = a0 + max(1, int(np.searchsorted(cum, BOX_BATCH, "right")))
        cnt = n[a0:a1]
        ia = np.repeat(np.arange(a0, a1), cnt)
        off = np.arange(int(cnt.sum())) - np.repeat(np.cumsum(cnt) - cnt, cnt)
        ib = order[np.repeat(start[a0:a1], cnt) + off]
        sel = np.all(lo_a[ia] <= hi_b[ib] + tol, axis=1)
        sel &= np.all(lo_b[ib] <= hi_a[ia] + tol, axis=1)
        if np.any(sel):
            yield ia[sel], ib[sel]
        a0 = a1


def _overlaps(
    ii: np.ndarray, jj: np.ndarray, P: np.ndarray, D: np.ndarray, L2: np.ndarray, tol: float
) -> list[tuple[int, int, tuple[float, float], tuple[float, float]]]:
    """The stretches that edge pairs ``(ii, jj)`` on one line (``_touches`` checked
    both ends) share, as fractions of each; pairs sharing at most a point are left out."""
    p1, d1, p2, d2 = P[ii], D[ii], P[jj], D[jj]
    u_p = np.einsum("ij,ij->i", p2 - p1, d1) / L2[ii]
    u_q = np.einsum("ij,ij->i", p2 + d2 - p1, d1) / L2[ii]
    u0 = np.maximum(0.0, np.minimum(u_p, u_q))
    u1 = np.minimum(1.0, np.maximum(u_p, u_q))
    k = np.flatnonzero((u1 - u0) * np.sqrt(L2[ii]) > tol)
    w_a = np.einsum("ij,ij->i", p1[k] + u0[k, None] * d1[k] - p2[k], d2[k]) / L2[jj[k]]
    w_b = np.einsum("ij,ij->i", p1[k] + u1[k, None] * d1[k] - p2[k], d2[k]) / L2[jj[k]]
    w0 = np.clip(np.minimum(w_a, w_b), 0.0, 1.0).tolist()
    w1 = np.clip(np.maximum(w_a, w_b), 0.0, 1.0).tolist()
    return [
        (int(ii[m]), int(jj[m]), (float(u0[m]), float(u1[m])), (w0[n], w1[n]))
        for n, m in enumerate(k.tolist())
    ]


def _snap(origin: np.ndarray, frac: np.ndarray) -> np.ndarray:
    """Fractions of one move within :data:`SNAP` of each other made equal (one node):
    markers for one point computed two ways differ by rounding, and a robot held at the
    first would stand on the point while it waits for the second.

    Example
    -------
    >>> _snap(np.array([0, 0, 1]), np.array([0.5, 0.5 + 1e-15, 0.5])).tolist()
    [0.5, 0.5, 0.5]
    """
    if len(frac) < 2:
        return frac
    order = np.lexsort((frac, origin))
    f, o = frac[order], origin[order]
    new = np.ones(len(f), dtype=bool)
    new[1:] = (o[1:] != o[:-1]) | (np.diff(f) > SNAP)
    out = np.empty_like(frac)
    out[order] = f[np.flatnonzero(new)[np.cumsum(new) - 1]]
    return out


def _rotation_arcs(
    vis: _Visits,
    req: Requirement,
    g,
    names: tuple[str, ...],
    coords: np.ndarray,
    src: np.ndarray,
    dst: np.ndarray,
    rot_src: np.ndarray,
    rot_dst: np.ndarray,
    cross: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray],
) -> TPG:
    """The plain TPG with rotations: for each rotation arc (A enters w in the step B
    enters v, the vertex A leaves) two arcs through markers ``ROTATION_MARK`` of the
    move past a vertex: B may reach v once A is that far past v (it has left v), and B
    may pass that far past v on its next move once A has reached w (so B never catches
    A on the edge v -> w). Both go forward in the plan's steps: acyclic. Point robots
    are then never on one point (docs/post.md). ``cross`` adds the arcs of edges that
    cross in the open (:func:`_crossings`): from a visit or a marker past the crossing
    point to a marker at it, lock -2 (no vertex; never switched at run time)."""
    f = ROTATION_MARK
    cs_origin, cs_frac, c_origin, c_frac = cross
    c_visit = cs_frac >= 1.0  # from the visit the move ends at
    cm_origin, cm_frac = cs_origin[~c_visit], cs_frac[~c_visit]  # from a marker past X
    to_visit = c_frac >= 1.0  # to the visit the move ends at (an arrival at a vertex)
    ct_origin, ct_frac = c_origin[~to_visit], c_frac[~to_visit]  # to a marker at X
    a_origin = rot_src - 1  # A's visit of v: its move v -> w carries A's marker
    b_next = ~vis.is_last[rot_dst]  # B moves on after v: its marker on that move
    b_origin = rot_dst[b_next]
    na, nb, nc = len(a_origin), len(b_origin), len(ct_origin)
    m_origin = np.concatenate([a_origin, b_origin, ct_origin, cm_origin])
    m_frac = _snap(m_origin, np.concatenate([np.full(na + nb, f), ct_frac, cm_frac]))
    pair = np.stack([m_origin.astype(float), m_frac], axis=1)
    uniq, inv = np.unique(pair, axis=0, return_inverse=True)
    inv = inv.ravel()
    origins, fr = uniq[:, 0].astype(np.int64), uniq[:, 1]
    role = np.zeros(len(origins), dtype=np.int8)
    np.bitwise_or.at(role, inv[:na], np.int8(LEAVE))
    np.bitwise_or.at(role, inv[na : na + nb + nc], np.int8(ENTER))
    np.bitwise_or.at(role, inv[na + nb + nc :], np.int8(LEAVE))
    m_kind = np.where(role == LEAVE | ENTER, MARKER, role).astype(np.int8)
    nvis = len(vis.V)
    nm = len(origins)
    key = np.concatenate([np.arange(nvis, dtype=float), origins + fr])
    order = np.argsort(key, kind="stable")
    newid = np.empty(nvis + nm, dtype=np.int64)
    newid[order] = np.arange(nvis + nm)
    vis_node, mark_node = newid[:nvis], newid[nvis:]
    move = np.searchsorted(vis.mv, origins)
    step_len = vis.s[origins + 1] - vis.s[origins]

    def arrange(x: np.ndarray, y: np.ndarray) -> np.ndarray:
        return np.concatenate([x, y])[order]

    node_agent = arrange(vis.A, vis.A[origins])
    agent_ptr = np.zeros(len(vis.ptr), dtype=np.int64)
    agent_ptr[1:] = np.cumsum(np.bincount(node_agent, minlength=len(vis.ptr) - 1))
    last = np.zeros(nvis + nm, dtype=bool)
    last[agent_ptr[1:] - 1] = True
    c_src = np.empty(len(c_origin), dtype=np.int64)
    c_src[c_visit] = vis_node[cs_origin[c_visit] + 1]
    c_src[~c_visit] = mark_node[inv[na + nb + nc :]]
    c_dst = np.empty(len(c_origin), dtype=np.int64)
    c_dst[to_visit] = vis_node[c_origin[to_visit] + 1]
    c_dst[~to_visit] = mark_node[inv[na + nb : na + nb + nc]]
    arc_src = np.concatenate([vis_node[src], mark_node[inv[:na]], vis_node[rot_src[b_next]], c_src])
    arc_dst = np.concatenate(
        [
            vis_node[dst],
            vis_node[rot_dst],
            mark_node[inv[na : na + nb]],
            c_dst,
        ]
    )
    lock = np.concatenate(
        [vis.V[dst], vis.V[rot_dst], vis.V[rot_dst[b_next]], np.full(len(c_dst), -2, np.int64)]
    )
    fc = fr[:, None]
    t1 = np.flatnonzero(~last)
    kinds = arrange(np.zeros(nvis, np.int8), m_kind)
    tpg = TPG(
        agent_ptr=agent_ptr,
        node_agent=node_agent,
        node_kind=kinds,
        node_vertex=arrange(vis.V, vis.V[origins]),
        node_step=arrange(vis.T, vis.T[origins + 1] - 1),
        node_pos=arrange(
            vis.pos, vis.pos[origins] + fc * (vis.pos[origins + 1] - vis.pos[origins])
        ),
        node_coord=arrange(coords, coords[origins] + fc * (coords[origins + 1] - coords[origins])),
        node_s=arrange(vis.s, vis.s[origins] + fr * step_len),
        node_turn=arrange(vis.turn, np.zeros(nm)),
        node_heading=arrange(vis.heading, vis.head[move]),
        arc_src=np.concatenate([t1, arc_src]),
        arc_dst=np.concatenate([t1 + 1, arc_dst]),
        arc_type=np.concatenate(
            [np.full(len(t1), TYPE1, np.int8), np.full(len(arc_src), TYPE2, np.int8)]
        ),
        arc_lock=np.concatenate([np.full(len(t1), -1, np.int64), lock]),
        requirement=req,
        regime="none",
        agent_names=names,
        location_names=_LocationNames(g),
    )
    _check_acyclic(tpg, g, "")
    return tpg


def _plain_tpg(
    vis: _Visits,
    req: Requirement,
    g,
    names: tuple[str, ...],
    coords: np.ndarray,
    t1: np.ndarray,
    src: np.ndarray,
    dst: np.ndarray,
    lock: np.ndarray,
    kinds: np.ndarray,
) -> TPG:
    """A plain TPG of vertex nodes only."""
    return TPG(
        agent_ptr=vis.ptr,
        node_agent=vis.A,
        node_kind=kinds,
        node_vertex=vis.V,
        node_step=vis.T,
        node_pos=vis.pos,
        node_coord=coords,
        node_s=vis.s,
        node_turn=vis.turn,
        node_heading=vis.heading,
        arc_src=np.concatenate([t1, src]),
        arc_dst=np.concatenate([t1 + 1, dst]),
        arc_type=np.concatenate(
            [np.full(len(t1), TYPE1, np.int8), np.full(len(src), TYPE2, np.int8)]
        ),
        arc_lock=np.concatenate([np.full(len(t1), -1, np.int64), lock]),
        requirement=req,
        regime="none",
        agent_names=names,
        location_names=_LocationNames(g),
    )


def _segments(vis: _Visits) -> Segments:
    """The moves as segments, plus one point segment per robot that never moves."""
    K = len(vis.ptr) - 1
    counts = np.diff(vis.ptr)
    still = np.flatnonzero(counts == 1)
    o = np.concatenate([vis.mv, vis.ptr[still]])
    moving = np.concatenate([np.ones(len(vis.mv), bool), np.zeros(len(still), bool)])
    dest = np.where(moving, o + 1, o)
    agent = vis.A[o]
    order = np.lexsort((o, agent))
    o, dest, moving, agent = o[order], dest[order], moving[order], agent[order]
    length = np.where(moving, vis.s[dest] - vis.s[o], 0.0)
    first = np.zeros(len(o), dtype=bool)
    last = np.zeros(len(o), dtype=bool)
    seg_ptr = np.searchsorted(agent, np.arange(K + 1))
    first[seg_ptr[:-1]] = True
    last[seg_ptr[1:] - 1] = True
    tau_move = np.where(moving, vis.T[dest] - 1, vis.T[o]).astype(float)
    leaves = moving & ~vis.is_last[dest]
    tau_next = np.full(len(o), np.inf)
    tau_next[leaves] = vis.T[dest[leaves] + 1] - 1
    return Segments(
        agent=agent,
        origin=o,
        a=vis.pos[o],
        b=vis.pos[dest],
        s0=vis.s[o],
        length=length,
        tau0=vis.T[o].astype(float),
        tau_move=tau_move,
        tau_next=tau_next,
        first=first,
        last=last,
        moving=moving,
    )


def _with_claims(instance: Instance, vis: _Visits, req: Requirement, regime: str) -> TPG:
    g = instance.graph
    seg = _segments(vis)
    geo = np.linalg.norm(seg.b - seg.a, axis=1)
    locks, lock_pos, rho = _locks(vis, seg, geo, req, regime)
    base, extra = claim_radii(req, regime, rho, g.cell_size)
    names = tuple(a.name for a in instance.agents)
    room = _room(g, geo)

    def describe(kind: str, agents: tuple[int, int], lock: int, dist: float) -> str:
        a, b = agents
        loc = _loc(g, int(locks[lock]))
        need = req.required(a, b)
        types = describe_types(req, (a, b))
        if kind == "start":
            what = (
                f"robots {names[a]} and {names[b]} ({types}) start too close near {loc}: "
                f"{names[a]}'s start is {dist:.4g} m from {names[b]}'s first moves"
            )
        elif kind == "goal":
            what = (
                f"robots {names[a]} and {names[b]} ({types}) end too close near {loc}: "
                f"{names[a]}'s goal is {dist:.4g} m from {names[b]}'s last moves"
            )
        else:
            what = (
                f"robot {names[a]} never leaves the surroundings of {loc} and robot "
                f"{names[b]} ({types}) passes {dist:.4g} m from its path there"
            )
        return f"{what}, but they need {need:g} m between their centres ({room})"

    claims = claim_precedences(seg, lock_pos, base, extra, req, describe=describe)
    # ---- markers: the claim ends that carry a precedence ----------------------------
    wait = claims.dst_wait
    go = ~wait
    pts_seg = np.concatenate([claims.seg_out[claims.src], claims.seg_in[claims.dst[go]]])
    pts_t = np.concatenate([claims.t_out[claims.src], claims.t_in[claims.dst[go]]])
    role = np.concatenate([np.full(len(claims.src), LEAVE), np.full(int(go.sum()), ENTER)])
    # A claim end at a segment's end point is the vertex node itself.
    o = seg.origin[pts_seg]
    at_vertex = (pts_t <= 0.0) | (pts_t >= 1.0) | ~seg.moving[pts_seg]
    vert_of_pt = np.where((pts_t >= 1.0) & seg.moving[pts_seg], o + 1, o)
    mk = ~at_vertex
    uniq, inv = np.unique(
        np.stack([pts_seg[mk].astype(float), pts_t[mk]]), axis=1, return_inverse=True
    )
    inv = inv.ravel()
    m_seg = uniq[0].astype(np.int64)
    m_t = uniq[1]
    m_role = np.zeros(len(m_seg), dtype=np.int8)
    np.bitwise_or.at(m_role, inv, role[mk].astype(np.int8))
    m_kind = np.where(m_role == LEAVE | ENTER, MARKER, m_role).astype(np.int8)
    # Robots that wait at their start until an earlier start claim has ended.
    waiters = np.unique(claims.agent[claims.dst[wait]])
    w_vis = vis.ptr[waiters]
    # ---- nodes: visits, waits and markers, sorted along each robot's path -------------
    nvis = len(vis.V)
    nw = len(waiters)
    m_orig = seg.origin[m_seg]
    key = np.concatenate([np.arange(nvis, dtype=float), w_vis.astype(float), m_orig + m_t])
    rank = np.concatenate([np.zeros(nvis), np.ones(nw), np.full(len(m_seg), 2.0)])
    order = np.lexsort((rank, key))
    newid = np.empty(len(key), dtype=np.int64)
    newid[order] = np.arange(len(key))
    vis_node = newid[:nvis]
    wait_node = newid[nvis : nvis + nw]
    mark_node = newid[nvis + nw :]
    d = seg.b[m_seg] - seg.a[m_seg]
    cu = g.coords[vis.V[m_orig]].astype(float)
    cw = g.coords[vis.V[np.minimum(m_orig + 1, nvis - 1)]].astype(float)
    move_of = np.searchsorted(vis.mv, m_orig)
    cat = np.concatenate

    def arrange(x: np.ndarray, w: np.ndarray, y: np.ndarray) -> np.ndarray:
        return cat([x, w, y])[order]

    node_agent = arrange(vis.A, waiters, vis.A[m_orig])
    counts = np.bincount(node_agent, minlength=len(vis.ptr) - 1)
    agent_ptr = np.zeros(len(vis.ptr), dtype=np.int64)
    agent_ptr[1:] = np.cumsum(counts)
    node_kind = arrange(np.zeros(nvis, np.int8), np.full(nw, WAIT, np.int8), m_kind)
    node_vertex = arrange(vis.V, vis.V[w_vis], vis.V[m_orig])
    node_step = arrange(vis.T, vis.T[w_vis], vis.T[np.minimum(m_orig + 1, nvis - 1)] - 1)
    node_pos = arrange(vis.pos, vis.pos[w_vis], seg.a[m_seg] + m_t[:, None] * d)
    node_coord = arrange(
        g.coords[vis.V].astype(float),
        g.coords[vis.V[w_vis]].astype(float),
        cu + m_t[:, None] * (cw - cu),
    )
    node_s = arrange(vis.s, vis.s[w_vis], seg.s0[m_seg] + m_t * seg.length[m_seg])
    node_turn = arrange(vis.turn, np.zeros(nw), np.zeros(len(m_seg)))
    node_heading = arrange(vis.heading, vis.heading[w_vis], vis.head[move_of])
    # ---- arcs -------------------------------------------------------------------------
    point_node = np.empty(len(pts_seg), dtype=np.int64)
    point_node[at_vertex] = vis_node[vert_of_pt[at_vertex]]
    point_node[mk] = mark_node[inv]
    ns = len(claims.src)
    t2_src = point_node[:ns]
    t2_dst = np.empty(len(claims.dst), dtype=np.int64)
    t2_dst[go] = point_node[ns:]
    t2_dst[wait] = wait_node[np.searchsorted(waiters, claims.agent[claims.dst[wait]])]
    t2_lock = locks[claims.lock[claims.dst]]
    pairs = np.unique(np.stack([t2_src, t2_dst, t2_lock]), axis=1)
    last_node = np.zeros(len(node_agent), dtype=bool)
    last_node[agent_ptr[1:] - 1] = True
    t1 = np.flatnonzero(~last_node)
    tpg = TPG(
        agent_ptr=agent_ptr,
        node_agent=node_agent,
        node_kind=node_kind,
        node_vertex=node_vertex,
        node_step=node_step,
        node_pos=node_pos,
        node_coord=node_coord,
        node_s=node_s,
        node_turn=node_turn,
        node_heading=node_heading,
        arc_src=cat([t1, pairs[0]]),
        arc_dst=cat([t1 + 1, pairs[1]]),
        arc_type=cat([np.full(len(t1), TYPE1, np.int8), np.full(pairs.shape[1], TYPE2, np.int8)]),
        arc_lock=cat([np.full(len(t1), -1, np.int64), pairs[2]]),
        requirement=req,
        regime=regime,
        agent_names=names,
        location_names=_LocationNames(g),
    )
    _check_acyclic(tpg, g, room)
    return tpg


#: Above this many used edges a roadmap is not checked for the tight regime.
GRID_LIKE_MAX_EDGES = 3000


def _grid_like(vis: _Visits, req: Requirement) -> bool:
    """Whether the roadmap edges the plan uses are laid out like grid edges, so that the
    tight claim radii (half the longest edge at a vertex + r + margin/2) are sound:
    with ``D = 2 r_max + margin``, every vertex has a used edge at least ``D`` long, used
    edges meet at 90 degrees or more, and used segments without a common vertex (and
    robots that never move) are at least ``D`` apart (``docs/post.md``)."""
    # not at the top: `hierplan solve` loads this module, not the geometry
    from hierplan_opt.schedule.geometry import segment_distance

    need = 2.0 * float(req.radius.max(initial=0.0)) + req.margin
    u, w = vis.V[vis.mv], vis.V[vis.mv + 1]
    key = np.unique(np.stack([np.minimum(u, w), np.maximum(u, w)], axis=1), axis=0)
    counts = np.diff(vis.ptr)
    still = vis.V[vis.ptr[:-1][counts == 1]]
    segs = np.concatenate([key, np.stack([still, still], axis=1)]).reshape(-1, 2)
    if len(segs) > GRID_LIKE_MAX_EDGES:
        return False
    first = np.unique(vis.V, return_index=True)
    pos_of = dict(zip(first[0].tolist(), vis.pos[first[1]], strict=True))
    a = np.array([pos_of[int(x)] for x in segs[:, 0]])
    b = np.array([pos_of[int(x)] for x in segs[:, 1]])
    # Every vertex on a used edge has one at least D long; edges meet at >= 90 degrees.
    longest: dict[int, float] = {}
    dirs: dict[int, list[np.ndarray]] = {}
    for (p, q), pa, pb in zip(key.tolist(), a[: len(key)], b[: len(key)], strict=True):
        d = pb - pa
        n = float(np.linalg.norm(d))
        for x, vec in ((p, d / n), (q, -d / n)):
            longest[x] = max(longest.get(x, 0.0), n)
            for other in dirs.get(x, []):
                if float(np.dot(other, vec)) > 1e-9:
                    return False
            dirs.setdefault(x, []).append(vec)
    if any(need > L for L in longest.values()):
        return False
    # Used segments without a common vertex stay D apart.
    ii, jj = np.triu_indices(len(segs), 1)
    apart = (
        (segs[ii, 0] != segs[jj, 0])
        & (segs[ii, 0] != segs[jj, 1])
        & (segs[ii, 1] != segs[jj, 0])
        & (segs[ii, 1] != segs[jj, 1])
    )
    ii, jj = ii[apart], jj[apart]
    return bool(not len(ii) or segment_distance(a[ii], b[ii], a[jj], b[jj]).min() >= need)


def _locks(
    vis: _Visits, seg: Segments, geo: np.ndarray, req: Requirement, regime: str
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Lock points: every visited vertex, and in the general regime points that cut
    every used edge longer than the largest ``D_ij`` into equal pieces no longer than
    it. Returns the nearest vertex of each lock (for messages), the positions, and
    ``rho``: half the longest piece at each lock (every robot is within ``rho`` of a lock
    of its own path)."""
    verts = np.unique(vis.V)
    dest = np.where(seg.moving, seg.origin + 1, seg.origin)
    u, w = vis.V[seg.origin], vis.V[dest]
    h = 2.0 * float(req.radius.max(initial=0.0)) + req.margin
    pieces = np.ones(len(geo), dtype=np.int64)
    if regime == "general" and h > 0:
        pieces = np.maximum(np.ceil(geo / h * (1 - 1e-12)).astype(np.int64), 1)
    half = np.where(seg.moving, geo / pieces / 2.0, 0.0)
    rho = np.zeros(len(verts))
    np.maximum.at(rho, np.searchsorted(verts, u), half)
    np.maximum.at(rho, np.searchsorted(verts, w), half)
    pos = [_vertex_positions(vis, verts)]
    near = [verts]
    rhos = [rho]
    # Cut points of each used edge (either direction once).
    cut = np.flatnonzero(seg.moving & (pieces > 1))
    if len(cut):
        key = np.stack([np.minimum(u[cut], w[cut]), np.maximum(u[cut], w[cut])], axis=1)
        _, first = np.unique(key, axis=0, return_index=True)
        cut = cut[first]
        n = pieces[cut]
        k = np.concatenate([np.arange(1, m) for m in n.tolist()])
        e = np.repeat(cut, n - 1)
        # Measured from the edge's smaller vertex id, so both directions agree.
        flip = u[e] > w[e]
        a = np.where(flip[:, None], seg.b[e], seg.a[e])
        b = np.where(flip[:, None], seg.a[e], seg.b[e])
        frac = k / np.repeat(n, n - 1)
        pos.append(a + frac[:, None] * (b - a))
        near.append(np.where(frac <= 0.5, np.minimum(u[e], w[e]), np.maximum(u[e], w[e])))
        rhos.append(np.repeat(half[cut], n - 1))
    return np.concatenate(near), np.concatenate(pos), np.concatenate(rhos)


def _vertex_positions(vis: _Visits, verts: np.ndarray) -> np.ndarray:
    """Positions of ``verts`` (sorted, all visited) from their first visits."""
    uniq, first = np.unique(vis.V, return_index=True)
    return vis.pos[first[np.searchsorted(uniq, verts)]]


def _room(g, geo: np.ndarray) -> str:
    """``cells of 1 m`` / ``roadmap edges of up to 2.5 m``, for error messages."""
    if g.kind == "grid":
        return f"cells of {g.cell_size:g} m"
    return f"roadmap edges of up to {float(geo.max(initial=0.0)):g} m"


def _check_acyclic(tpg: TPG, g, room: str) -> None:
    """Refuse, in one line, a TPG whose precedences wait for each other in a cycle."""
    topo = topo_order(tpg.num_nodes, tpg.arc_src, tpg.arc_dst)
    if topo.is_dag:
        return
    cyc = find_cycle(tpg.num_nodes, tpg.arc_src, tpg.arc_dst, topo.cyclic)
    succ = cyc[1:] + cyc[:1]
    key = {
        (int(a), int(b)): k for k, (a, b) in enumerate(zip(tpg.arc_src, tpg.arc_dst, strict=True))
    }
    robots: list[int] = []
    locs: list[str] = []
    steps: set[int] = set()
    need = 0.0
    req = tpg.requirement
    for u, w in zip(cyc, succ, strict=True):
        k = key[(u, w)]
        if tpg.arc_type[k] != TYPE2:
            continue
        a, b = int(tpg.node_agent[u]), int(tpg.node_agent[w])
        robots.append(a)
        need = max(need, req.required(a, b))
        lock = int(tpg.arc_lock[k])
        locs.append(tpg.location_names[lock] if lock >= 0 else "edges that meet in the open")
        steps.add(int(tpg.node_step[w]))
    names = [tpg.agent_names[a] for a in robots]
    ring = " -> ".join([*names, names[0]]) if names else "?"
    where = ", ".join(dict.fromkeys(locs))
    if tpg.regime == "none" and "edges that meet in the open" in locs:
        raise ClearanceError(
            f"robots {ring} wait for each other around {where}: each would have to pass "
            "a point where roadmap edges cross, overlap or run through a vertex only "
            "after the next one has; MAPF-POST cannot order them without two robots "
            "meeting, replan"
        )
    if tpg.regime == "none":
        at = f" at step {min(steps) - 1}" if steps else ""
        raise ClearanceError(
            f"robots {ring} rotate{at} around {where}: each moves into the vertex that "
            "the next one leaves in the same step, so each would have to wait for the "
            "next to arrive first; MAPF-POST cannot schedule a rotation without two "
            "robots meeting, replan without rotations"
        )
    why = (
        (
            f"they rotate at step {steps.pop()}: each enters the cell that the next one "
            "leaves, so with any clearance > 0 one of them would have to move first"
        )
        if g.kind == "grid"
        else (
            f"at step {steps.pop()} each moves into room that the next one leaves or "
            "crosses in the same step (a rotation, or edges that cross), so with any "
            "clearance > 0 one of them would have to move first"
        )
        if len(steps) == 1
        else "each holds the surroundings of a cell that the next one needs"
    )
    hint = (
        "margin 0 (point robots then rotate, never on one point)"
        if len(steps) <= 1 and not np.any(req.radius[robots] > 0)
        else "smaller radii, a smaller margin or larger cells"
    )
    raise ClearanceError(
        f"no schedule keeps robots of {describe_types(req, robots)} {need:g} m apart "
        f"(r_i + r_j + margin {req.margin:g}) on {room}: {ring} wait for each other around "
        f"{where} ({why}); replan, or use {hint}"
    )


def _edge_lengths(g, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``g.edge_length`` of many moves at once (binary search in the sorted CSR)."""
    n = g.n
    keys = np.repeat(np.arange(n, dtype=np.int64), np.diff(g.indptr)) * n + g.indices
    want = a.astype(np.int64) * n + b
    if len(keys) and np.all(keys[1:] > keys[:-1]):
        pos = np.minimum(np.searchsorted(keys, want), max(len(keys) - 1, 0))
        if len(keys) and np.array_equal(keys[pos], want):
            return g.lengths[pos].astype(float)
    # Unsorted adjacency or a non-edge: the per-edge lookup names the problem.
    return np.array(
        [g.edge_length(int(u), int(v)) for u, v in zip(a.tolist(), b.tolist(), strict=True)],
        dtype=float,
    )


def _fill_headings(head: np.ndarray, move_agent: np.ndarray) -> np.ndarray:
    """Forward-fill NaN headings within each robot's moves; leading NaNs take the
    first defined heading of that robot (0 if it has none)."""
    out = head.copy()
    if not len(out) or not np.isnan(out).any():
        return out
    prev_agent = -1
    last = math.nan
    pending: list[int] = []
    for k in range(len(out)):
        a = int(move_agent[k])
        if a != prev_agent:
            for q in pending:
                out[q] = 0.0
            pending = []
            prev_agent = a
            last = math.nan
        if math.isnan(out[k]):
            if math.isnan(last):
                pending.append(k)
            else:
                out[k] = last
        else:
            last = float(out[k])
            for q in pending:
                out[q] = last
            pending = []
    for q in pending:
        out[q] = 0.0
    return out


class _LocationNames:
    """Lazy ``vertex id -> printable location`` (grids are large; names are rare)."""

    def __init__(self, graph) -> None:
        self._g = graph

    def __getitem__(self, v: int) -> str:
        return _loc(self._g, v)


def _loc(g, v: int) -> str:
    loc = g.location(v)
    return loc if isinstance(loc, str) else "(" + ", ".join(map(str, loc)) + ")"


def _freeze(tpg: TPG) -> TPG:
    for name in tpg.__dataclass_fields__:
        val = getattr(tpg, name)
        if isinstance(val, np.ndarray):
            val.setflags(write=False)
    return tpg
