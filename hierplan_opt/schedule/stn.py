"""Simple temporal network (STN) on a temporal plan graph.

One time variable per TPG node (the moment the robot passes that point); every arc
``e = (u, v)`` carries ``lb_e <= t_v - t_u <= ub_e``. Node bounds
``release_v <= t_v <= deadline_v`` stand for the arcs from the start event X0 (fixed at
time 0): every robot's first node has ``release = deadline = 0``.

Lower bounds of a robot's own arcs come from the true geometry and its kinematics.
**A robot is at rest at every vertex of its path** (at its start and goal, while it
waits, and while a differential-drive robot turns in place), and passes markers on
the fly:

* without ``a_max``: a piece of length ``l`` takes at least ``l / v_max`` (length along
  the path in ``Graph.edge_length`` units: roadmap lengths, or cells times the cell
  size);
* with ``a_max`` (``acceleration=True``): a move ``u -> w`` of length ``L`` takes at
  least :func:`accel_time` ``(L)`` (rest to rest); reaching a marker at distance ``s``
  after leaving ``u`` takes at least :func:`reach_time` ``(s)`` (from rest, full
  acceleration, not stopping), and so does the way from a marker to ``w`` (full
  deceleration, by symmetry); between two markers ``ds / v_max``. Every such bound
  holds for *any* motion with ``|a| <= a_max`` and ``v <= v_max`` that rests at the
  vertices, so none asks for less time than physics allows. Pieces to and from a
  vertex carry the bound themselves; move arcs (kind :data:`MOVE`) add it for marker
  pairs further apart;
* differential drive: ``+ |dtheta| / omega_max`` on every arc that leaves a vertex where
  the robot turns (a robot starts facing its first move).

Type-2 arcs get ``[epsilon + turn, inf)``: the later robot may pass its point once the
earlier one has *left* its point (at a vertex where it turns in place, after the turn;
in the plain TPG of point robots the earlier point is the robot's next vertex, and
reaching it means it has left the shared one: no turn is added).
Upper bounds come from deadlines (arrival of a robot at its final node) or from any
``ub`` set by the caller (:meth:`STN.with_bounds`).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from hierplan_opt.core.errors import InputError
from hierplan_opt.core.instance import Instance
from hierplan_opt.core.reprs import short_repr
from hierplan_opt.schedule.clearance import finite_nonnegative
from hierplan_opt.schedule.dag import TopoOrder, csr, topo_order
from hierplan_opt.schedule.tpg import TPG, TYPE1, TYPE2, VERTEX, WAIT

#: STN arc kinds: a robot's piece between consecutive nodes, a Type-2 precedence,
#: and a move arc carrying an acceleration bound between non-consecutive nodes.
PIECE = 1
PRECEDENCE = 2
MOVE = 3
ARC_KIND_NAMES = {PIECE: "piece", PRECEDENCE: "precedence", MOVE: "move"}


def accel_time(length: float, v_max: float, a_max: float) -> float:
    """Least time to travel ``length`` from standstill to standstill.

    Triangular profile ``2 sqrt(length / a_max)`` when the robot cannot reach
    ``v_max`` (``length <= v_max**2 / a_max``), otherwise trapezoidal
    ``length / v_max + v_max / a_max``.

    Example
    -------
    >>> accel_time(1.0, 1.0, 1.0), accel_time(4.0, 1.0, 1.0), accel_time(0.25, 1.0, 1.0)
    (2.0, 5.0, 1.0)
    """
    return float(_accel(np.array([length], dtype=float), v_max, a_max)[0])


def reach_time(length: float, v_max: float, a_max: float) -> float:
    """Least time to *pass* a point ``length`` ahead, starting from standstill.

    ``sqrt(2 length / a_max)`` while accelerating (``length <= v_max**2 / (2 a_max)``),
    else ``length / v_max + v_max / (2 a_max)``. By symmetry also the least time from
    passing a point to standing still ``length`` further on.

    Example
    -------
    >>> reach_time(0.5, 1.0, 1.0), reach_time(2.0, 1.0, 1.0)
    (1.0, 2.5)
    """
    return float(_reach(np.array([length], dtype=float), v_max, a_max)[0])


def _accel(length: np.ndarray, v: np.ndarray | float, a: np.ndarray | float) -> np.ndarray:
    length = np.maximum(length, 0.0)
    tri = length <= v * v / a
    return np.where(tri, 2.0 * np.sqrt(length / a), length / v + v / a)


def _reach(length: np.ndarray, v: np.ndarray | float, a: np.ndarray | float) -> np.ndarray:
    length = np.maximum(length, 0.0)
    acc = length <= v * v / (2.0 * a)
    return np.where(acc, np.sqrt(2.0 * length / a), length / v + v / (2.0 * a))


@dataclass(frozen=True, eq=False)
class STN:
    """Simple temporal network over the nodes of a :class:`TPG` (read-only arrays).

    Attributes
    ----------
    tpg : TPG
    arc_src, arc_dst : (M,) int
    lb, ub : (M,) float
        ``lb <= t_dst - t_src <= ub`` (``ub`` is ``inf`` when unbounded).
    arc_kind : (M,) int
        :data:`PIECE`, :data:`PRECEDENCE` or :data:`MOVE`.
    arc_length : (M,) float
        Path length of a piece (0 for other arcs): the LP's safety constraint is
        ``t_dst - t_src <= arc_length * R`` on pieces.
    arc_turn : (M,) float
        Part of an arc's lower bound spent turning in place (0 for most arcs).
    release, deadline : (N,) float
        Node bounds relative to X0 = 0.
    v_max : (K,) float
        Top speed of every robot.

    The lower-bound arcs form a DAG (the TPG's arcs and move arcs along a robot's
    path): :attr:`topo` is its topological order, :meth:`out_arcs` / :meth:`in_arcs` the
    arcs at a node (for incremental re-solving, :func:`~hierplan_opt.schedule.
    solve_graph.fix_and_propagate`).
    """

    __repr__ = short_repr  # arrays and long tuples summarised (core/reprs)

    tpg: TPG
    arc_src: np.ndarray
    arc_dst: np.ndarray
    lb: np.ndarray
    ub: np.ndarray
    arc_kind: np.ndarray
    arc_length: np.ndarray
    arc_turn: np.ndarray
    release: np.ndarray
    deadline: np.ndarray
    v_max: np.ndarray  # per agent

    @property
    def num_nodes(self) -> int:
        return self.tpg.num_nodes

    @property
    def num_arcs(self) -> int:
        return len(self.arc_src)

    @property
    def has_upper_bounds(self) -> bool:
        """True when a finite upper bound other than the start nodes' time 0 exists."""
        if np.isfinite(self.ub).any():
            return True
        d = self.deadline.copy()
        d[self.tpg.start_nodes()] = np.inf
        return bool(np.isfinite(d).any())

    @cached_property
    def topo(self) -> TopoOrder:
        """Topological order (waves) of the lower-bound arcs."""
        return topo_order(self.num_nodes, self.arc_src, self.arc_dst)

    @cached_property
    def _out(self) -> tuple[np.ndarray, np.ndarray]:
        return csr(self.num_nodes, self.arc_src)

    @cached_property
    def _in(self) -> tuple[np.ndarray, np.ndarray]:
        return csr(self.num_nodes, self.arc_dst)

    def out_arcs(self, v: int) -> np.ndarray:
        """Arc ids leaving node ``v``."""
        order, ptr = self._out
        return order[ptr[v] : ptr[v + 1]]

    def in_arcs(self, v: int) -> np.ndarray:
        """Arc ids entering node ``v``."""
        order, ptr = self._in
        return order[ptr[v] : ptr[v + 1]]

    def with_bounds(
        self,
        *,
        lb: np.ndarray | None = None,
        ub: np.ndarray | None = None,
        deadline: np.ndarray | None = None,
        release: np.ndarray | None = None,
    ) -> STN:
        """A copy with other arc bounds / node bounds (arrays of the same shape).

        Example
        -------
        >>> from hierplan_opt.core.graph import Graph
        >>> from hierplan_opt.core.plan import Plan
        >>> from hierplan_opt.schedule.tpg import build_tpg
        >>> inst = Instance.mapf(Graph.grid(3, 1), [(0, 0)], [(2, 0)])
        >>> stn = build_stn(inst, build_tpg(inst, Plan.from_paths([[0, 1, 2]])))
        >>> stn.with_bounds(lb=stn.lb * 2).lb.tolist()  # a robot running at half speed
        [2.0, 2.0]
        """

        def arr(x: np.ndarray | None, old: np.ndarray) -> np.ndarray:
            if x is None:
                return old
            out = np.array(x, dtype=float)
            if out.shape != old.shape:
                raise InputError(f"bounds of shape {out.shape} for an STN of shape {old.shape}")
            return out

        return _freeze(
            STN(
                self.tpg,
                self.arc_src,
                self.arc_dst,
                arr(lb, self.lb),
                arr(ub, self.ub),
                self.arc_kind,
                self.arc_length,
                self.arc_turn,
                arr(release, self.release),
                arr(deadline, self.deadline),
                self.v_max,
            )
        )


