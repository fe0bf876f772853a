"""Simple temporal network (STN) on a temporal plan graph.

One time variable per TPG node; every arc ``e = (u, v)`` carries
``lb_e <= t_v - t_u <= ub_e``. Node bounds ``release_v <= t_v <= deadline_v`` stand for
the arcs from the start event X0 (fixed at time 0): every robot's first node has
``release = deadline = 0`` (robots are at their starts at time 0).

Lower bounds of a robot's own arcs (Type-1 pieces) come from the true geometry and its
kinematics:

* ``piece length / v_max`` where the length is measured along the path in
  ``Graph.edge_length`` units (roadmap lengths, or grid cells times ``cell_size``);
* plus ``|dtheta| / omega_max`` on the first piece of a move, for differential-drive
  robots that must turn in place (a robot starts facing its first move);
* optionally (``acceleration=True``, robots with ``a_max``) a move-level arc from the
  move's first to its last node with the standstill-to-standstill bound
  :func:`accel_time` (plus the turn). It is conservative: a robot that goes straight
  on need not stop at the vertex.

Type-2 arcs get ``[epsilon, inf)``. Upper bounds come from deadlines (arrival of a
robot at its final node) or from any ``ub`` set by the caller.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from hierplan_opt.core.errors import InputError
from hierplan_opt.core.instance import Instance
from hierplan_opt.schedule.tpg import TPG, TYPE1, TYPE2, VERTEX

#: STN arc kinds: a robot's piece between consecutive nodes, a Type-2 precedence,
#: and a move-level arc carrying the acceleration bound.
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
    if length <= 0:
        return 0.0
    if length <= v_max * v_max / a_max:
        return 2.0 * math.sqrt(length / a_max)
    return length / v_max + v_max / a_max


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
        Part of a piece's lower bound spent turning in place (0 for other arcs).
    release, deadline : (N,) float
        Node bounds relative to X0 = 0.
    """

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

    def with_bounds(
        self,
        *,
        ub: np.ndarray | None = None,
        deadline: np.ndarray | None = None,
        release: np.ndarray | None = None,
    ) -> STN:
        """A copy with other upper bounds / node bounds (arrays of the same shape)."""
        return _freeze(
            STN(
                self.tpg,
                self.arc_src,
                self.arc_dst,
                self.lb,
                np.asarray(ub if ub is not None else self.ub, dtype=float).copy(),
                self.arc_kind,
                self.arc_length,
                self.arc_turn,
                np.asarray(release if release is not None else self.release, dtype=float).copy(),
                np.asarray(deadline if deadline is not None else self.deadline, dtype=float).copy(),
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
        Lower bound of every Type-2 arc (``>= 0``).
    acceleration : bool
        Add the acceleration-aware bound for robots whose kinematics give ``a_max``.
    deadlines : mapping, optional
        Agent name (or index) -> latest arrival time at its final vertex.

    Example
    -------
    >>> from hierplan_opt.core.graph import Graph
    >>> from hierplan_opt.core.plan import Plan
    >>> from hierplan_opt.schedule.tpg import build_tpg
    >>> g = Graph.grid(3, 1, cell_size=2.0)
    >>> inst = Instance.mapf(g, [(0, 0)], [(2, 0)])
    >>> stn = build_stn(inst, build_tpg(inst, Plan.from_paths([[0, 1, 2]])))
    >>> stn.lb.tolist()  # two cells of 2 m at 1 m/s
    [2.0, 2.0]
    """
    if (
        isinstance(epsilon, bool)
        or not isinstance(epsilon, (int, float))
        or not math.isfinite(epsilon)
        or epsilon < 0
    ):
        raise InputError(f"epsilon must be a finite number >= 0, got {epsilon!r}")
    K = tpg.num_agents
    kins = [a.kinematics for a in instance.agents]
    v_max = np.array([k.v_max for k in kins], dtype=float)
    omega = np.array(
        [k.omega_max if k.drive == "differential" and k.omega_max else np.inf for k in kins],
        dtype=float,
    )

    is1 = tpg.arc_type == TYPE1
    src1 = tpg.arc_src[is1]
    dst1 = tpg.arc_dst[is1]
    ag1 = tpg.node_agent[src1]
    length1 = tpg.node_s[dst1] - tpg.node_s[src1]
    turn1 = tpg.node_turn[src1] / omega[ag1]  # 0 for omni robots (turn / inf)
    turn1 = np.where(np.isfinite(turn1), turn1, 0.0)
    lb1 = length1 / v_max[ag1] + turn1

    is2 = tpg.arc_type == TYPE2
    src2 = tpg.arc_src[is2]
    dst2 = tpg.arc_dst[is2]
    lb2 = np.full(len(src2), float(epsilon))

    # Acceleration-aware move arcs (vertex node -> next vertex node of the robot).
    src3: list[int] = []
    dst3: list[int] = []
    lb3: list[float] = []
    if acceleration:
        for j in range(K):
            a_max = kins[j].a_max
            if a_max is None:
                continue
            nodes = np.flatnonzero(tpg.node_kind[tpg.agent_ptr[j] : tpg.agent_ptr[j + 1]] == VERTEX)
            nodes = nodes + int(tpg.agent_ptr[j])
            for u, w in zip(nodes[:-1].tolist(), nodes[1:].tolist(), strict=True):
                ell = float(tpg.node_s[w] - tpg.node_s[u])
                t = accel_time(ell, float(v_max[j]), float(a_max))
                if math.isfinite(omega[j]):
                    t += float(tpg.node_turn[u]) / float(omega[j])
                if w == u + 1:
                    # One piece: raise its lower bound instead of adding an arc.
                    k = int(np.searchsorted(src1, u))
                    lb1[k] = max(lb1[k], t)
                else:
                    src3.append(u)
                    dst3.append(w)
                    lb3.append(t)

    arc_src = np.concatenate([src1, src2, np.array(src3, dtype=np.int64)])
    arc_dst = np.concatenate([dst1, dst2, np.array(dst3, dtype=np.int64)])
    lb = np.concatenate([lb1, lb2, np.array(lb3, dtype=float)])
    m1, m2, m3 = len(src1), len(src2), len(src3)
    kind = np.concatenate(
        [np.full(m1, PIECE, np.int8), np.full(m2, PRECEDENCE, np.int8), np.full(m3, MOVE, np.int8)]
    )
    arc_length = np.concatenate([length1, np.zeros(m2 + m3)])
    arc_turn = np.concatenate([turn1, np.zeros(m2 + m3)])
    ub = np.full(len(arc_src), np.inf)

    n = tpg.num_nodes
    release = np.zeros(n)
    deadline = np.full(n, np.inf)
    deadline[tpg.start_nodes()] = 0.0
    if deadlines:
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
            if (
                isinstance(when, bool)
                or not isinstance(when, (int, float))
                or not math.isfinite(when)
                or when < 0
            ):
                raise InputError(
                    f"deadline of agent {instance.agents[j].name!r} must be a finite "
                    f"number >= 0, got {when!r}"
                )
            f = int(finals[j])
            deadline[f] = min(deadline[f], float(when))
    return _freeze(
        STN(tpg, arc_src, arc_dst, lb, ub, kind, arc_length, arc_turn, release, deadline, v_max)
    )


def _freeze(stn: STN) -> STN:
    for name in ("arc_src", "arc_dst", "lb", "ub", "arc_kind", "arc_length", "arc_turn"):
        getattr(stn, name).setflags(write=False)
    for name in ("release", "deadline", "v_max"):
        getattr(stn, name).setflags(write=False)
    return stn
