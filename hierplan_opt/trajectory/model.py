"""The CasADi optimal-control problems of trajectory refinement (see formulations/trajectory.md).

Both problems live on a grid of ``N`` intervals whose lengths ``h_k`` are decision
variables (a free time grid: events fall on grid nodes, so their windows are plain
bounds), with piecewise-constant acceleration integrated exactly:

* :func:`path_ocp` — the path-velocity decomposition used by ``mode="path"``: the
  robot stays on its polyline and only its progress ``sigma(t)`` is optimised. State
  ``(sigma, v, t)``, control ``(a, h)``. Every robot model reduces to it: a turn in
  place is a piece of the path measured in radians with the turn-rate limits.
* :func:`corridor_ocp` — the double integrator in 2D or 3D for ``mode="corridor"``:
  state ``(p, v, t)``, control ``(a, h)``, with ``|v| <= v_max``, ``|a| <= a_max`` and
  every node (and every interval's midpoint) inside a corridor around its segment.

Every problem is built once per size and solver as an SX ``nlpsol`` Function (a
CasADi Function), then called for each robot with that robot's bounds and warm start:
everything robot-specific (limits, windows, geometry) enters as bounds ``lbx/ubx``,
``lbg/ubg`` or parameters ``p``. An SX ``nlpsol`` evaluates its derivatives several
times faster than ``Opti.to_function`` (MX): measured on a 300-interval path problem,
37 ms vs 138 ms per IPOPT solve and 21 ms vs 113 ms with fatrop. Variables are ordered
stage by stage (``x_0, u_0, x_1, u_1, ..., x_N``) and constraints likewise, which lets
fatrop detect the optimal-control structure.
"""

from __future__ import annotations

import logging
import math
import threading
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from hierplan_opt.core import progress as _progress
from hierplan_opt.core.errors import InputError

log = logging.getLogger(__name__)

SOLVERS = ("ipopt", "fatrop")
#: Grid sizes the problems are built for; a robot uses the smallest that fits.
SIZES = (8, 12, 16, 24, 32, 48, 64, 96, 128, 192, 256, 384, 512, 768, 1024, 1536, 2048, 3072, 4096)
#: IPOPT / fatrop iteration limit.
MAX_ITER = 1000


def grid_size(intervals: int) -> int:
    """The smallest built size that holds ``intervals``.

    Example
    -------
    >>> grid_size(5), grid_size(33), grid_size(2048)
    (8, 48, 2048)
    """
    for n in SIZES:
        if n >= intervals:
            return n
    raise InputError(
        f"a robot needs {intervals} grid intervals; the largest problem has {SIZES[-1]} "
        "(lower intervals_per_piece)"
    )


