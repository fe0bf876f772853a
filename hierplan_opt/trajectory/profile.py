"""Path mode without an NLP: knot times inside the windows, smooth speeds in between.

A robot's knots ``k`` (its events with a window, corners, waits, ends of turns) are
passed at times ``T_k``; they start at the stretched schedule's times ``f t*_k``, which
lie in the stretched windows because every decoupled window contains the schedule's
time (formulations/trajectory.md), and are only ever *delayed* inside the windows. What
remains is a speed ``V_k >= 0`` at every knot (``0`` at stops) and a motion between
consecutive knots that covers their distance ``d`` in exactly ``tau = T_{k+1} - T_k``.

**One segment.** The speed is linear in time from ``u = V_k`` to a middle speed ``p`` at
``theta tau``, then linear to ``w = V_{k+1}`` (``theta`` from :data:`THETAS`), so

    d = tau (theta u + p + (1 - theta) w) / 2,   p = 2 d / tau - theta u - (1 - theta) w,

and the limits ``0 <= p <= v_max``, ``|p - u| <= a_max theta tau``, ``|w - p| <= a_max
(1 - theta) tau`` are linear inequalities in ``(u, w)``: a convex polygon per
``theta``. Speeds are linear between the nodes, so ``0 <= v <= v_max`` holds throughout
and progress never goes back. A convex combination of two such motions (same ``d``,
``tau``) is again a motion within the limits, with two breakpoints.

**The chain** (:func:`solve`). A forward pass carries the interval of speeds each knot
can be passed with: from ``u in [ra, rb]`` the reachable ``w`` of one polygon are an
interval, whose ends lie among the polygon's line intersections and ``ra``, ``rb``
(:func:`_reach`); over all ``theta`` the hull of these intervals (a speed in between is
a convex combination); a stop intersects it with ``{0}``. When a segment has no
reachable speed, the pass *delays* knots: it lengthens that segment or one of the three
before it (all later knots move by the same delay, so their gaps stay, and no knot
leaves its window: the delay is at most the smallest room ``f hi_j - T_j`` after it),
by the smallest delay found by bisection that lets the pass through. A backward pass
then picks every speed inside its interval: the one (and ``theta``) that makes the
segment's accelerations smallest, or a convex combination of two motions.

A robot that fails even so needs a larger factor: ``refine`` finds each robot's factor
by bisection (a solution for ``f`` slowed down by ``f' / f`` is one for ``f'``, so the
fleet's factor is the largest robot factor and every other solution is slowed down to
it). The family is restricted, so the factor is an upper bound of the smallest one;
every result goes through the same checks and the independent
:func:`~hierplan_opt.trajectory.verify.verify`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from hierplan_opt.core.reprs import short_repr
from hierplan_opt.trajectory.paths import PathProblem, RobotPath

#: Tolerance of the speed intervals (m/s).
TOL = 1e-9
#: Stands for an infinite acceleration limit (turns without ``alpha_max``).
BIG = 1e9
#: Shapes of a segment's speed: linear from ``u`` to ``p`` until ``theta1 tau``, flat
#: until ``theta2 tau``, linear to ``w`` (fractions of the segment's duration).
SHAPES = np.array(
    [(0.5, 0.5), (0.2, 0.2), (0.8, 0.8), (0.1, 0.9), (0.25, 0.75), (0.05, 0.95), (0.1, 0.4),
     (0.6, 0.9), (0.4, 0.6), (0.3, 0.5), (0.5, 0.7)]
)  # fmt: skip
#: How many segments back a failing segment may take its delay from.
LOOKBACK = 1
#: Bisection steps for a delay.
DELAY_STEPS = 8

_PAIRS = np.array([(i, j) for i in range(8) for j in range(i + 1, 8) if i % 4 != j % 4]).T
_T1, _T2 = SHAPES[:, 0], SHAPES[:, 1]
# d / tau = alpha u + g p + beta w
_AL, _BE, _G = _T1 / 2, (1 - _T2) / 2, (1 + _T2 - _T1) / 2
#: Slopes ``dw/du`` of the four pairs of lines of every shape.
_SL = np.stack([-_AL / _BE, -(_AL + _G) / _BE, -_AL / (_G + _BE), np.zeros_like(_AL)], axis=1)
_S8 = np.concatenate([_SL, _SL], axis=1)
_DS = _S8[:, _PAIRS[0]] - _S8[:, _PAIRS[1]]


def _tables(d: np.ndarray, tau: np.ndarray, vmax: np.ndarray, amax: np.ndarray) -> np.ndarray:
    """For segments ``(n,)`` and every ``theta``: ``(n, thetas, 12)`` rows ``u1, u2, uU,
    uL, lo_0..lo_3, up_0..up_3``: the feasible start speeds ``[u1, u2]`` of the polygon
    (``u1 > u2``: empty), where its upper envelope of ``w`` is highest (``uU``) and its
    lower one lowest (``uL``), and the lines' intercepts. The ends and extremes are among
    the lines' intersections and ``0``, ``v_max`` (convexity)."""
    n = len(d)
    ns = len(SHAPES)
    ts = np.where(tau > 0, tau, 1.0)
    cp = (d / ts)[:, None]
    A1 = np.minimum(amax[:, None] * _T1 * ts[:, None], BIG)
    A2 = np.minimum(amax[:, None] * (1 - _T2) * ts[:, None], BIG)
    vm = vmax[:, None] + np.zeros((1, ns))
    z = np.zeros((n, ns))
    al, be, g = _AL, _BE, _G
    lo = np.stack([(cp - g * vm) / be, (cp - g * A1) / be, (cp - g * A2) / (g + be), z], axis=-1)
    up = np.stack([cp / be + z, (cp + g * A1) / be, (cp + g * A2) / (g + be), vm], axis=-1)
    del al
    ic = np.concatenate([lo, up], axis=-1)
    cand = (ic[..., _PAIRS[1]] - ic[..., _PAIRS[0]]) / _DS
    u = np.concatenate([cand, z[..., None], vm[..., None]], axis=-1)
    u = np.clip(u, 0.0, vm[..., None])[..., None]  # (n, thetas, 26, 1)
    L = np.max(lo[:, :, None, :] + _SL[None, :, None, :] * u, axis=-1)
    U = np.min(up[:, :, None, :] + _SL[None, :, None, :] * u, axis=-1)
    good = L <= U + TOL
    uu = u[..., 0]
    u1 = np.where(good, uu, np.inf).min(axis=-1)
    u2 = np.where(good, uu, -np.inf).max(axis=-1)
    kU = np.argmax(np.where(good, U, -np.inf), axis=-1)[..., None]
    kL = np.argmin(np.where(good, L, np.inf), axis=-1)[..., None]
    uU = np.take_along_axis(uu, kU, -1)[..., 0]
    uL = np.take_along_axis(uu, kL, -1)[..., 0]
    return np.concatenate([np.stack([u1, u2, uU, uL], axis=-1), lo, up], axis=-1)


