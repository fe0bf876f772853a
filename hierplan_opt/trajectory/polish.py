"""Path mode, second stage: a convex QP that smooths the profile solver's speeds.

Once the knot times are fixed (by :mod:`hierplan_opt.trajectory.profile`), the grid's
step lengths ``h_n`` are constants and the path-mode problem of one robot is a convex
QP in its progress ``s_n``, speed ``v_n`` (nodes) and acceleration ``a_n`` (intervals):

    min  sum_n h_n a_n^2                            (= integral of |a|^2 dt)
    s.t. s_{n+1} = s_n + h_n v_n + h_n^2 a_n / 2,   v_{n+1} = v_n + h_n a_n,
         s = sigma_k at the node of knot k,  v = 0 at stops,
         0 <= v_n <= v_max,  |a_n| <= a_max,  s_n inside its piece.

The time grid is the profile's (its zero-length intervals dropped), so the profile's
own motion is a feasible point: the QP never needs a larger stretch, keeps every knot
time (so every window and the safety distance) and only lowers the objective. The
stage-wise structure (states ``(s, v)``, input ``a``) is solved by HPIPM's Riccati
interior point through CasADi's ``conic``; the solver is built once per padded grid
length (:data:`SIZES`) and reused.
"""

from __future__ import annotations

import functools
import time
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from hierplan_opt.trajectory.paths import PathProblem, _feasible, path_bounds
from hierplan_opt.trajectory.windows import Windows

#: Grid lengths the QP is built for (a robot's grid is padded up to the next one with
#: zero-length intervals); building costs O(N^2) in CasADi, so few sizes are kept.
SIZES = (32, 64, 128, 192, 256, 384, 512, 768, 1024, 1536, 2048, 3072, 4096)
#: The QP plugin (measured against osqp, highs, qpoases, proxqp: formulations/trajectory.md).
PLUGIN = "hpipm"
#: HPIPM's tolerances, and the largest error of a knot's position accepted (metres).
TOL = 1e-10
KNOT_TOL = 1e-7


@dataclass(frozen=True, eq=False)
class Polished:
    """A robot's polished motion ``(X, U)`` on ``pp``, or (``ok`` False) the input."""

    ok: bool
    X: np.ndarray
    U: np.ndarray
    pp: PathProblem
    before: float  # integral of a^2 of the input
    after: float  # of the result (= before when not ok)
    wall: float  # QP seconds
    status: str


def accel_energy(U: np.ndarray) -> float:
    """``sum_n h_n a_n^2`` of a grid's controls ``U = (a, h)``."""
    return float(np.sum(U[1] * U[0] ** 2))


@functools.cache
def _qp(N: int) -> tuple[Any, Any, Any, np.ndarray]:
    """The QP for ``N`` intervals, variables ``z = (s_0, v_0, a_0, s_1, ..., s_N, v_N)``:
    CasADi ``conic`` with HPIPM, the sparsity of ``A`` and ``H``, and the order of the
    ``A`` entries of :func:`_a_values` in CasADi's column-compressed storage."""
    import casadi as ca  # heavy module: CasADi

    n = np.arange(N)
    r = 2 * n
    # rows 2n: s_{n+1} - s_n - h v_n - h^2/2 a_n; rows 2n+1: v_{n+1} - v_n - h a_n
    rows = np.stack([r, r, r, r, r + 1, r + 1, r + 1], axis=1).ravel()
    cols = np.stack(
        [3 * n + 3, 3 * n, 3 * n + 1, 3 * n + 2, 3 * n + 4, 3 * n + 1, 3 * n + 2], axis=1
    ).ravel()
    order = np.lexsort((rows, cols))
    A = ca.Sparsity.triplet(2 * N, 3 * N + 2, rows.tolist(), cols.tolist())
    ai = (3 * n + 2).tolist()
    H = ca.Sparsity.triplet(3 * N + 2, 3 * N + 2, ai, ai)
    opts = {
        "error_on_fail": False,
        "N": N,
        "nx": [2] * (N + 1),
        "nu": [1] * N + [0],
        "ng": [0] * (N + 1),
        "hpipm": {
            "mode": "robust",
            "res_g_max": TOL,
            "res_b_max": TOL,
            "res_d_max": TOL,
            "res_m_max": TOL,
        },
    }
    return ca.conic("polish", PLUGIN, {"h": H, "a": A}, opts), A, H, order


def _a_values(h: np.ndarray, order: np.ndarray) -> np.ndarray:
    v = np.empty((len(h), 7))
    v[:, 0], v[:, 1], v[:, 2], v[:, 3] = 1.0, -1.0, -h, -0.5 * h * h
    v[:, 4], v[:, 5], v[:, 6] = 1.0, -1.0, -h
    return v.ravel()[order]


def _pack(s: np.ndarray, v: np.ndarray, a: np.ndarray) -> np.ndarray:
    z = np.empty(3 * len(a) + 2)
    z[0::3], z[1::3], z[2::3] = s, v, a
    return z


