"""Temporal plan graph (TPG) of a discrete plan, plain or augmented with safety markers.

A node is an event "robot j reaches a point of its path". The plain TPG has one node
per visit of a location (consecutive waits merged): "robot j enters p_j(t)". Type-1
arcs run along each robot's path; a Type-2 arc ``u -> w`` says that event ``w`` of one
robot may happen only after event ``u`` of another robot.

Type-2 arcs come from the order in which robots visit each location. For every
location, the visits are sorted by their entry timestep; for two *consecutive* visits
by different robots (j before k) the plain TPG adds "j enters its next location" ->
"k enters the location". Arcs to later visits follow transitively through the
Type-1 chain of the robots in between, so the first later visit suffices.

The augmented TPG (``delta > 0``) puts two safety markers on every move a -> b: ``m1``
at distance ``delta`` past ``a`` and ``m2`` at distance ``delta`` before ``b``. Type-2
arcs then run from j's marker past the shared location to k's marker before it: k may
come within ``delta`` of the location only once j is ``delta`` beyond it. A marker that
no Type-2 arc touches (one arc in, one arc out) is merged away, so only the markers
that carry a precedence remain.

Nodes of robot j are contiguous, in path order: ``agent_ptr[j]:agent_ptr[j+1]``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from hierplan_opt.core.errors import InputError
from hierplan_opt.core.instance import Instance
from hierplan_opt.core.plan import Plan

#: Node kinds.
VERTEX = 0
LEAVE = 1  # marker m1: ``delta`` past the vertex being left
ENTER = 2  # marker m2: ``delta`` before the vertex being entered
KIND_NAMES = ("vertex", "leave", "enter")

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
        Robot, kind (:data:`VERTEX`, :data:`LEAVE`, :data:`ENTER`) and the vertex the
        node is at or ``delta`` away from.
    node_step : (N,) int
        Discrete timestep of the event in the plan (vertex nodes: entry step; markers:
        the step at which the move starts).
    node_pos : (N, dim) float
        Geometric position (``Graph.position`` units, i.e. grid cells times cell size).
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
    delta : float
        Marker distance (0 for the plain TPG).
    """

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
    delta: float
    agent_names: tuple[str, ...]
    location_names: tuple[str, ...]

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

    def label(self, v: int) -> str:
        """A short human-readable name of node ``v``, e.g. ``agent1 enters (2, 0)``."""
        who = self.agent_names[int(self.node_agent[v])]
        loc = self.location_names[int(self.node_vertex[v])]
        kind = int(self.node_kind[v])
        if kind == VERTEX:
            return f"{who} at {loc}"
        if kind == LEAVE:
            return f"{who} {self.delta:g} past {loc}"
        return f"{who} {self.delta:g} before {loc}"


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