@dataclass(frozen=True, eq=False)
class OCP:
    """One built problem: the nlpsol Function and its layout.

    ``x`` is ``[x_0, u_0, x_1, u_1, ..., x_N]``; :meth:`pack` and :meth:`unpack` convert
    between that vector and ``(X, U)`` with ``X`` of shape ``(nx, N+1)`` and ``U`` of
    shape ``(nu, N)``.
    """

    name: str
    solver: str
    N: int
    nx: int
    nu: int
    ng_stage: int  # inequality constraints per stage (before the dynamics)
    nparam: int
    function: Any = field(repr=False)
    build_time: float = 0.0
    watcher: Any = field(default=None, repr=False)  # IPOPT's iteration callback

    def pack(self, X: np.ndarray, U: np.ndarray) -> np.ndarray:
        N, nx, nu = self.N, self.nx, self.nu
        z = np.empty(N * (nx + nu) + nx)
        body = z[: N * (nx + nu)].reshape(N, nx + nu)
        body[:, :nx] = X[:, :N].T
        body[:, nx:] = U.T
        z[N * (nx + nu) :] = X[:, N]
        return z

    def unpack(self, z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        N, nx, nu = self.N, self.nx, self.nu
        body = z[: N * (nx + nu)].reshape(N, nx + nu)
        X = np.empty((nx, N + 1))
        X[:, :N] = body[:, :nx].T
        X[:, N] = z[N * (nx + nu) :]
        return X, body[:, nx:].T.copy()

    def pack_g(self, G_stage: np.ndarray, G_final: np.ndarray) -> np.ndarray:
        """Constraint bounds ``[dyn_0 (nx), g_0 (ng_stage), dyn_1, g_1, ..., g_N]``
        (a stage's dynamics first, as fatrop's structure detection needs): ``G_stage``
        has shape ``(ng_stage, N+1)``; dynamics rows get ``G_final``'s value (0 for both
        bounds)."""
        N, nx, ng = self.N, self.nx, self.ng_stage
        out = np.empty(N * (ng + nx) + ng)
        body = out[: N * (ng + nx)].reshape(N, ng + nx)
        body[:, nx:] = G_stage[:, :N].T
        body[:, :nx] = G_final
        out[N * (ng + nx) :] = G_stage[:, N]
        return out

    def solve(
        self,
        x0: np.ndarray,
        lbx: np.ndarray,
        ubx: np.ndarray,
        p: np.ndarray,
        lbg: np.ndarray | float = 0.0,
        ubg: np.ndarray | float = 0.0,
    ) -> SolveResult:
        t0 = time.perf_counter()
        if self.watcher is not None:
            self.watcher.iterations = 0
        out = self.function(x0=x0, lbx=lbx, ubx=ubx, lbg=lbg, ubg=ubg, p=p)
        wall = time.perf_counter() - t0
        st = self.function.stats()
        status = str(st.get("return_status", st.get("success", "")))
        return SolveResult(
            z=np.asarray(out["x"], dtype=float).ravel(),
            objective=float(out["f"]),
            success=bool(st.get("success", False)),
            status=status,
            iterations=int(st.get("iter_count", -1)),
            wall=wall,
            solver=self.solver,
        )


@dataclass(frozen=True, eq=False)
class SolveResult:
    z: np.ndarray
    objective: float
    success: bool
    status: str
    iterations: int
    wall: float
    solver: str


_CACHE: dict[tuple, OCP] = {}
_LOCK = threading.Lock()


def _watched(solver: str) -> bool:
    """Whether a problem gets IPOPT's iteration callback: only while a progress is
    active (a separate build, so solves without a progress pay nothing); fatrop does
    not call it."""
    return solver == "ipopt" and _progress.active() is not None


def _nlpsol(name: str, solver: str, nlp: dict, options: dict, watched: bool) -> tuple[Any, Any]:
    """``casadi.nlpsol``, with an iteration callback showing IPOPT's iteration and
    objective on the active progress (``nlp_iter``, ``nlp_obj``) when ``watched``."""
    import casadi as ca  # heavy module: CasADi

    if not watched:
        return ca.nlpsol(name, solver, nlp, options), None
    sizes = {"x": nlp["x"].numel(), "g": nlp["g"].numel(), "p": nlp["p"].numel(), "f": 1}

    class Watcher(ca.Callback):
        def __init__(self) -> None:
            ca.Callback.__init__(self)
            self.iterations = 0
            self.last = -math.inf
            self.construct(f"{name}_progress", {})

        def get_n_in(self) -> int:
            return ca.nlpsol_n_out()

        def get_n_out(self) -> int:
            return 1

        def get_name_in(self, i: int) -> str:
            return ca.nlpsol_out(i)

        def get_name_out(self, i: int) -> str:
            return "ret"

        def get_sparsity_in(self, i: int) -> Any:
            return ca.Sparsity.dense(sizes[ca.nlpsol_out(i).removeprefix("lam_")], 1)

        def eval(self, arg: Any) -> list[int]:
            self.iterations += 1
            now = time.perf_counter()
            progress = _progress.active()
            if progress is not None and now - self.last >= _progress.CALLBACK_INTERVAL:
                self.last = now
                progress.update(nlp_iter=self.iterations - 1, nlp_obj=float(arg[1]))
            return [0]

    watcher = Watcher()
    fn = ca.nlpsol(name, solver, nlp, {**options, "iteration_callback": watcher})
    return fn, watcher


def _options(solver: str, nx: int, N: int, ng_stage: int) -> dict[str, Any]:
    if solver == "ipopt":
        return {
            "print_time": False,
            "error_on_fail": False,
            "ipopt.print_level": 0,
            "ipopt.sb": "yes",
            "ipopt.max_iter": MAX_ITER,
            "ipopt.tol": 1e-6,
            "ipopt.constr_viol_tol": 1e-8,
            # An "acceptable" stop must be as feasible as an optimal one (the verifier
            # checks the motion's continuity to 1e-5).
            "ipopt.acceptable_constr_viol_tol": 1e-8,
        }
    if solver == "fatrop":
        equality = ([True] * nx + [False] * ng_stage) * N + [False] * ng_stage
        return {
            "print_time": False,
            "error_on_fail": False,
            "structure_detection": "auto",
            "equality": equality,
            "fatrop.print_level": 0,
            "fatrop.max_iter": MAX_ITER,
            "fatrop.tol": 1e-8,
        }
    raise InputError(f"unknown NLP solver {solver!r} (use {', '.join(SOLVERS)})")


def path_ocp(N: int, solver: str = "fatrop") -> OCP:
    """The 1-D path-following problem with ``N`` intervals (built once, then cached).

    Variables per stage: ``x_k = (sigma_k, v_k, t_k, f_k)``, ``u_k = (a_k, h_k)``;
    ``f`` is the stretch factor of the robot's windows (constant along the grid).
    Parameters ``p = (w_acc, w_time, w_reg, w_stretch, w_arr, T_arr, lo_0..lo_N,
    hi_0..hi_N)``.
    Dynamics (exact for constant ``a_k``)::

        sigma_{k+1} = sigma_k + h_k v_k + h_k^2 a_k / 2
        v_{k+1}     = v_k + h_k a_k
        t_{k+1}     = t_k + h_k
        f_{k+1}     = f_k

    Stage constraints ``t_k - f_k lo_k >= 0`` and ``t_k - f_k hi_k <= 0``: the windows
    stretched by a free factor (inactive rows get infinite bounds). With ``f`` fixed
    (its bounds ``[1, 1]``) the windows are plain bounds on ``t`` instead.

    Objective ``w_acc * sum_k a_k^2 h_k + w_time * t_N + w_reg * sum_k h_k^2 +
    w_stretch * f_N + w_arr * (t_N - T_arr)^2``: the third term (small) removes the
    freedom of how a wait is split between intervals, which otherwise costs IPOPT many
    iterations; the fourth (large, with ``f`` free) finds the smallest stretch factor of
    the robot in one solve; the last holds the arrival near ``T_arr`` (the robot's
    scheduled arrival, stretched), so that a robot whose last window reaches the
    makespan does not creep there to save acceleration.
    Everything else (the path's pieces, stops, speed and acceleration limits, windows)
    is a bound on ``x`` or ``u`` or a constraint bound.

    Example
    -------
    >>> ocp = path_ocp(8, "ipopt")
    >>> ocp.nx, ocp.nu, ocp.N, ocp.ng_stage
    (4, 2, 8, 2)
    """
    key = ("path", N, solver, _watched(solver))
    with _LOCK:
        if key in _CACHE:
            return _CACHE[key]
    import casadi as ca  # heavy module: CasADi

    t0 = time.perf_counter()
    # ---- variables: z = [x_0, u_0, x_1, u_1, ..., x_N], built as whole rows ----------
    z = ca.SX.sym("z", 6 * N + 4)
    Z = ca.reshape(z[: 6 * N], 6, N)  # column k: sigma_k, v_k, t_k, f_k, a_k, h_k
    x_end = z[6 * N :]
    sigma, v, t, f, a, h = (Z[i, :] for i in range(6))
    X = ca.horzcat(Z[:4, :], x_end)  # nodes 0..N
    nxt = X[:, 1:]  # x_{k+1}
    w = ca.SX.sym("w", 6)  # w_acc, w_time, w_reg, w_stretch, w_arr, T_arr
    lo = ca.SX.sym("lo", 1, N + 1)
    hi = ca.SX.sym("hi", 1, N + 1)
    # ---- windows stretched by f --------------------------------------------------------
    stage = ca.vertcat(X[2, :] - X[3, :] * lo, X[2, :] - X[3, :] * hi)
    # ---- dynamics: exact integration of a constant acceleration -------------------------
    dyn = nxt - ca.vertcat(sigma + h * v + 0.5 * h * h * a, v + h * a, t + h, f)
    g = ca.vertcat(ca.vec(ca.vertcat(dyn, stage[:, :N])), stage[:, N])
    # ---- objective: acceleration energy, arrival time, even steps, stretch, arrival ------
    late = x_end[2] - w[5]
    J = (
        w[0] * ca.sum2(a * a * h)
        + w[1] * x_end[2]
        + w[2] * ca.sum2(h * h)
        + w[3] * x_end[3]
        + w[4] * late * late
    )
    nlp = {"x": z, "p": ca.vertcat(w, lo.T, hi.T), "f": J, "g": g}
    options = _options(solver, 4, N, 2)
    fn, watcher = _nlpsol(f"path_{N}_{solver}", solver, nlp, options, key[-1])
    ocp = OCP("path", solver, N, 4, 2, 2, 6 + 2 * (N + 1), fn, time.perf_counter() - t0, watcher)
    log.debug("built %s in %.3f s", fn.name(), ocp.build_time)
    with _LOCK:
        return _CACHE.setdefault(key, ocp)


#: Stage constraints of the corridor problem, in order.
CORRIDOR_ROWS = ("speed2", "accel2", "lateral2", "along", "ctrl_lateral2", "ctrl_along")


def corridor_ocp(N: int, dim: int, solver: str = "ipopt") -> OCP:
    """The double integrator in ``dim`` dimensions with a corridor (built once, cached).

    Variables per stage: ``x_k = (p_k, v_k, t_k)``, ``u_k = (a_k, h_k)``. Parameters per
    stage: the corridor's axis ``A_k`` (a point), unit direction ``e_k`` and a flag
    ``m_k`` (1: a cylinder around the axis line, 0: a ball around ``A_k``), for the node
    and, separately, for the interval's middle control point; then ``(w_acc, w_time,
    w_arr, T_arr)``: objective ``w_acc * sum_k |a_k|^2 h_k + w_time * t_N + w_arr * (t_N
    - T_arr)^2`` (the last as in :func:`path_ocp`).
    Stage constraints (bounds in ``lbg/ubg``, see :data:`CORRIDOR_ROWS`)::

        |v_k|^2 <= v_max^2,  |a_k|^2 <= a_max^2
        |q|^2 - m (q . e)^2 <= c^2,  (q . e) in [lo, hi]      with q = p_k - A_k
        the same for the control point p_k + h v_k / 2

    The arc of an interval is a quadratic Bezier curve with control points ``p_k``,
    ``p_k + h v_k / 2`` and ``p_{k+1}``; it lies in the convex hull of the three, so
    constraining them to a convex corridor keeps the whole arc inside.

    Example
    -------
    >>> corridor_ocp(8, 2, "ipopt").ng_stage
    6
    """
    key = ("corridor", N, dim, solver, _watched(solver))
    with _LOCK:
        if key in _CACHE:
            return _CACHE[key]
    import casadi as ca  # heavy module: CasADi

    t0 = time.perf_counter()
    nx, nu = 2 * dim + 1, dim + 1
    npar_stage = 2 * (2 * dim + 1)
    # ---- variables: z = [x_0, u_0, ..., x_N], built as whole rows -------------------------
    z = ca.SX.sym("z", (nx + nu) * N + nx)
    Z = ca.reshape(z[: (nx + nu) * N], nx + nu, N)
    x_end = z[(nx + nu) * N :]
    X = ca.horzcat(Z[:nx, :], x_end)  # nodes 0..N
    p, v, t = X[:dim, :], X[dim : 2 * dim, :], X[2 * dim, :]
    a, h = Z[nx : nx + dim, :], Z[nx + dim, :]
    P = ca.SX.sym("P", npar_stage, N + 1)
    w = ca.SX.sym("w", 4)  # w_acc, w_time, w_arr, T_arr

    def inside(pt, par):
        A, e, m = par[:dim, :], par[dim : 2 * dim, :], par[2 * dim, :]
        q = pt - A
        along = ca.sum1(q * e)
        return ca.sum1(q * q) - m * along * along, along

    pk, vk = p[:, :N], v[:, :N]
    hd = ca.repmat(h, dim, 1)  # the step, once per axis
    # ---- limits and corridor at every node, and at every interval's control point -------
    lat, along = inside(p, P[: 2 * dim + 1, :])
    ctrl = pk + 0.5 * hd * vk  # middle Bezier control point of interval k
    clat, calong = inside(ctrl, P[2 * dim + 1 :, :N])
    zero = ca.SX.zeros(1, 1)
    stage = ca.vertcat(
        ca.sum1(v * v),
        ca.horzcat(ca.sum1(a * a), zero),
        lat,
        along,
        ca.horzcat(clat, zero),
        ca.horzcat(calong, zero),
    )
    # ---- dynamics: exact integration of a constant acceleration -------------------------
    dyn = X[:, 1:] - ca.vertcat(pk + vk * hd + 0.5 * a * (hd * hd), vk + a * hd, t[:, :N] + h)
    g = ca.vertcat(ca.vec(ca.vertcat(dyn, stage[:, :N])), stage[:, N])
    # ---- objective: acceleration energy, arrival time, arrival near T_arr --------------
    late = x_end[2 * dim] - w[3]
    J = w[0] * ca.sum2(ca.sum1(a * a) * h) + w[1] * x_end[2 * dim] + w[2] * late * late
    nlp = {"x": z, "p": ca.vertcat(ca.vec(P), w), "f": J, "g": g}
    ng = len(CORRIDOR_ROWS)
    options = _options(solver, nx, N, ng)
    fn, watcher = _nlpsol(f"corridor{dim}_{N}_{solver}", solver, nlp, options, key[-1])
    ocp = OCP(
        f"corridor{dim}", solver, N, nx, nu, ng, npar_stage * (N + 1) + 4, fn,
        time.perf_counter() - t0, watcher,
    )  # fmt: skip
    log.debug("built %s in %.3f s", fn.name(), ocp.build_time)
    with _LOCK:
        return _CACHE.setdefault(key, ocp)


def clear_cache() -> None:
    """Forget every built problem (benchmarks use it to time the builds)."""
    with _LOCK:
        _CACHE.clear()