def compress(
    pp: PathProblem, X: np.ndarray, U: np.ndarray
) -> tuple[PathProblem, np.ndarray, np.ndarray]:
    """The same motion without zero-length intervals (a piece keeps at least one)."""
    h = U[1]
    piece = pp.interval_piece
    keep = h > 0
    first = np.concatenate([[True], piece[1:] != piece[:-1]])
    has = np.zeros(pp.path.num_pieces, dtype=bool)
    has[piece[keep]] = True
    keep |= first & ~has[piece]
    idx = np.flatnonzero(keep)
    nodes = np.concatenate([[0], idx + 1])
    counts = np.bincount(piece[idx], minlength=pp.path.num_pieces)
    knot_node = np.concatenate([[0], np.cumsum(counts)])
    pp2 = replace(pp, N=len(idx), counts=counts, knot_node=knot_node, interval_piece=piece[idx])
    X2 = X[:, nodes].copy()
    X2[0, knot_node] = pp.path.knot_sigma
    return pp2, X2, U[:, idx].copy()


def polish(pp: PathProblem, X: np.ndarray, U: np.ndarray, windows: Windows) -> Polished:
    """Solve the QP on the grid of the feasible motion ``(X, U)`` (its knot times kept).

    Falls back to the input (``ok`` False, ``status`` saying why) when the grid is
    larger than :data:`SIZES` allows or the QP's answer fails the same checks as the
    input, or is not better.

    Example
    -------
    A 4 m line whose middle knot (2 m) must be passed in [3, 3.5] s, from rest to rest
    in 6 s (``v_max = a_max = 1``): the profile's motion, then the QP's.

    >>> from types import SimpleNamespace
    >>> from hierplan_opt.trajectory import profile
    >>> from hierplan_opt.trajectory.paths import RobotPath
    >>> path = RobotPath.straight([0.0, 2.0, 4.0], [0.0, 3.0, 6.0], [True, False, True])
    >>> lo, hi = np.array([0.0, 3.0, 0.0]), np.array([0.0, 3.5, np.inf])
    >>> pr = profile.solve(path, 1.0, lo, hi)
    >>> r = polish(pr.pp, pr.X, pr.U, SimpleNamespace(lo=lo, hi=hi, stretch=1.0))
    >>> r.ok, round(r.before, 4), round(r.after, 4), float(r.X[2][r.pp.knot_node[1]])
    (True, 0.963, 0.963, 3.0)
    """
    import casadi as ca  # heavy module: CasADi

    pp, X, U = compress(pp, X, U)
    before = accel_energy(U)
    N = pp.N
    size = next((s for s in SIZES if s >= N), None)
    if size is None:
        return Polished(False, X, U, pp, before, before, 0.0, f"grid of {N} too large")
    bounds = path_bounds(pp, windows)
    lbX, ubX, lbU, ubU = bounds[:4]
    pad = size - N
    h = np.concatenate([U[1], np.zeros(pad)])

    def ext(x: np.ndarray, k: int) -> np.ndarray:
        return np.concatenate([x, np.full(k, x[-1])])

    lbx = _pack(ext(lbX[0], pad), ext(lbX[1], pad), ext(lbU[0], pad))
    ubx = _pack(ext(ubX[0], pad), ext(ubX[1], pad), ext(ubU[0], pad))
    x0 = _pack(ext(X[0], pad), ext(X[1], pad), np.concatenate([U[0], np.zeros(pad)]))
    solver, A, H, order = _qp(size)
    t0 = time.perf_counter()
    res = solver(
        h=ca.DM(H, 2 * h),
        g=ca.DM.zeros(3 * size + 2),
        a=ca.DM(A, _a_values(h, order)),
        lba=0.0,
        uba=0.0,
        lbx=lbx,
        ubx=ubx,
        x0=x0,
    )
    wall = time.perf_counter() - t0
    # HPIPM may stop short of its 1e-10 residuals (iteration limit); its answer is still
    # kept when it passes the checks below, which do not rely on the solver.
    converged = bool(solver.stats().get("success", False))
    z = np.asarray(res["x"]).ravel()
    if not np.all(np.isfinite(z)):
        return Polished(False, X, U, pp, before, before, wall, "qp failed")
    X2 = X.copy()
    X2[0], X2[1] = z[0 : 3 * N + 1 : 3], z[1 : 3 * N + 2 : 3]
    knot_error = float(np.max(np.abs(X2[0, pp.knot_node] - pp.path.knot_sigma)))
    X2[0, pp.knot_node] = pp.path.knot_sigma
    X2[1] = np.clip(X2[1], lbX[1], ubX[1])  # round-off of the interior point (1e-18 m/s)
    U2 = U.copy()
    U2[0] = np.clip(np.where(U[1] > 0, z[2 : 3 * N : 3], 0.0), lbU[0], ubU[0])
    after = accel_energy(U2)
    if knot_error > KNOT_TOL or not _feasible(X2, U2, bounds):
        why = "qp answer fails the checks" if converged else "qp failed"
        return Polished(False, X, U, pp, before, before, wall, why)
    if after > before * (1 + 1e-9) + 1e-12:
        return Polished(False, X, U, pp, before, before, wall, "qp answer not better")
    return Polished(True, X2, U2, pp, before, after, wall, "qp" if converged else "qp (checked)")
