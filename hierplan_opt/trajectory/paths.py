"""One robot's path and its time-grid problem: the shared ground of :mod:`.refine`,
:mod:`.corridor`, :mod:`.polish` and :mod:`.profile` (none of which imports another).

A :class:`RobotPath` is a robot's polyline from the schedule's events (knots joined by
straight moves and turns in place); :func:`path_problem` puts it on a free time grid and
:func:`path_bounds` / :func:`path_warm_start` give that grid's bounds and warm start.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from hierplan_opt.trajectory.events import EventNetwork
from hierplan_opt.trajectory.model import grid_size
from hierplan_opt.trajectory.windows import Windows

#: Largest stretch factor tried before giving up.
MAX_STRETCH = 256.0
#: Feasibility tolerance of a returned solution (bounds, dynamics).
FEAS_TOL = 1e-6
#: Angles below this are straight on (radians).
ANGLE_TOL = 1e-9


@dataclass(frozen=True)
class Limits:
    v_max: float
    a_max: float
    omega_max: float
    alpha_max: float

    def as_dict(self) -> dict[str, float]:
        return {
            "v_max": self.v_max,
            "a_max": self.a_max,
            "omega_max": self.omega_max,
            "alpha_max": self.alpha_max,
        }


# ---------------------------------------------------------------------- one robot's path
@dataclass(frozen=True, eq=False)
class RobotPath:
    """A robot's path as a sequence of knots joined by pieces.

    Knots are the robot's STN events plus, for unicycles, the end of every turn in
    place. Pieces are straight moves (``sigma`` in metres) or turns in place (``sigma``
    in radians). ``knot_t`` is the schedule's time of each knot (the warm start).
    """

    name: str
    model: str
    limits: Limits
    knot_sigma: np.ndarray
    knot_event: np.ndarray  # STN event id, -1 for the end of a turn
    knot_stop: np.ndarray  # the robot is at rest there
    knot_t: np.ndarray
    knot_pos: np.ndarray  # (m, dim) metres
    piece_turn: np.ndarray  # bool
    piece_dir: np.ndarray  # (m-1, dim) unit direction of a move
    piece_theta0: np.ndarray  # heading at the start of the piece
    piece_sign: np.ndarray  # +1 / -1: direction of a turn
    piece_vmax: np.ndarray
    piece_amax: np.ndarray
    theta0: float
    event_ids: np.ndarray  # every STN event of the robot, in path order
    event_axis: np.ndarray  # their coordinate on the 1-D axis

    @property
    def num_pieces(self) -> int:
        return len(self.knot_sigma) - 1

    @classmethod
    def straight(
        cls,
        sigma: Sequence[float],
        t: Sequence[float],
        stop: Sequence[bool],
        v_max: float = 1.0,
        a_max: float = 1.0,
    ) -> RobotPath:
        """An omni-directional robot on a straight line along x (for examples): knots at
        ``sigma`` metres, scheduled at times ``t``, at rest where ``stop``.

        Example
        -------
        >>> p = RobotPath.straight([0.0, 2.0, 4.0], [0.0, 3.0, 6.0], [True, False, True])
        >>> p.num_pieces, p.knot_pos[:, 0].tolist()
        (2, [0.0, 2.0, 4.0])
        """
        s = np.asarray(sigma, dtype=float)
        m = len(s)
        pos = np.zeros((m, 2))
        pos[:, 0] = s
        ones = np.ones(m - 1)
        return cls(
            "r",
            "double_integrator",
            Limits(v_max, a_max, np.inf, np.inf),
            s,
            np.arange(m),
            np.asarray(stop, dtype=bool),
            np.asarray(t, dtype=float),
            pos,
            np.zeros(m - 1, dtype=bool),
            np.tile([1.0, 0.0], (m - 1, 1)),
            np.zeros(m - 1),
            ones,
            v_max * ones,
            a_max * ones,
            0.0,
            np.arange(m),
            s.copy(),
        )


def _wrap(a: float) -> float:
    return (a + math.pi) % (2 * math.pi) - math.pi


def robot_path(
    net: EventNetwork,
    j: int,
    model: str,
    limits: Limits,
    *,
    turns: bool,
    knots: np.ndarray | None = None,
) -> RobotPath:
    """Knots and pieces of robot ``j``.

    ``turns``: insert a turn in place at every corner. ``knots`` (a mask over all
    events): the events that must be grid nodes (those with a window); the robot's
    first and last events and every corner are knots anyway. Other events lie inside a
    piece and get their passage time from the solution.
    """
    ev = np.array(list(net.events(j)), dtype=np.int64)
    P = net.pos[ev]
    T = net.times[ev]
    dim = P.shape[1]
    d = np.diff(P, axis=0)
    ell = np.linalg.norm(d, axis=1)
    # A piece of length 0 (a robot that sets off from its start only after a ``wait``
    # event) is a rest: both ends are stops, and it takes the direction of the next move.
    zero = ell <= 1e-12
    dirs = d / np.where(zero, 1.0, ell)[:, None] if len(ell) else np.zeros((0, dim))
    for k in np.flatnonzero(zero)[::-1].tolist():
        if k + 1 < len(dirs):
            dirs[k] = dirs[k + 1]
    for k in np.flatnonzero(zero).tolist():
        if not np.any(dirs[k]) and k > 0:
            dirs[k] = dirs[k - 1]
    heads = np.arctan2(dirs[:, 1], dirs[:, 0]) if len(ell) else np.zeros(0)
    if dim == 3 and len(ell):
        # Vertical moves keep the previous heading (it is only reported, never used).
        flat = np.hypot(dirs[:, 0], dirs[:, 1]) > 1e-12
        for k in range(len(heads)):
            if not flat[k]:
                heads[k] = heads[k - 1] if k else 0.0
    ev_sigma = np.concatenate([[0.0], np.cumsum(ell)])
    need = np.ones(len(ev), dtype=bool) if knots is None else np.asarray(knots)[ev].copy()
    need[0] = need[-1] = True
    corner = np.zeros(len(ev), dtype=bool)
    if len(ell) > 1:
        corner[1:-1] = np.einsum("ij,ij->i", dirs[:-1], dirs[1:]) < 1.0 - ANGLE_TOL
    rest = corner.copy()
    rest[1:][zero] = True
    rest[:-1][zero] = True
    need |= rest
    sig, evl, stop, tt, pos = [0.0], [int(ev[0])], [True], [float(T[0])], [P[0]]
    p_turn, p_dir, p_th0, p_sign, p_v, p_a = [], [], [], [], [], []
    last = 0  # index (into ev) of the last knot
    for i in range(1, len(ev)):
        if not need[i]:
            continue
        # ---- a straight move from event ``last`` to event ``i`` -------------------------
        k = i - 1
        p_turn.append(False)
        p_dir.append(dirs[k])
        p_th0.append(float(heads[k]))
        p_sign.append(1.0)
        p_v.append(limits.v_max)
        p_a.append(limits.a_max)
        sig.append(sig[-1] + float(ev_sigma[i] - ev_sigma[last]))
        evl.append(int(ev[i]))
        stop.append(bool(rest[i]))
        tt.append(float(T[i]))
        pos.append(P[i])
        last = i
        if corner[i]:
            dth = _wrap(float(heads[i] - heads[i - 1]))
            if turns and abs(dth) > ANGLE_TOL:
                # ---- a turn in place at the corner -----------------------------------
                dur = abs(dth) / limits.omega_max
                t_end = min(tt[-1] + dur, 0.5 * (tt[-1] + float(T[i + 1])))
                p_turn.append(True)
                p_dir.append(np.zeros(dim))
                p_th0.append(float(heads[i - 1]))
                p_sign.append(1.0 if dth > 0 else -1.0)
                p_v.append(limits.omega_max)
                p_a.append(limits.alpha_max)
                sig.append(sig[-1] + abs(dth))
                evl.append(-1)
                stop.append(True)
                tt.append(t_end)
                pos.append(P[i])
    stop[-1] = True
    # Arc-length coordinate of every event on the 1-D axis (turns add radians).
    knot_ev = np.asarray(evl, dtype=np.int64)
    ax = np.asarray(sig, dtype=float)
    event_axis = np.empty(len(ev))
    kpos = {int(e): q for q, e in enumerate(knot_ev.tolist()) if e >= 0}
    q_base, i_base = 0, 0
    for i in range(len(ev)):
        q = kpos.get(int(ev[i]))
        if q is not None:
            event_axis[i] = ax[q]
            # A move that follows a turn in place starts at the turn's end.
            q_base = q + 1 if q + 1 < len(knot_ev) and knot_ev[q + 1] < 0 else q
            i_base = i
        else:
            event_axis[i] = ax[q_base] + float(ev_sigma[i] - ev_sigma[i_base])
    arr = np.asarray
    return RobotPath(
        name=net.agent_names[j],
        model=model,
        limits=limits,
        knot_sigma=ax,
        knot_event=knot_ev,
        knot_stop=arr(stop, dtype=bool),
        knot_t=arr(tt, dtype=float),
        knot_pos=arr(pos, dtype=float).reshape(-1, dim),
        piece_turn=arr(p_turn, dtype=bool),
        piece_dir=arr(p_dir, dtype=float).reshape(-1, dim),
        piece_theta0=arr(p_th0, dtype=float),
        piece_sign=arr(p_sign, dtype=float),
        piece_vmax=arr(p_v, dtype=float),
        piece_amax=arr(p_a, dtype=float),
        theta0=float(heads[0]) if len(heads) else 0.0,
        event_ids=ev,
        event_axis=event_axis,
    )


def allocate(durations: np.ndarray, base: int) -> tuple[int, np.ndarray]:
    """Intervals per piece: ``base`` each, the rest of the grid size by duration.

    Example
    -------
    >>> allocate(np.array([1.0, 3.0]), 2)
    (8, array([3, 5]))
    """
    P = len(durations)
    need = max(base * P, 1)
    N = grid_size(need)
    n = np.full(P, base, dtype=np.int64)
    extra = N - base * P
    if extra and P:
        w = np.maximum(durations, 0.0)
        w = w / w.sum() if w.sum() > 0 else np.full(P, 1.0 / P)
        share = w * extra
        add = np.floor(share).astype(np.int64)
        rest = extra - int(add.sum())
        if rest:
            add[np.argsort(-(share - add))[:rest]] += 1
        n += add
    return N, n


# ---------------------------------------------------------------------- path mode
@dataclass(frozen=True, eq=False)
class PathProblem:
    """The bounds, warm start and layout of one robot's path-mode problem."""

    path: RobotPath
    N: int
    counts: np.ndarray  # intervals per piece
    knot_node: np.ndarray  # grid node of every knot
    interval_piece: np.ndarray  # piece of every interval


