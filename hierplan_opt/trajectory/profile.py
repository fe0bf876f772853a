"""Path mode without an NLP: the stretched schedule's times, smooth speeds in between.

Every knot ``k`` of a robot's path (its events with a window, corners, waits, ends of
turns) is passed at its scheduled time stretched by the factor ``f``: ``T_k = f t*_k``.
That time lies in the knot's stretched window, because every decoupled window contains
the schedule's time (formulations/trajectory.md). What remains is a speed ``V_k >= 0``
at every knot (``0`` at stops) and a motion between consecutive knots that covers their
distance ``d`` in exactly ``tau = T_{k+1} - T_k``. The family used: speed linear in time
from ``V_k`` to a middle speed ``p`` at ``tau / 2``, then linear to ``V_{k+1}``, so

    d = tau (V_k + 2 p + V_{k+1}) / 4,     p = 2 d / tau - (V_k + V_{k+1}) / 2,

with ``0 <= p <= v_max`` and both accelerations ``|p - V_k|, |V_{k+1} - p| <= a_max tau
/ 2``: linear inequalities in ``(V_k, V_{k+1})``. Speeds between the three nodes are
linear, so ``0 <= v <= v_max`` holds throughout and progress never goes back.

The chain of speeds is decided exactly for this family: a **forward pass** carries the
interval of speeds each knot can be passed with (the projection of a convex polygon is
an interval; its ends are found among the lines' intersections, see :func:`_step`), a
stop intersects it with ``{0}``, an empty interval is a knot the robot cannot meet at
this factor; a **backward pass** picks every speed inside its interval, the one that
makes the following segment's accelerations smallest. All robots are processed together
(arrays over robots, one step per knot), so deciding one factor for the whole fleet is a
few hundred array operations, and the smallest factor is found by bisection
(feasibility is monotone in ``f``: a motion for ``f`` slowed down by ``f' / f`` is one
for ``f'``).

The family is restricted (knot times are fixed, each segment has one shape), so the
factor it needs is an upper bound of the smallest one; ``refine`` reports the factor
it used, and every result goes through the same checks and the independent
:func:`~hierplan_opt.trajectory.verify.verify`.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from hierplan_opt.trajectory.refine import PathProblem, RobotPath

#: Tolerance of the speed intervals (m/s).
TOL = 1e-9
#: Stands for an infinite acceleration limit (turns without ``alpha_max``).
BIG = 1e9


@dataclass(frozen=True, eq=False)
class Fleet:
    """Every robot's segments as ``(robots, segments)`` arrays, padded with empty ones;
    robots by decreasing number of segments (``index``: their place in the input)."""

    paths: tuple[RobotPath, ...]
    index: np.ndarray
    d: np.ndarray  # distance of each segment
    t: np.ndarray  # scheduled duration (unstretched)
    vmax: np.ndarray
    amax: np.ndarray
    stop: np.ndarray  # the segment's end is a stop
    length: np.ndarray  # segments per robot

    @staticmethod
    def of(paths: Sequence[RobotPath]) -> Fleet:
        index = np.argsort([-p.num_pieces for p in paths], kind="stable")
        paths = [paths[i] for i in index.tolist()]
        n = max((p.num_pieces for p in paths), default=0)
        B = len(paths)
        d, t = np.zeros((B, n)), np.zeros((B, n))
        vmax, amax = np.ones((B, n)), np.full((B, n), BIG)
        stop = np.zeros((B, n), dtype=bool)
        for b, p in enumerate(paths):
            m = p.num_pieces
            d[b, :m] = np.diff(p.knot_sigma)
            t[b, :m] = np.diff(p.knot_t)
            vmax[b, :m] = p.piece_vmax
            amax[b, :m] = np.minimum(p.piece_amax, BIG)
            stop[b, :m] = p.knot_stop[1:]
        length = np.array([p.num_pieces for p in paths], dtype=np.int64)
        return Fleet(tuple(paths), index, d, t, vmax, amax, stop, length)


_PAIRS = [(i, j) for i in range(8) for j in range(i + 1, 8) if i % 4 != j % 4]
_SL = np.array([-1.0, -3.0, -1.0 / 3.0, 0.0])


def _segments(fleet: Fleet, f: float) -> tuple[np.ndarray, ...]:
    """Per segment, at factor ``f``: the lower and upper lines' intercepts
    ``(robots, segments, 4)`` and the intersections of every two lines of different
    slopes ``(robots, segments, 24)``: the candidate ends and kinks of :func:`_step`."""
    tau = f * fleet.t
    pos = tau > 0
    ts = np.where(pos, tau, 1.0)
    c = np.where(pos, 2 * fleet.d / ts, 0.0)
    A = np.minimum(fleet.amax * ts / 2, BIG)
    vm = fleet.vmax
    lo = np.stack([2 * c - 2 * vm, 2 * (c - A), 2 * (c - A) / 3, np.zeros_like(c)], axis=-1)
    up = np.stack([2 * c, 2 * (c + A), 2 * (c + A) / 3, vm], axis=-1)
    ic = np.concatenate([lo, up], axis=-1)
    s8 = np.concatenate([_SL, _SL])
    i, j = np.array(_PAIRS).T
    cand = (ic[..., j] - ic[..., i]) / (s8[i] - s8[j])
    return pos, lo, up, cand


def forward(
    fleet: Fleet, f: float, early: bool = False
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Speed intervals ``(ra, rb)`` at every knot, ``(robots, segments + 1)``, and the
    first segment each robot fails at (``-1``: feasible) at factor ``f``; ``early``:
    stop at the first robot that fails.

    One step per segment, for all robots at once: the speeds ``w`` at a segment's end
    reachable from speeds ``u in [ra, rb]`` at its start. The pairs ``(u, w)`` form a
    convex polygon, so the reachable ``w`` are an interval; the feasible ``u`` are an
    interval whose ends, and the kinks of the lower and upper envelopes of ``w``, are
    intersections of the polygon's lines (or ``ra``, ``rb``): the envelopes evaluated
    at all of them give the interval exactly. An empty segment (``tau = 0``) keeps the
    speed and needs ``d = 0``; a stop needs speed 0.
    """
    B, n = fleet.d.shape
    pos, lo, up, cand = _segments(fleet, f)
    ra, rb = np.zeros((B, n + 1)), np.zeros((B, n + 1))
    fail = np.full(B, -1, dtype=np.int64)
    # robots are sorted by decreasing length: at segment k only the first ``act`` move
    active = np.searchsorted(-fleet.length, -np.arange(n), side="left")
    for k in range(n):
        if early and (fail >= 0).any():
            break
        q = int(active[k])
        a, b = ra[:q, k], rb[:q, k]
        u = np.concatenate([cand[:q, k], a[:, None], b[:, None]], axis=1)
        u = np.clip(u, a[:, None], b[:, None])[:, :, None]
        L = np.max(lo[:q, k, None, :] + _SL * u, axis=-1)
        U = np.min(up[:q, k, None, :] + _SL * u, axis=-1)
        good = L <= U + TOL
        wa = np.maximum(np.where(good, L, np.inf).min(axis=1), 0.0)
        wb = np.where(good, U, -np.inf).max(axis=1)
        p = pos[:q, k]
        ok = np.where(p, good.any(axis=1), fleet.d[:q, k] <= 1e-12)
        wa = np.where(p, wa, a)
        wb = np.where(p, wb, b)
        st = fleet.stop[:q, k]
        ok &= ~st | (wa <= TOL)
        f_q = fail[:q]
        f_q[~ok & (f_q < 0)] = k
        keep = (f_q < 0) & ~st
        ra[:q, k + 1] = np.where(keep, wa, 0.0)
        rb[:q, k + 1] = np.where(keep, np.maximum(wb, wa), 0.0)
    return ra, rb, fail