_SLOPES = _SL.tolist()


def _reach(a: float, b: float, rows: list) -> tuple[list, list, list]:
    """End speeds reachable from start speeds in ``[a, b]``: per ``theta`` the interval
    ``(wa, wb)`` and whether it is non-empty (``rows``: the segment's :func:`_tables`).
    The upper envelope is concave and the lower convex, so their extremes over
    ``[max(a, u1), min(b, u2)]`` are at the clipped ``uU`` and ``uL``."""
    wa, wb, ok = [], [], []
    for r, sl in zip(rows, _SLOPES, strict=True):
        lo_u, hi_u = max(a, r[0]), min(b, r[1])
        if lo_u > hi_u + TOL:
            wa.append(math.inf)
            wb.append(-math.inf)
            ok.append(False)
            continue
        x = min(max(r[2], lo_u), hi_u)
        top = min(r[8] + sl[0] * x, r[9] + sl[1] * x, r[10] + sl[2] * x, r[11])
        y = min(max(r[3], lo_u), hi_u)
        bot = max(r[4] + sl[0] * y, r[5] + sl[1] * y, r[6] + sl[2] * y, 0.0)
        wa.append(bot)
        wb.append(top)
        ok.append(bot <= top + TOL)
    return wa, wb, ok


_SHAPES = [
    (t1, t2, al, be, g)
    for t1, t2, al, be, g in zip(
        _T1.tolist(), _T2.tolist(), _AL.tolist(), _BE.tolist(), _G.tolist(), strict=True
    )
]