def build_stn(
    instance: Instance,
    tpg: TPG,
    *,
    epsilon: float = 0.0,
    acceleration: bool = True,
    deadlines: Mapping[str | int, float] | None = None,
) -> STN:
    """The STN of ``tpg`` with bounds from each robot's kinematics.

    Parameters
    ----------
    epsilon : float
        Lower bound of every Type-2 arc (``>= 0``, seconds).
    acceleration : bool
        Use the acceleration-aware bounds for robots whose kinematics give ``a_max``.
    deadlines : mapping, optional
        Agent name (or index) -> latest arrival time at its final vertex.

    Example
    -------
    >>> from hierplan_opt import Graph, Plan
    >>> from hierplan_opt.schedule import build_tpg
    >>> g = Graph.grid(3, 1, cell_size=2.0)
    >>> inst = Instance.mapf(g, [(0, 0)], [(2, 0)])
    >>> stn = build_stn(inst, build_tpg(inst, Plan.from_paths([[0, 1, 2]])))
    >>> stn.lb.tolist()  # two cells of 2 m at 1 m/s
    [2.0, 2.0]
    """
    epsilon = finite_nonnegative(epsilon, f"epsilon must be a finite number >= 0, got {epsilon!r}")
    kins = [a.kinematics for a in instance.agents]
    v_max = np.array([k.v_max for k in kins], dtype=float)
    omega = np.array(
        [k.omega_max if k.drive == "differential" and k.omega_max else np.inf for k in kins],
        dtype=float,
    )
    a_max = np.array(
        [k.a_max if acceleration and k.a_max is not None else np.inf for k in kins], dtype=float
    )
    n = tpg.num_nodes
    agent = tpg.node_agent
    is_vertex = tpg.node_kind == VERTEX
    at_rest = is_vertex | (tpg.node_kind == WAIT)
    with np.errstate(invalid="ignore"):
        turn_time = np.where(is_vertex, tpg.node_turn / omega[agent], 0.0)
    turn_time = np.where(np.isfinite(turn_time), turn_time, 0.0)  # omni: turn / inf
    # The rest point a node's move starts from (u) and ends at (w), for acceleration.
    idx = np.arange(n)
    move_u = np.maximum.accumulate(np.where(at_rest, idx, -1))
    move_w = np.minimum.accumulate(np.where(at_rest, idx, n)[::-1])[::-1]

    # ---- pieces: consecutive nodes of a robot --------------------------------------
    is1 = tpg.arc_type == TYPE1
    src1 = tpg.arc_src[is1]
    dst1 = tpg.arc_dst[is1]
    ag1 = agent[src1]
    length1 = tpg.node_s[dst1] - tpg.node_s[src1]
    turn1 = turn_time[src1]
    lb1 = _bound(length1, at_rest[src1], at_rest[dst1], v_max[ag1], a_max[ag1]) + turn1

    # ---- move arcs: acceleration bounds between non-consecutive nodes of one move ---
    markers = np.flatnonzero(~at_rest & np.isfinite(a_max[agent]))
    to_m = markers[markers > move_u[markers] + 1]  # u -> marker (not adjacent)
    from_m = markers[markers < move_w[markers] - 1]  # marker -> w (not adjacent)
    whole = np.unique(move_u[markers])  # u -> w for every move with a marker
    whole_w = move_w[markers[np.searchsorted(move_u[markers], whole)]]
    src3 = np.concatenate([move_u[to_m], from_m, whole])
    dst3 = np.concatenate([to_m, move_w[from_m], whole_w])
    ag3 = agent[src3]
    lb3 = _bound(
        tpg.node_s[dst3] - tpg.node_s[src3],
        at_rest[src3],
        at_rest[dst3],
        v_max[ag3],
        a_max[ag3],
    )
    turn3 = turn_time[src3]
    lb3 = lb3 + turn3

    # ---- precedences ---------------------------------------------------------------
    is2 = tpg.arc_type == TYPE2
    src2 = tpg.arc_src[is2]
    dst2 = tpg.arc_dst[is2]
    # Plain TPG: the source is the earlier robot's next vertex, reached after it left
    # the shared one; its turn there does not matter.
    turn2 = turn_time[src2] if tpg.regime != "none" else np.zeros(len(src2))
    lb2 = float(epsilon) + turn2

    arc_src = np.concatenate([src1, src2, src3])
    arc_dst = np.concatenate([dst1, dst2, dst3])
    lb = np.concatenate([lb1, lb2, lb3])
    m1, m2, m3 = len(src1), len(src2), len(src3)
    kind = np.concatenate(
        [np.full(m1, PIECE, np.int8), np.full(m2, PRECEDENCE, np.int8), np.full(m3, MOVE, np.int8)]
    )
    arc_length = np.concatenate([length1, np.zeros(m2 + m3)])
    arc_turn = np.concatenate([turn1, turn2, turn3])
    _check_finite(instance, tpg, arc_src, arc_dst, lb, v_max)
    ub = np.full(len(arc_src), np.inf)

    release = np.zeros(n)
    deadline = np.full(n, np.inf)
    deadline[tpg.start_nodes()] = 0.0
    if deadlines:
        _set_deadlines(instance, tpg, deadline, deadlines)
    return _freeze(
        STN(tpg, arc_src, arc_dst, lb, ub, kind, arc_length, arc_turn, release, deadline, v_max)
    )