def path_problem(path: RobotPath, base: int) -> PathProblem:
    dur = np.diff(path.knot_t)
    N, counts = allocate(dur, base)
    knot_node = np.concatenate([[0], np.cumsum(counts)])
    interval_piece = np.repeat(np.arange(path.num_pieces), counts)
    return PathProblem(path, N, counts, knot_node, interval_piece)


def _effective_windows(
    path: RobotPath, windows: Windows, upto: int | None
) -> tuple[np.ndarray, np.ndarray]:
    """Windows of the knots (turn ends get the range their neighbours allow); knots after
    ``upto`` are left free (used to find the first way-point a robot cannot meet)."""
    m = len(path.knot_sigma)
    lo = np.full(m, 0.0)
    hi = np.full(m, np.inf)
    has = path.knot_event >= 0
    lo[has] = windows.lo[path.knot_event[has]]
    hi[has] = windows.hi[path.knot_event[has]]
    if upto is not None:
        lo[upto + 1 :] = 0.0
        hi[upto + 1 :] = np.inf
    lo = np.maximum.accumulate(lo)
    hi = np.minimum.accumulate(hi[::-1])[::-1]
    return lo, hi


def path_bounds(
    pp: PathProblem, windows: Windows, upto: int | None = None, free: bool = False
) -> tuple[np.ndarray, ...]:
    """``lbX, ubX (4, N+1), lbU, ubU (2, N), lbG, ubG (2, N+1), LO, HI (N+1)`` of a
    robot's path-mode problem.

    ``free``: the stretch factor ``f`` of the windows is a variable in ``[1,
    MAX_STRETCH]`` and the windows are the constraints ``f lo <= t <= f hi`` at the
    knots; otherwise ``f = 1`` and the windows are bounds on ``t``.
    """
    path, N = pp.path, pp.N
    kn, ip = pp.knot_node, pp.interval_piece
    lo, hi = _effective_windows(path, windows, upto)
    lbX = np.empty((4, N + 1))
    ubX = np.empty((4, N + 1))
    # Interior nodes take their piece's ranges; knots are pinned below.
    node_piece = np.concatenate([ip, [path.num_pieces - 1]])
    lbX[0] = path.knot_sigma[node_piece]
    ubX[0] = path.knot_sigma[node_piece + 1]
    lbX[1] = 0.0
    ubX[1] = path.piece_vmax[node_piece]
    # ---- knots: fixed position, rest at stops -------------------------------------------
    lbX[0, kn] = ubX[0, kn] = path.knot_sigma
    vk = np.minimum(
        np.concatenate([[np.inf], path.piece_vmax]), np.concatenate([path.piece_vmax, [np.inf]])
    )
    ubX[1, kn] = np.where(path.knot_stop, 0.0, vk)
    LO = np.zeros(N + 1)
    HI = np.zeros(N + 1)
    lbG = np.full((2, N + 1), -np.inf)
    ubG = np.full((2, N + 1), np.inf)
    if free:
        lbX[2] = 0.0
        ubX[2] = np.inf
        lbX[2, 0] = ubX[2, 0] = lo[0]
        lbX[3] = 1.0
        ubX[3] = MAX_STRETCH
        LO[kn] = lo
        lbG[0, kn] = 0.0  # t_k - f lo_k >= 0
        fin = np.isfinite(hi)
        HI[kn[fin]] = hi[fin]
        ubG[1, kn[fin]] = 0.0  # t_k - f hi_k <= 0
    else:
        lbX[2] = lo[node_piece]
        ubX[2] = hi[node_piece + 1]
        lbX[2, kn] = lo
        ubX[2, kn] = hi
        lbX[3] = ubX[3] = 1.0
    lbU = np.empty((2, N))
    ubU = np.empty((2, N))
    lbU[0] = -path.piece_amax[ip]
    ubU[0] = path.piece_amax[ip]
    lbU[1] = 0.0
    ubU[1] = np.inf
    return lbX, ubX, lbU, ubU, lbG, ubG, LO, HI