def _starts(
    w: float, a: float, b: float, d: float, tau: float, vmax: float, amax: float
) -> tuple[list[float], list[float]]:
    """Start speeds ``u in [a, b]`` from which each shape ends at speed ``w``."""
    cp = d / tau
    lo, hi = [], []
    for t1, t2, al, be, g in _SHAPES:
        A1 = min(amax * t1 * tau, BIG)
        A2 = min(amax * (1 - t2) * tau, BIG)
        lo.append(
            max(
                a,
                0.0,
                (cp - g * vmax - be * w) / al,
                (cp - g * A1 - be * w) / (al + g),
                (cp - g * A2 - (g + be) * w) / al,
            )
        )
        hi.append(
            min(
                b,
                vmax,
                (cp - be * w) / al,
                (cp + g * A1 - be * w) / (al + g),
                (cp + g * A2 - (g + be) * w) / al,
            )
        )
    return lo, hi


def _middle(i: int, u: float, w: float, d: float, tau: float) -> float:
    """The flat speed ``p`` of shape ``i`` from ``u`` to ``w``."""
    _, _, al, be, g = _SHAPES[i]
    return (d / tau - al * u - be * w) / g


def _best_start(
    w: float, a: float, b: float, d: float, tau: float, vmax: float, amax: float
) -> tuple[int, float] | None:
    """The shape and start speed ending at ``w`` with the least acceleration energy
    ``(p - u)^2 / theta1 + (w - p)^2 / (1 - theta2)``, or None."""
    lo, hi = _starts(w, a, b, d, tau, vmax, amax)
    cp = d / tau
    best, arg = math.inf, None
    for i, (t1, t2, al, be, g) in enumerate(_SHAPES):
        if lo[i] > hi[i] + TOL:
            continue
        P0 = (cp - be * w) / g
        k2 = al / g
        k1 = k2 + 1
        u = (k1 * P0 / t1 - k2 * (w - P0) / (1 - t2)) / (k1 * k1 / t1 + k2 * k2 / (1 - t2))
        u = min(max(u, lo[i]), max(lo[i], hi[i]))
        p = (cp - al * u - be * w) / g
        e = (p - u) ** 2 / t1 + (w - p) ** 2 / (1 - t2)
        if e < best:
            best, arg = e, (i, u)
    return arg


@dataclass(frozen=True, eq=False)
class Profile:
    """A robot's solution ``(X, U)`` on its own grid ``pp``, or the knot it failed at."""

    __repr__ = short_repr  # arrays and long tuples summarised (core/reprs)

    ok: bool
    X: np.ndarray | None
    U: np.ndarray | None
    pp: PathProblem | None
    failed_knot: int
    delays: int