def _bound(
    length: np.ndarray,
    from_vertex: np.ndarray,
    to_vertex: np.ndarray,
    v: np.ndarray,
    a: np.ndarray,
) -> np.ndarray:
    """Least time for ``length`` between two points of one move (rest at vertices)."""
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        plain = length / v
        finite_a = np.isfinite(a)
        a_safe = np.where(finite_a, a, 1.0)
        rest_rest = _accel(length, v, a_safe)
        rest_pass = _reach(length, v, a_safe)
    one_end = from_vertex ^ to_vertex
    out = np.where(from_vertex & to_vertex, rest_rest, np.where(one_end, rest_pass, plain))
    return np.where(finite_a, np.maximum(out, plain), plain)


def _check_finite(
    instance: Instance,
    tpg: TPG,
    src: np.ndarray,
    dst: np.ndarray,
    lb: np.ndarray,
    v_max: np.ndarray,
) -> None:
    bad = np.flatnonzero(~np.isfinite(lb))
    if not len(bad):
        return
    k = int(bad[0])
    j = int(tpg.node_agent[src[k]])
    length = float(tpg.node_s[dst[k]] - tpg.node_s[src[k]])
    raise InputError(
        f"robot {instance.agents[j].name!r} needs a time that is not a finite number to go "
        f"from {tpg.label(int(src[k]))} to {tpg.label(int(dst[k]))} ({length:g} m at v_max "
        f"{v_max[j]:g} m/s); MAPF-POST cannot represent this schedule"
    )


def _set_deadlines(
    instance: Instance,
    tpg: TPG,
    deadline: np.ndarray,
    deadlines: Mapping[str | int, float],
) -> None:
    K = tpg.num_agents
    names = {a.name: i for i, a in enumerate(instance.agents)}
    finals = tpg.final_nodes()
    for key, when in deadlines.items():
        if isinstance(key, (int, np.integer)) and not isinstance(key, bool):
            if not 0 <= int(key) < K:
                raise InputError(f"deadline for agent index {key}: no such agent")
            j = int(key)
        elif key in names:
            j = names[key]
        else:
            raise InputError(f"deadline for unknown agent {key!r}")
        when = finite_nonnegative(
            when,
            f"deadline of agent {instance.agents[j].name!r} must be a finite number >= 0, "
            f"got {when!r}",
        )
        f = int(finals[j])
        deadline[f] = min(deadline[f], when)


def _freeze(stn: STN) -> STN:
    for name in ("arc_src", "arc_dst", "lb", "ub", "arc_kind", "arc_length", "arc_turn"):
        getattr(stn, name).setflags(write=False)
    for name in ("release", "deadline", "v_max"):
        getattr(stn, name).setflags(write=False)
    return stn
