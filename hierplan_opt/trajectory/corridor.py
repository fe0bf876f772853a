"""``mode="corridor"``: a double integrator that may cut corners inside a corridor.

Same knots, windows and grid as path mode (:mod:`.refine`), but the robot's position is
free in space. With ``r = c / sqrt(2)``: every node and every interval's middle Bezier
control point of a move lies in the cylinder of radius ``r`` around the move's axis,
between its ends extended by ``r``; every node at an event lies within ``r`` of the
event. The cylinder is convex and holds the balls around its ends, so every arc (the
quadratic Bezier curve of its three control points) stays inside it, and every point
of the cylinder is within ``r sqrt(2) = c`` of the move: the robot never leaves the
corridor of half-width ``c``. The verifier checks the whole motion.
"""

from __future__ import annotations

import numpy as np

from hierplan_opt.trajectory.model import corridor_ocp
from hierplan_opt.trajectory.paths import (
    arrival_term,
    path_bounds,
    path_problem,
    path_warm_start,
)

#: Radius of the cylinders the optimiser uses, as a share of the corridor half-width.
INNER = 1.0 / np.sqrt(2.0)


def solve_corridor(path, windows, opts: dict, warm=None) -> dict:
    """Solve one robot's corridor problem; the same result layout as path mode."""
    pp = path_problem(path, opts["base"])
    N, dim = pp.N, path.knot_pos.shape[1]
    c = float(opts["corridor"]) * INNER
    ip = pp.interval_piece
    kn = pp.knot_node
    node_piece = np.concatenate([ip, [path.num_pieces - 1]])
    start = path.knot_pos[:-1]
    dirs = path.piece_dir
    length = np.diff(path.knot_sigma)

    # ---- bounds: windows on t at the knots; rest at both ends --------------------------------
    lbX1, ubX1, lbU1, ubU1, *_ = path_bounds(pp, windows)
    nx, nu = 2 * dim + 1, dim + 1
    lbX = np.full((nx, N + 1), -np.inf)
    ubX = np.full((nx, N + 1), np.inf)
    lbX[2 * dim], ubX[2 * dim] = lbX1[2], ubX1[2]
    for end, k in ((0, 0), (-1, N)):
        lbX[:dim, k] = ubX[:dim, k] = path.knot_pos[end]
        lbX[dim : 2 * dim, k] = ubX[dim : 2 * dim, k] = 0.0
    lbU = np.full((nu, N), -np.inf)
    ubU = np.full((nu, N), np.inf)
    lbU[dim], ubU[dim] = 0.0, np.inf

    # ---- corridor parameters: node and midpoint of every interval ---------------------------
    par = np.zeros((2 * (2 * dim + 1), N + 1))
    par[:dim] = start[node_piece].T
    par[dim : 2 * dim] = dirs[node_piece].T
    par[2 * dim] = 1.0
    ball = kn[1:-1]
    par[:dim, ball] = path.knot_pos[1:-1].T
    par[2 * dim, ball] = 0.0
    off = 2 * dim + 1
    mp = np.concatenate([ip, [ip[-1]]])
    par[off : off + dim] = start[mp].T
    par[off + dim : off + 2 * dim] = dirs[mp].T
    par[off + 2 * dim] = 1.0

    vmax = path.piece_vmax[node_piece]
    amax = path.piece_amax[node_piece]
    G_lo = np.full((6, N + 1), -np.inf)
    G_hi = np.full((6, N + 1), np.inf)
    G_hi[0] = vmax**2
    G_hi[1] = amax**2
    G_hi[2] = c * c
    G_lo[3] = -c
    G_hi[3] = length[node_piece] + c
    G_lo[3, ball] = -np.inf
    G_hi[3, ball] = np.inf
    G_hi[4] = c * c
    G_lo[5] = -c
    G_hi[5] = length[mp] + c
    G_hi[1, N] = np.inf
    G_lo[4:, N] = -np.inf
    G_hi[4:, N] = np.inf

    # ---- warm start: the path-mode warm start laid on the path --------------------------------
    if warm is not None:
        X0, U0 = warm
    else:
        X1, U1 = path_warm_start(pp, windows.stretch)
        ds = (X1[0] - path.knot_sigma[node_piece])[None, :]
        X0 = np.vstack(
            [start[node_piece].T + dirs[node_piece].T * ds, dirs[node_piece].T * X1[1], X1[2]]
        )
        U0 = np.vstack([dirs[ip].T * U1[0], U1[1]])
    w_arr, T = arrival_term(path, windows.stretch, opts["weights"])
    w = np.array([*opts["weights"][:2], w_arr, T], dtype=float)
    p = np.concatenate([par.ravel(order="F"), w])

    tries = []
    res = None
    ok = False
    X = U = None
    for name in opts["solvers"]:
        ocp = corridor_ocp(N, dim, name)
        res = ocp.solve(
            ocp.pack(X0, U0),
            ocp.pack(lbX, lbU),
            ocp.pack(ubX, ubU),
            p,
            ocp.pack_g(G_lo, np.zeros(nx)),
            ocp.pack_g(G_hi, np.zeros(nx)),
        )
        X, U = ocp.unpack(res.z)
        ok = res.success and _corridor_feasible(X, U, (lbX, ubX), dim)
        tries.append((name, res.wall, res.iterations, ok))
        if ok:
            break
    assert res is not None and X is not None and U is not None
    traj = _trajectory(path, pp, X, U, dim) if ok else None
    return {
        "ok": ok,
        "X": X,
        "U": U,
        "pp": pp,
        "traj": traj,
        "wall": sum(t[1] for t in tries),
        "iterations": sum(t[2] for t in tries),
        "solver": res.solver,
        "status": res.status,
        "tries": tuple(tries),
        "N": N,
    }