def solve(
    path: RobotPath, f: float, lo: np.ndarray, hi: np.ndarray, motion: bool = True
) -> Profile:
    """The robot's motion at factor ``f`` with knot windows ``[lo, hi]`` (unstretched,
    propagated along the path): forward pass with delays, backward pass, grid
    (``motion=False``: the forward pass only, to decide feasibility).

    Example
    -------
    A 4 m line whose middle knot (2 m) must be passed in [3, 3.5] s; the schedule says
    3 s there and 6 s at the end:

    >>> from hierplan_opt.trajectory.paths import RobotPath
    >>> path = RobotPath.straight([0.0, 2.0, 4.0], [0.0, 3.0, 6.0], [True, False, True])
    >>> pr = solve(path, 1.0, np.array([0.0, 3.0, 0.0]), np.array([0.0, 3.5, np.inf]))
    >>> pr.ok, float(pr.X[2][pr.pp.knot_node[1]]), float(pr.X[2][-1])
    (True, 3.0, 6.0)
    """
    m = path.num_pieces
    s = path.knot_sigma
    d = np.diff(s)
    T = f * np.asarray(path.knot_t, dtype=float).copy()
    T = np.maximum(T, f * lo)  # turn ends carry no window; events' times lie inside
    HI = f * hi
    vm, am, stop = path.piece_vmax, path.piece_amax, path.knot_stop
    ra, rb = np.zeros(m + 1), np.zeros(m + 1)
    WA = np.zeros((m, len(SHAPES)))
    WB = np.zeros((m, len(SHAPES)))
    OK = np.zeros((m, len(SHAPES)), dtype=bool)
    delays = 0

    tab = _tables(d, np.diff(T), vm, am).tolist()

    def step(k: int, T: np.ndarray, store: bool, rows: list | None = None) -> bool:
        tau = float(T[k + 1] - T[k])
        a, b = float(ra[k]), float(rb[k])
        if tau <= 0:
            if d[k] > 1e-12:
                return False
            wa, wb = a, b
            if store:
                WA[k], WB[k], OK[k] = a, b, False
        else:
            wa_t, wb_t, ok_t = _reach(a, b, tab[k] if rows is None else rows)
            if not any(ok_t):
                return False
            wa = min(x for x, o in zip(wa_t, ok_t, strict=True) if o)
            wb = max(x for x, o in zip(wb_t, ok_t, strict=True) if o)
            if store:
                WA[k], WB[k], OK[k] = wa_t, wb_t, ok_t
        if stop[k + 1]:
            if wa > TOL:
                return False
            wa = wb = 0.0
        if store:
            ra[k + 1], rb[k + 1] = wa, max(wb, wa)
        return True

    def run(j: int, k: int, T: np.ndarray, store: bool) -> bool:
        saved = (ra[j + 1 : k + 2].copy(), rb[j + 1 : k + 2].copy())
        rows = _tables(d[j : k + 1], np.diff(T[j : k + 2]), vm[j : k + 1], am[j : k + 1]).tolist()
        good = True
        for i in range(j, k + 1):
            if not step(i, T, True, rows[i - j]):
                good = False
                break
        if store and good:
            tab[j : k + 1] = rows
        if not store or not good:
            ra[j + 1 : k + 2], rb[j + 1 : k + 2] = saved
        return good

    k = 0
    while k < m:
        if step(k, T, True):
            k += 1
            continue
        fixed = False
        # Delays, in turn: every knot from k + 1 on (the failing segment longer), knot
        # k + 1 alone (the next one shorter), every knot from k on, knot k alone.
        for first, alone in ((k + 1, False), (k + 1, True), (k, False), (k, True)):
            if first < 1 or first > m or first <= k - LOOKBACK:
                continue
            last = first + 1 if alone else m + 1
            room = float(np.min(HI[first:last] - T[first:last]))
            if alone and first < m:
                room = min(room, float(T[first + 1] - T[first]) * (1 - 1e-9))
            room = min(room, 2 * (T[-1] - T[0]) + 10.0)
            if not room > 1e-12:
                continue

            def moved(x: float, first: int = first, last: int = last) -> np.ndarray:
                Tx = T.copy()
                Tx[first:last] += x
                return Tx

            if not run(first - 1, k, moved(room), False):
                continue
            lo_d, hi_d = 0.0, room
            for _ in range(DELAY_STEPS):
                mid = 0.5 * (lo_d + hi_d)
                if run(first - 1, k, moved(mid), False):
                    hi_d = mid
                else:
                    lo_d = mid
            T[:] = moved(hi_d)
            run(first - 1, k, T, True)
            if alone and first < m:
                nxt = slice(first, first + 1)
                tab[first] = _tables(d[nxt], np.diff(T[first : first + 2]), vm[nxt], am[nxt])[
                    0
                ].tolist()
            delays += 1
            fixed = True
            break
        if not fixed:
            return Profile(False, None, None, None, k + 1, delays)
        k += 1
    if not motion:
        return Profile(True, None, None, None, -1, delays)
    # ---- backward: speeds and shapes ---------------------------------------------------
    V = np.zeros(m + 1)
    segs: list[tuple[int, float, float, int, float, float, float]] = []
    for k in range(m - 1, -1, -1):
        w = float(V[k + 1])
        tau = float(T[k + 1] - T[k])
        if tau <= 0:
            V[k] = w
            segs.append((0, w, w, 0, w, w, 1.0))
            continue
        args = (float(d[k]), tau, float(vm[k]), float(am[k]))
        one = _best_start(w, float(ra[k]), float(rb[k]), *args)
        if one is not None:
            i, u = one
            V[k] = u
            segs.append((i, u, w, i, u, w, 1.0))
            continue
        # a convex combination of the highest end below w and the lowest above
        below = np.where(OK[k] & (WB[k] < w), WB[k], -np.inf)
        above = np.where(OK[k] & (WA[k] > w), WA[k], np.inf)
        i1, i2 = int(np.argmax(below)), int(np.argmin(above))
        w1, w2 = float(WB[k, i1]), float(WA[k, i2])
        lo1, hi1 = _starts(w1, float(ra[k]), float(rb[k]), *args)
        lo2, hi2 = _starts(w2, float(ra[k]), float(rb[k]), *args)
        u1 = float(min(max(lo1[i1], ra[k]), rb[k]))
        u2 = float(min(max(lo2[i2], ra[k]), rb[k]))
        lam = (w2 - w) / (w2 - w1) if w2 > w1 else 1.0
        V[k] = lam * u1 + (1 - lam) * u2
        segs.append((i1, u1, w1, i2, u2, w2, lam))
    segs.reverse()
    V[0] = 0.0
    return Profile(True, *_grid(path, T, d, segs), -1, delays)