def arrival_term(path: RobotPath, stretch: float, weights: Sequence[float]) -> tuple[float, float]:
    """``(w_arr, T)`` of the arrival term ``w_arr (t_N - T)^2`` of a robot's objective.

    ``weights``: ``(accel, time, step, arrival)``. ``T`` is the robot's scheduled
    arrival stretched like its windows, ``w_arr = arrival * accel * a_max^2 / T`` (the
    units of the acceleration energy, so the balance is the same in any units of length
    and time). Without the term a robot whose last window reaches the makespan (every
    robot that finishes early) takes all of it: its acceleration energy falls with its
    arrival time. ``T`` is a constant, never ``f T`` with a free factor ``f``, so the
    term never pulls a free stretch factor up.

    Example
    -------
    >>> from types import SimpleNamespace
    >>> p = SimpleNamespace(knot_t=np.array([0.0, 2.0]), limits=Limits(1, 3, math.inf, math.inf))
    >>> arrival_term(p, 1.5, (1.0, 0.01, 1e-3, 10.0))  # 10 * 1 * 3**2 / (2 * 1.5)
    (30.0, 3.0)
    """
    T = float(path.knot_t[-1]) * stretch
    a = float(path.limits.a_max)
    if T <= 0 or not math.isfinite(a) or len(weights) < 4:
        return 0.0, T
    return float(weights[3]) * float(weights[0]) * a * a / T, T