def _corridor_feasible(X, U, bounds, dim) -> bool:
    lower, upper = bounds
    x = X
    tol = 1e-6
    slack = tol * (1 + np.abs(x))
    if not (np.all(x - lower >= -slack) and np.all(upper - x >= -slack)):
        return False
    p, v, t = X[:dim], X[dim : 2 * dim], X[2 * dim]
    a, h = U[:dim], U[dim]
    res = np.concatenate(
        [
            (p[:, 1:] - (p[:, :-1] + h * v[:, :-1] + 0.5 * h * h * a)).ravel(),
            (v[:, 1:] - (v[:, :-1] + h * a)).ravel(),
            t[1:] - (t[:-1] + h),
        ]
    )
    return bool(np.all(np.abs(res) <= tol * (1.0 + np.abs(t[-1]))) and np.all(h >= -tol))


def _trajectory(path, pp, X: np.ndarray, U: np.ndarray, dim: int) -> dict:
    p, v, t = X[:dim].T.copy(), X[dim : 2 * dim].T.copy(), np.maximum.accumulate(X[2 * dim])
    a = U[:dim].T.copy()
    speed = np.linalg.norm(v, axis=1)
    theta = np.where(speed > 1e-9, np.arctan2(v[:, 1], v[:, 0]), np.nan)
    # Heading: the direction of motion, held while at rest.
    last = path.theta0
    for k in range(len(theta)):
        if np.isnan(theta[k]):
            theta[k] = last
        last = theta[k]
    ev_t = _event_times(path, pp, p, v, a, t)
    return {
        "t": t,
        "p": p,
        "v": v,
        "a": a,
        "theta": theta,
        "omega": np.zeros(len(t)),
        "alpha": np.zeros(len(a)),
        "event_times": ev_t,
    }


def _event_times(path, pp, p, v, a, t) -> np.ndarray:
    """Knot events: the node time. Other events: the closest approach between the
    knots around them."""
    out = np.empty(len(path.event_ids))
    knot_of = {int(e): q for q, e in enumerate(path.knot_event.tolist()) if e >= 0}
    for i, e in enumerate(path.event_ids.tolist()):
        q = knot_of.get(int(e))
        if q is not None:
            out[i] = t[pp.knot_node[q]]
            continue
        # Between the previous and the next knot on the 1-D axis.
        s = path.event_axis[i]
        qa = int(np.searchsorted(path.knot_sigma, s, side="right") - 1)
        ka, kb = int(pp.knot_node[qa]), int(pp.knot_node[min(qa + 1, len(pp.knot_node) - 1)])
        ts = np.linspace(t[ka], t[kb], 64)
        k = np.clip(np.searchsorted(t, ts, side="right") - 1, 0, len(a) - 1)
        tau = ts - t[k]
        P = p[k] + v[k] * tau[:, None] + 0.5 * a[k] * (tau * tau)[:, None]
        target = _event_pos(path, i)
        out[i] = ts[int(np.argmin(np.linalg.norm(P - target, axis=1)))]
    return out


def _event_pos(path, i: int) -> np.ndarray:
    s = path.event_axis[i]
    q = int(np.clip(np.searchsorted(path.knot_sigma, s, side="right") - 1, 0, path.num_pieces - 1))
    return path.knot_pos[q] + path.piece_dir[q] * (s - path.knot_sigma[q])