def _grid(
    path: RobotPath, T: np.ndarray, d: np.ndarray, segs: list
) -> tuple[np.ndarray, np.ndarray, PathProblem]:
    """Five intervals per segment (nodes at the breakpoints of its one or two shapes),
    knots on every fifth node; speeds linear on every interval, positions integrated
    exactly."""
    m = path.num_pieces
    Q = 5
    N = Q * m
    t = np.empty(N + 1)
    v = np.empty(N + 1)
    sig = np.empty(N + 1)
    t[0], v[0], sig[0] = T[0], 0.0, path.knot_sigma[0]

    def speed(x: float, i: int, u: float, p: float, w: float) -> float:
        t1, t2 = _SHAPES[i][0], _SHAPES[i][1]
        if x <= t1:
            return u + (p - u) * x / t1
        if x <= t2:
            return p
        return p + (w - p) * (x - t2) / (1 - t2)

    for k, (i1, u1, w1, i2, u2, w2, lam) in enumerate(segs):
        tau = float(T[k + 1] - T[k])
        xs = sorted((_SHAPES[i1][0], _SHAPES[i1][1], _SHAPES[i2][0], _SHAPES[i2][1]))
        if tau > 0:
            p1 = _middle(i1, u1, w1, float(d[k]), tau)
            p2 = _middle(i2, u2, w2, float(d[k]), tau)
        else:
            p1, p2 = u1, u2
        for q, x in enumerate((*xs, 1.0)):
            n = Q * k + q + 1
            t[n] = T[k] + x * tau if q < Q - 1 else T[k + 1]
            sp = lam * speed(x, i1, u1, p1, w1) + (1 - lam) * speed(x, i2, u2, p2, w2)
            v[n] = max(sp, 0.0)
            sig[n] = sig[n - 1] + (t[n] - t[n - 1]) * (v[n] + v[n - 1]) / 2
        sig[Q * k + Q] = path.knot_sigma[k + 1]
        v[Q * k + Q] = max(lam * w1 + (1 - lam) * w2, 0.0)
    h = np.diff(t)
    a = np.where(h > 0, np.diff(v) / np.where(h > 0, h, 1.0), 0.0)
    X = np.vstack([sig, v, t, np.ones(N + 1)])
    U = np.vstack([a, h])
    pp = PathProblem(path, N, np.full(m, Q), Q * np.arange(m + 1), np.repeat(np.arange(m), Q))
    return X, U, pp


def smallest(
    path: RobotPath,
    lo: np.ndarray,
    hi: np.ndarray,
    top: float,
    rtol: float,
    start: float = 1.0,
) -> tuple[float, Profile] | None:
    """The smallest factor in ``[start, top]`` (bisection within ``rtol``) at which
    :func:`solve` finds the robot's motion, with that motion; None if none."""
    if solve(path, start, lo, hi, motion=False).ok:
        return start, solve(path, start, lo, hi)
    a, b = start, 2.0 * start
    while not solve(path, b, lo, hi, motion=False).ok:
        a, b = b, 2 * b
        if b > top:
            return None
    while b - a > rtol * a:
        mid = math.sqrt(a * b)
        if solve(path, mid, lo, hi, motion=False).ok:
            b = mid
        else:
            a = mid
    return b, solve(path, b, lo, hi)