def backward(fleet: Fleet, f: float, ra: np.ndarray, rb: np.ndarray) -> np.ndarray:
    """A speed at every knot inside its interval, consistent with the next one; each the
    one that makes the following segment's accelerations smallest."""
    B, n = fleet.d.shape
    V = np.zeros((B, n + 1))
    for k in range(n - 1, -1, -1):
        w = V[:, k + 1]
        tau = f * fleet.t[:, k]
        pos = tau > 0
        ts = np.where(pos, tau, 1.0)
        c = np.where(pos, 2 * fleet.d[:, k] / ts, 0.0)
        A = np.minimum(fleet.amax[:, k] * ts / 2, BIG)
        vm = fleet.vmax[:, k]
        lo = np.maximum.reduce(
            [ra[:, k], np.zeros(B), 2 * c - 2 * vm - w, (2 * (c - A) - w) / 3, 2 * (c - A) - 3 * w]
        )
        hi = np.minimum.reduce(
            [rb[:, k], vm, 2 * c - w, (2 * (c + A) - w) / 3, 2 * (c + A) - 3 * w]
        )
        best = np.clip((4 * c - 3 * w) / 5, lo, np.maximum(lo, hi))
        V[:, k] = np.where(pos, best, w)
    V[:, 0] = 0.0
    return V


def smallest_factor(fleet: Fleet, base: float, hi: float, rtol: float) -> float | None:
    """The smallest factor ``f`` in ``[1, hi]`` (within ``rtol``) such that every robot of
    the fleet passes its knots at ``base * f`` times their scheduled times, or None."""

    def ok(f: float) -> bool:
        return bool((forward(fleet, base * f, early=True)[2] < 0).all())

    if ok(1.0):
        return 1.0
    a, b = 1.0, 2.0
    while not ok(b):
        a, b = b, 2 * b
        if b > hi:
            return None
    while b - a > rtol * a:
        m = 0.5 * (a + b)
        if ok(m):
            b = m
        else:
            a = m
    return b


def grid(path: RobotPath, f: float, V: np.ndarray) -> tuple[np.ndarray, np.ndarray, PathProblem]:
    """The robot's motion as a grid solution ``(X, U)``: two intervals per segment, knots
    on the even nodes."""
    m = path.num_pieces
    V = V[: m + 1]
    T = f * path.knot_t
    s = path.knot_sigma
    tau = np.diff(T)
    d = np.diff(s)
    pos = tau > 0
    ts = np.where(pos, tau, 1.0)
    u, w = V[:-1], V[1:]
    p = np.where(pos, 2 * d / ts - 0.5 * (u + w), u)
    p = np.maximum(p, 0.0)
    half = tau / 2
    hs = np.where(pos, half, 1.0)
    X = np.empty((4, 2 * m + 1))
    X[0, 0::2] = s
    X[0, 1::2] = s[:-1] + half * (u + p) / 2
    X[1, 0::2] = V
    X[1, 1::2] = p
    X[2, 0::2] = T
    X[2, 1::2] = T[:-1] + half
    X[3] = 1.0
    U = np.empty((2, 2 * m))
    U[0, 0::2] = np.where(pos, (p - u) / hs, 0.0)
    U[0, 1::2] = np.where(pos, (w - p) / hs, 0.0)
    U[1] = np.repeat(half, 2)
    pp = PathProblem(path, 2 * m, np.full(m, 2), 2 * np.arange(m + 1), np.repeat(np.arange(m), 2))
    return X, U, pp