def build_tpg(instance: Instance, plan: Plan, delta: float = 0.0) -> TPG:
    """The (augmented, when ``delta > 0``) temporal plan graph of a *valid* plan.

    The plan is assumed valid (``postprocess`` validates it first); ``delta`` must be
    below half of every move's geometric length (checked by ``postprocess``).

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
    >>> build_tpg(inst, plan, delta=0.25).num_nodes  # 6 vertices + 2 markers kept
    8
    """
    g = instance.graph
    if delta < 0 or not math.isfinite(delta):
        raise InputError(f"delta must be a finite number >= 0, got {delta!r}")
    K = plan.num_agents
    scale = g.cell_size if g.kind == "grid" else 1.0

    # ---- visits (waits merged), concatenated over robots -------------------------
    verts_l, steps_l = [], []
    for p in plan.paths:
        vv, ss = _compress(p)
        verts_l.append(vv)
        steps_l.append(ss)
    counts = np.array([len(v) for v in verts_l], dtype=np.int64)
    V = np.concatenate(verts_l)
    T = np.concatenate(steps_l)
    A = np.repeat(np.arange(K), counts)
    visit_ptr = np.zeros(K + 1, dtype=np.int64)
    visit_ptr[1:] = np.cumsum(counts)
    nvis = len(V)
    is_last = np.zeros(nvis, dtype=bool)
    is_last[visit_ptr[1:] - 1] = True
    is_first = np.zeros(nvis, dtype=bool)
    is_first[visit_ptr[:-1]] = True

    # ---- moves: visit i -> visit i+1 of the same robot ------------------------------
    mv = np.flatnonzero(~is_last)  # visit index of each move's origin
    a_v, b_v = V[mv], V[mv + 1]
    coords = g.coords
    pos_a = coords[a_v] * scale
    pos_b = coords[b_v] * scale
    geo = np.linalg.norm(pos_b - pos_a, axis=1)
    elen = _edge_lengths(g, a_v, b_v)
    # Heading of each move (x-y plane); vertical 3D moves keep the previous heading.
    d = pos_b - pos_a
    flat = np.hypot(d[:, 0], d[:, 1]) > 1e-12
    head = np.where(flat, np.arctan2(d[:, 1], d[:, 0]), np.nan)
    # Forward-fill NaNs within each robot (and backward-fill a leading NaN).
    move_agent = A[mv]
    head = _fill_headings(head, move_agent)

    # Per visit: heading when leaving (or the arrival heading for the last visit) and
    # the turn made at the visit before the next move.
    vis_head = np.zeros(nvis)
    vis_head[mv] = head
    last_with_move = visit_ptr[1:] - 1
    has_move = counts > 1
    vis_head[last_with_move[has_move]] = head[np.searchsorted(mv, last_with_move[has_move] - 1)]
    vis_turn = np.zeros(nvis)
    # Turn at visit mv[k] (k not the robot's first move) = |head[k] - head[k-1]|.
    not_first_move = ~is_first[mv]
    kk = np.flatnonzero(not_first_move)
    vis_turn[mv[kk]] = np.abs(_wrap(head[kk] - head[kk - 1]))

    # Cumulative path length per visit.
    vis_s = np.zeros(nvis)
    step_len = np.zeros(nvis)
    step_len[mv + 1] = elen
    cs = np.cumsum(step_len)
    vis_s = cs - np.repeat(cs[visit_ptr[:-1]], counts)

    # ---- Type-2 precedences between consecutive visits of each location -------------
    order = np.lexsort((T, V))
    same_loc = V[order[1:]] == V[order[:-1]]
    other = A[order[1:]] != A[order[:-1]]
    sel = np.flatnonzero(same_loc & other)
    prev_vis = order[sel]  # j's visit (earlier)
    next_vis = order[sel + 1]  # k's visit (later)
    if np.any(is_last[prev_vis]) or np.any(is_first[next_vis]):
        raise InputError("the plan has a vertex conflict (validate it first)")

    names = tuple(a.name for a in instance.agents)
    loc_names = _LocationNames(g)

    if delta == 0:
        node_kind = np.zeros(nvis, dtype=np.int8)
        src2 = prev_vis + 1  # j enters its next location ...
        dst2 = next_vis  # ... before k enters the shared one
        t1 = np.flatnonzero(~is_last)
        arc_src = np.concatenate([t1, src2])
        arc_dst = np.concatenate([t1 + 1, dst2])
        arc_type = np.concatenate(
            [np.full(len(t1), TYPE1, np.int8), np.full(len(src2), TYPE2, np.int8)]
        )
        return _freeze(
            TPG(
                agent_ptr=visit_ptr,
                node_agent=A,
                node_kind=node_kind,
                node_vertex=V,
                node_step=T,
                node_pos=coords[V] * scale,
                node_coord=coords[V].astype(float),
                node_s=vis_s,
                node_turn=vis_turn,
                node_heading=vis_head,
                arc_src=arc_src,
                arc_dst=arc_dst,
                arc_type=arc_type,
                delta=0.0,
                agent_names=names,
                location_names=loc_names,  # type: ignore[arg-type]
            )
        )

    # ---- augmented TPG: vertex, m1, m2 per move ------------------------------------
    # Full node layout before merging: visit i occupies 1 slot if last, else 3.
    width = np.where(is_last, 1, 3)
    base = np.zeros(nvis + 1, dtype=np.int64)
    base[1:] = np.cumsum(width)
    nfull = int(base[-1])
    m1_of_move = base[mv] + 1
    m2_of_move = base[mv] + 2
    # The move index of a visit's outgoing move: position of the visit in mv.
    move_of_visit = np.full(nvis, -1, dtype=np.int64)
    move_of_visit[mv] = np.arange(len(mv))
    src2 = m1_of_move[move_of_visit[prev_vis]]
    dst2 = m2_of_move[move_of_visit[next_vis - 1]]

    keep = np.zeros(nfull, dtype=bool)
    keep[base[:-1]] = True
    keep[src2] = True
    keep[dst2] = True

    kind = np.zeros(nfull, dtype=np.int8)
    kind[m1_of_move] = LEAVE
    kind[m2_of_move] = ENTER
    agent = np.repeat(A, width)
    vertex = np.repeat(V, width)
    vertex[m2_of_move] = b_v
    step = np.repeat(T, width)
    step[m1_of_move] = T[mv + 1] - 1
    step[m2_of_move] = T[mv + 1] - 1
    frac = delta / geo
    pos = np.repeat(coords[V] * scale, width, axis=0)
    pos[m1_of_move] = pos_a + frac[:, None] * d
    pos[m2_of_move] = pos_b - frac[:, None] * d
    cvec = (coords[b_v] - coords[a_v]).astype(float)
    coord = np.repeat(coords[V].astype(float), width, axis=0)
    coord[m1_of_move] = coords[a_v] + frac[:, None] * cvec
    coord[m2_of_move] = coords[b_v] - frac[:, None] * cvec
    s = np.repeat(vis_s, width)
    s[m1_of_move] = vis_s[mv] + frac * elen
    s[m2_of_move] = vis_s[mv + 1] - frac * elen
    turn = np.repeat(vis_turn, width)
    turn[m1_of_move] = 0.0
    turn[m2_of_move] = 0.0
    heading = np.repeat(vis_head, width)
    heading[m1_of_move] = head
    heading[m2_of_move] = head

    newid = np.cumsum(keep) - 1
    kept = np.flatnonzero(keep)
    n_agent = agent[kept]
    counts_new = np.bincount(n_agent, minlength=K)
    agent_ptr = np.zeros(K + 1, dtype=np.int64)
    agent_ptr[1:] = np.cumsum(counts_new)
    last_node = np.zeros(len(kept), dtype=bool)
    last_node[agent_ptr[1:] - 1] = True
    t1 = np.flatnonzero(~last_node)
    arc_src = np.concatenate([t1, newid[src2]])
    arc_dst = np.concatenate([t1 + 1, newid[dst2]])
    arc_type = np.concatenate(
        [np.full(len(t1), TYPE1, np.int8), np.full(len(src2), TYPE2, np.int8)]
    )
    return _freeze(
        TPG(
            agent_ptr=agent_ptr,
            node_agent=n_agent,
            node_kind=kind[kept],
            node_vertex=vertex[kept],
            node_step=step[kept],
            node_pos=pos[kept],
            node_coord=coord[kept],
            node_s=s[kept],
            node_turn=turn[kept],
            node_heading=heading[kept],
            arc_src=arc_src,
            arc_dst=arc_dst,
            arc_type=arc_type,
            delta=float(delta),
            agent_names=names,
            location_names=loc_names,  # type: ignore[arg-type]
        )
    )


def _edge_lengths(g, a: np.ndarray, b: np.ndarray) -> np.ndarray:  # noqa: ANN001
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

    def __init__(self, graph) -> None:  # noqa: ANN001
        self._g = graph

    def __getitem__(self, v: int) -> str:
        loc = self._g.location(v)
        return loc if isinstance(loc, str) else "(" + ", ".join(map(str, loc)) + ")"


def _freeze(tpg: TPG) -> TPG:
    for name in tpg.__dataclass_fields__:
        val = getattr(tpg, name)
        if isinstance(val, np.ndarray):
            val.setflags(write=False)
    return tpg