def path_warm_start(pp: PathProblem, stretch: float) -> tuple[np.ndarray, np.ndarray]:
    """The constant-velocity schedule on the grid (rest at the stops)."""
    path, N = pp.path, pp.N
    X = np.empty((4, N + 1))
    X[3] = 1.0
    U = np.zeros((2, N))
    kt = path.knot_t * stretch
    for p in range(path.num_pieces):
        a, b = int(pp.knot_node[p]), int(pp.knot_node[p + 1])
        n = b - a
        s0, s1 = path.knot_sigma[p], path.knot_sigma[p + 1]
        t0, t1 = kt[p], max(kt[p + 1], kt[p] + 1e-6)
        f = np.arange(n + 1) / n
        X[0, a : b + 1] = s0 + f * (s1 - s0)
        X[2, a : b + 1] = t0 + f * (t1 - t0)
        speed = min((s1 - s0) / (t1 - t0), float(path.piece_vmax[p]))
        X[1, a : b + 1] = speed
        U[1, a:b] = (t1 - t0) / n
    X[1, pp.knot_node[path.knot_stop]] = 0.0
    h = np.maximum(U[1], 1e-9)
    U[0] = np.clip(
        np.diff(X[1]) / h, -path.piece_amax[pp.interval_piece], path.piece_amax[pp.interval_piece]
    )
    return X, U


def _feasible(
    X: np.ndarray, U: np.ndarray, bounds: tuple[np.ndarray, ...], tol: float = FEAS_TOL
) -> bool:
    lbX, ubX, lbU, ubU, lbG, ubG, LO, HI = bounds

    def ok(v: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> bool:
        scale = 1.0 + np.abs(np.where(np.isfinite(hi), hi, 0.0))
        return bool(np.all(v >= lo - tol * scale) and np.all(v <= hi + tol * scale))

    s, v, t, f = X
    G = np.stack([t - f * LO, t - f * HI])
    if not (ok(X, lbX, ubX) and ok(U, lbU, ubU) and ok(G, lbG, ubG)):
        return False
    a, h = U
    res = np.concatenate(
        [
            s[1:] - (s[:-1] + h * v[:-1] + 0.5 * h * h * a),
            v[1:] - (v[:-1] + h * a),
            t[1:] - (t[:-1] + h),
            f[1:] - f[:-1],
        ]
    )
    # Continuity in metres, m/s and seconds (the verifier allows 1e-5 m, m/s).
    return bool(np.all(np.abs(res) <= tol + 1e-9 * abs(float(t[-1]))))
