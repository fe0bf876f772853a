"""``refine(instance, schedule) -> Trajectories``: smooth, limited motion for every robot.

Steps (formulations/trajectory.md has the mathematics):

1. the schedule's events and inter-robot precedences (:mod:`.events`);
2. decoupled windows (:mod:`.windows`), so robots can be refined one by one;
3. per robot, a problem on a free time grid (:mod:`.model`): ``mode="path"`` keeps the
   robot on its polyline and optimises its progress (it stops at every corner, and a
   differential-drive robot turns in place there); ``mode="corridor"`` lets a double
   integrator cut corners within a corridor of half-width ``c``;
4. robots whose windows their limits cannot meet are reported with the way-point, and
   the smallest stretch factor of the schedule that makes every robot feasible is found
   by bisection (feasibility is monotone in the factor: slowing a feasible trajectory
   down by ``f' / f`` keeps its speed and acceleration within the limits and maps its
   event times into the stretched windows).

Checking the result is :func:`hierplan_opt.trajectory.verify.verify`'s job.
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Sequence
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from types import SimpleNamespace
from typing import Any

import numpy as np

from hierplan_opt.core.errors import HierplanError, InputError, OptionError
from hierplan_opt.core.instance import Instance
from hierplan_opt.core.progress import tick
from hierplan_opt.schedule.stn import accel_time
from hierplan_opt.trajectory import profile as P
from hierplan_opt.trajectory.corridor import _trajectory, solve_corridor
from hierplan_opt.trajectory.events import EventNetwork, from_schedule
from hierplan_opt.trajectory.model import SOLVERS, SolveResult
from hierplan_opt.trajectory.model import path_ocp as _path_ocp
from hierplan_opt.trajectory.paths import (
    MAX_STRETCH,
    Limits,
    PathProblem,
    RobotPath,
    _effective_windows,
    _feasible,
    arrival_term,
    path_bounds,
    path_problem,
    path_warm_start,
    robot_path,
)
from hierplan_opt.trajectory.polish import polish
from hierplan_opt.trajectory.result import RobotTrajectory, Trajectories
from hierplan_opt.trajectory.windows import Windows, decouple

log = logging.getLogger(__name__)

MODELS = ("auto", "double_integrator", "unicycle")
MODES = ("path", "corridor")
#: Solvers tried in turn by ``solver="auto"``. IPOPT/MUMPS alone: fatrop is faster per
#: iteration but fails on most robots of these problems (their pinned way-points and
#: zero-width windows are fixed variables, which its interior point handles badly), so
#: falling back costs more than it saves; ``hierplan bench trajectory`` prints both.
AUTO_SOLVERS: tuple[str, ...] = ("ipopt",)
#: Path-mode solvers without an NLP: the profile, and the profile polished by a QP.
PROFILE_SOLVERS = ("profile", "profile+qp")
#: ``solver="auto"`` in path mode: IPOPT up to this many robots, ``profile+qp`` beyond.
#: Medians of 3 in one warm process under the CPU lock (issue 34): IPOPT 0.89 s on the
#: 32-robot formation, 7.5 s on 50 warehouse robots (bench trajectory's ECBS plan, r 0.3
#: m), where profile+qp took 0.35 s and 1.75 s; on 200 robots IPOPT took 101 s and
#: profile+qp 9.4-9.6 s (README). Corridor mode always needs the NLP.
AUTO_NLP_ROBOTS = 32


def auto_solver(mode: str, num_robots: int) -> str:
    """What ``solver="auto"`` runs: IPOPT for few robots (or in corridor mode, which
    needs the NLP), ``profile+qp`` for a fleet (:data:`AUTO_NLP_ROBOTS`).

    Example
    -------
    >>> auto_solver("path", 12), auto_solver("path", 200), auto_solver("corridor", 200)
    ('ipopt', 'profile+qp', 'ipopt')
    """
    if mode == "path" and num_robots > AUTO_NLP_ROBOTS:
        return "profile+qp"
    return AUTO_SOLVERS[0]


#: Relative precision of the stretch factor.
STRETCH_RTOL = 1e-3
#: Weight of the stretch factor (per second of the robot's schedule) when it is free.
STRETCH_WEIGHT = 10.0
#: Default ``arrival_weight`` of :func:`refine`: the penalty on a robot's arrival away
#: from its stretched scheduled one ``T``, ``arrival_weight * accel_weight * a_max^2 *
#: (t_arrival - T)^2 / T`` (:func:`~hierplan_opt.trajectory.paths.arrival_term`). On the
#: audit's g1 (1 m to go, a_max 1.5, least time 1.667 s) the robot arrives at 2.22 s
#: with 1, 1.81 s with 10, 1.73 s with 30 (7.45 s without the term).
ARRIVAL_WEIGHT = 10.0


class InfeasibleWindowsError(HierplanError):
    """A robot's limits cannot meet its windows.

    Attributes: ``robot`` (name), ``event`` (a description of the way-point, or None),
    ``stretch`` (smallest factor that makes every robot feasible, or None).
    """

    def __init__(self, message: str, robot: str, event: str | None, stretch: float | None):
        super().__init__(message)
        self.robot = robot
        self.event = event
        self.stretch = stretch


@dataclass(frozen=True, eq=False)
class Attempt:
    """The outcome of one robot's solve."""

    ok: bool
    X: np.ndarray
    U: np.ndarray
    result: SolveResult
    tries: tuple[tuple[str, float, int, bool], ...]  # (solver, wall, iterations, success)


def solve_path(
    pp: PathProblem,
    windows: Windows,
    *,
    solvers: Sequence[str],
    weights: tuple[float, ...],
    upto: int | None = None,
    warm: tuple[np.ndarray, np.ndarray] | None = None,
    free: bool = False,
) -> Attempt:
    """Solve one robot's path problem, trying ``solvers`` in turn until one succeeds.

    ``free``: the stretch factor of the robot's windows is a variable (weighted by
    :data:`STRETCH_WEIGHT` per second of the schedule), so the solve finds the robot's
    smallest factor (1 when it meets its windows).

    ``weights``: ``(accel, time, step, arrival)``; the arrival term (see
    :func:`~hierplan_opt.trajectory.paths.arrival_term`) holds the robot's arrival near
    its scheduled one, stretched like its windows.
    """
    bounds = path_bounds(pp, windows, upto, free)
    lbX, ubX, lbU, ubU, lbG, ubG, LO, HI = bounds
    X0, U0 = warm if warm is not None else path_warm_start(pp, windows.stretch)
    w_arr, T = arrival_term(pp.path, windows.stretch, weights)
    w_f = STRETCH_WEIGHT * (1.0 + T) if free else 0.0
    par = np.concatenate([np.array([*weights[:3], w_f, w_arr, T], dtype=float), LO, HI])
    tries = []
    last = None
    for name in solvers:
        ocp = _path_ocp(pp.N, name)
        res = ocp.solve(
            ocp.pack(X0, U0),
            ocp.pack(lbX, lbU),
            ocp.pack(ubX, ubU),
            par,
            ocp.pack_g(lbG, np.zeros(4)),
            ocp.pack_g(ubG, np.zeros(4)),
        )
        X, U = ocp.unpack(res.z)
        good = res.success and _feasible(X, U, bounds)
        tries.append((name, res.wall, res.iterations, good))
        last = Attempt(good, X, U, res, tuple(tries))
        if good:
            return last
    assert last is not None
    return last


def path_trajectory(pp: PathProblem, X: np.ndarray, U: np.ndarray, net_events: int) -> dict:
    """Spatial piecewise-quadratic motion from the 1-D solution."""
    path = pp.path
    ip = pp.interval_piece
    N = pp.N
    sigma, v, t = X[0], X[1], X[2]
    a, h = U
    # Clean solver round-off: progress never goes back, speeds are >= 0.
    v = np.clip(v, 0.0, None)
    t = np.maximum.accumulate(t)
    start = path.knot_pos[ip]
    s0 = path.knot_sigma[ip]
    turn = path.piece_turn[ip]
    ds = (sigma[:N] - s0)[:, None]
    dirs = path.piece_dir[ip]
    p = np.where(turn[:, None], start, start + dirs * ds)
    vel = np.where(turn[:, None], 0.0, dirs * v[:N, None])
    acc = np.where(turn[:, None], 0.0, dirs * a[:, None])
    sign = path.piece_sign[ip]
    theta = np.where(turn, path.piece_theta0[ip] + sign * (sigma[:N] - s0), path.piece_theta0[ip])
    omega = np.where(turn, sign * v[:N], 0.0)
    alpha = np.where(turn, sign * a, 0.0)
    last_theta = float(theta[-1] + omega[-1] * h[-1] + 0.5 * alpha[-1] * h[-1] ** 2)
    P = np.vstack([p, path.knot_pos[-1:]])
    V = np.vstack([vel, np.zeros((1, P.shape[1]))])
    TH = np.append(theta, last_theta)
    OM = np.append(omega, 0.0)
    return {
        "t": t,
        "p": P,
        "v": V,
        "a": acc,
        "theta": TH,
        "omega": OM,
        "alpha": alpha,
        "event_times": event_times(pp, sigma, v, t, a),
    }


def event_times(
    pp: PathProblem, sigma: np.ndarray, v: np.ndarray, t: np.ndarray, a: np.ndarray
) -> np.ndarray:
    """When the robot passes each of its events: knots at their grid node's time (a
    ``wait`` event is the moment the robot sets off), other events by
    :func:`passage_times`."""
    path = pp.path
    out = passage_times(sigma, v, t, a, path.event_axis)
    has = path.knot_event >= 0
    out[path.knot_event[has] - int(path.event_ids[0])] = t[pp.knot_node[has]]
    return out


def passage_times(
    sigma: np.ndarray, v: np.ndarray, t: np.ndarray, a: np.ndarray, targets: np.ndarray
) -> np.ndarray:
    """First time the 1-D motion reaches each of ``targets`` (non-decreasing progress).

    Example
    -------
    >>> passage_times(np.array([0.0, 0.5, 1.0]), np.array([0.0, 1.0, 0.0]),
    ...               np.array([0.0, 1.0, 2.0]), np.array([1.0, -1.0]), np.array([0.5, 0.125]))
    array([1. , 0.5])
    """
    s = np.maximum.accumulate(sigma)
    idx = np.clip(np.searchsorted(s, targets - 1e-12, side="left"), 0, len(s) - 1)
    out = t[idx].astype(float).copy()
    inner = (idx > 0) & (s[idx] > targets + 1e-12)
    k = idx[inner] - 1
    d = targets[inner] - s[k]
    vk, ak = v[k], a[k]
    disc = np.sqrt(np.maximum(vk * vk + 2.0 * ak * d, 0.0))
    # The first root of d = v tau + a tau^2 / 2 as 2 d / (v + disc), equal to
    # (disc - v) / a but without its cancellation: with |a| ~ 1e-12 (a profile's
    # round-off) that form missed the passage by 3e-5 s, the way-point by 1e-5 m.
    with np.errstate(divide="ignore", invalid="ignore"):
        tau = 2.0 * d / (vk + disc)
        tau = np.where(np.isfinite(tau), tau, 0.0)
    out[inner] = t[k] + np.clip(tau, 0.0, t[k + 1] - t[k])
    return out


# ---------------------------------------------------------------------- diagnosis
def _reach_time(d: float, v: float, a: float) -> float:
    """Least time to cover ``d`` from rest (no need to stop at the end)."""
    if d <= 0:
        return 0.0
    if not math.isfinite(a):
        return d / v
    if d <= v * v / (2 * a):
        return math.sqrt(2 * d / a)
    return v / a + (d - v * v / (2 * a)) / v


def earliest_passage(path: RobotPath, lo: np.ndarray) -> np.ndarray:
    """A lower bound on the time each knot can be passed (limits + lower windows).

    Within a run between two stops the robot is at best accelerating flat out from the
    last stop; it must rest at every stop; it can never pass a knot before its window
    opens. A knot whose bound exceeds its window's end is proven unreachable.
    """
    m = len(path.knot_sigma)
    E = np.zeros(m)
    E[0] = lo[0]
    run_start = 0
    for i in range(1, m):
        p = i - 1
        vmax, amax = float(path.piece_vmax[p]), float(path.piece_amax[p])
        d = float(path.knot_sigma[i] - path.knot_sigma[run_start])
        if path.knot_stop[i]:
            need = accel_time(d, vmax, amax) if math.isfinite(amax) else d / vmax
        else:
            need = _reach_time(d, vmax, amax)
        step = float(path.knot_sigma[i] - path.knot_sigma[i - 1]) / vmax
        E[i] = max(lo[i], E[run_start] + need, E[i - 1] + step)
        if path.knot_stop[i]:
            run_start = i
    return E


# ---------------------------------------------------------------------- front door
def _limits(
    instance: Instance, j: int, model: str, alpha_max: float | None, a_max: float | None
) -> Limits:
    k = instance.agents[j].kinematics
    inf = math.inf
    acc = k.a_max if k.a_max else a_max
    if not acc:
        raise InputError(
            f"robot type {k.robot_type!r} of {instance.agents[j].name!r} has no a_max; "
            "refinement needs an acceleration limit (give one in the instance's robot "
            "types, or a_max= (the command line's --a-max) for robots without one)"
        )
    omega = float(k.omega_max) if k.omega_max else inf
    if model == "unicycle" and not math.isfinite(omega):
        raise InputError(
            f"model 'unicycle' needs omega_max, and robot type {k.robot_type!r} of "
            f"{instance.agents[j].name!r} has none"
        )
    return Limits(
        v_max=float(k.v_max),
        a_max=float(acc),
        omega_max=omega,
        alpha_max=float(alpha_max) if alpha_max else inf,
    )


def _model_of(instance: Instance, j: int, model: str) -> str:
    if model != "auto":
        return model
    return (
        "unicycle" if instance.agents[j].kinematics.drive == "differential" else "double_integrator"
    )


def _check_options(**kw: Any) -> None:
    if kw["model"] not in MODELS:
        raise OptionError(f"unknown model {kw['model']!r} (use {', '.join(MODELS)})")
    if kw["mode"] not in MODES:
        raise OptionError(f"unknown mode {kw['mode']!r} (use {', '.join(MODES)})")
    solver = kw["solver"]
    if solver not in (*SOLVERS, *PROFILE_SOLVERS, "auto"):
        raise OptionError(
            f"unknown solver {solver!r} (use auto, profile, profile+qp, {', '.join(SOLVERS)})"
        )
    for name in ("accel_weight", "time_weight", "step_weight", "arrival_weight", "corridor"):
        v = kw[name]
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v < 0:
            raise OptionError(f"{name} must be a finite number >= 0, got {v!r}")
    if kw["accel_weight"] == 0 and kw["time_weight"] == 0:
        raise OptionError("accel_weight and time_weight cannot both be 0")
    ipp = kw["intervals_per_piece"]
    if isinstance(ipp, bool) or not isinstance(ipp, int) or not 1 <= ipp <= 64:
        raise OptionError(f"intervals_per_piece must be an integer in [1, 64], got {ipp!r}")
    st = kw["stretch"]
    if (
        st is not None
        and st != "auto"
        and (
            isinstance(st, bool)
            or not isinstance(st, (int, float))
            or not math.isfinite(st)
            or st < 1
        )
    ):
        raise OptionError(f"stretch must be None, 'auto' or a number >= 1, got {st!r}")
    for name in ("alpha_max", "a_max"):
        a = kw[name]
        if a is not None and (
            isinstance(a, bool) or not isinstance(a, (int, float)) or not math.isfinite(a) or a <= 0
        ):
            raise OptionError(f"{name} must be a positive number, got {a!r}")
    w = kw["workers"]
    if isinstance(w, bool) or not isinstance(w, int) or w < 1:
        raise OptionError(f"workers must be a positive integer, got {w!r}")


def refine(
    instance: Instance,
    schedule: Any,
    *,
    model: str = "auto",
    mode: str = "path",
    corridor: float = 0.1,
    solver: str = "auto",
    split: float = 0.5,
    stretch: float | str | None = None,
    accel_weight: float = 1.0,
    time_weight: float = 0.01,
    step_weight: float = 1e-3,
    arrival_weight: float = ARRIVAL_WEIGHT,
    intervals_per_piece: int = 2,
    alpha_max: float | None = None,
    a_max: float | None = None,
    workers: int = 1,
) -> Trajectories:
    """Refine a MAPF-POST schedule into smooth trajectories within each robot's limits.

    Parameters
    ----------
    instance : Instance
        Gives each robot's limits (``v_max``, ``a_max``; ``omega_max`` for unicycles).
    schedule : Schedule or EventNetwork
        From :func:`hierplan_opt.schedule.postprocess`, or a file read with
        :func:`hierplan_opt.trajectory.events.from_file`.
    model : {"auto", "double_integrator", "unicycle"}
        ``auto``: unicycle for differential-drive robots, else double integrator.
    mode : {"path", "corridor"}
        ``path``: on the planned polyline, the schedule's safety distance carries over;
        ``corridor``: corners cut within ``corridor`` metres (double integrator only),
        the guarantee drops by ``2 * corridor``.
    solver : {"auto", "ipopt", "fatrop", "profile", "profile+qp"}
        ``auto``: by size (:func:`auto_solver`): IPOPT with MUMPS for up to
        :data:`AUTO_NLP_ROBOTS` robots or in corridor mode, else ``profile+qp``; the
        result's ``stats["solver"]`` says which ran. ``profile`` (path mode only,
        one process): no NLP; knots at the stretched schedule's times, delayed inside
        their windows where needed, speeds from a forward and a backward pass
        (:mod:`hierplan_opt.trajectory.profile`); 20-30x faster. Its stretch factor,
        like IPOPT's, is one that works (an upper bound of the smallest), neither is the
        smallest in general, and either may be the smaller (the profile's on the
        formation, IPOPT's on the warehouse: ``formulations/trajectory.md``).
        ``profile+qp``: the profile's motion, then per robot a convex QP on its fixed
        time grid (CasADi ``conic`` with HPIPM) that minimises the integral of ``|a|^2``
        (:mod:`hierplan_opt.trajectory.polish`); knot times, windows and stretch are the
        profile's.
    split : float
        Share of each precedence's slack given to the earlier event (:func:`decouple`).
    stretch : None, "auto" or float >= 1
        None: a robot that cannot meet its windows raises
        :class:`InfeasibleWindowsError` (naming robot, way-point and the smallest
        stretch factor that would work); "auto": stretch by that factor; a number:
        stretch by it.
    accel_weight, time_weight, step_weight, arrival_weight : float
        Objective ``accel_weight * integral |a|^2 dt + time_weight * arrival +
        step_weight * sum h_k^2`` (a small regulariser of the free time grid) ``+
        arrival_weight * accel_weight * a_max^2 * (arrival - T)^2 / T`` in path mode,
        with ``T`` the robot's scheduled arrival times the stretch factor: a robot that
        finishes early arrives about when its schedule says (stretched like the rest),
        instead of creeping to the makespan (:func:`solve_path`).
    intervals_per_piece : int
        Grid intervals per piece of path at least (the grid is rounded up to a built size).
    alpha_max : float, optional
        Turn acceleration limit of unicycles (rad/s^2); default unlimited.
    a_max : float, optional
        Acceleration limit (m/s^2) for robots whose kinematics give none (MovingAI
        instances); a robot without either is refused.
    workers : int
        Solve in that many processes (1: in this process).

    Example
    -------
    >>> from hierplan_opt.core.graph import Graph
    >>> from hierplan_opt.core.instance import Kinematics
    >>> from hierplan_opt.core.plan import Plan
    >>> from hierplan_opt.schedule import postprocess
    >>> g = Graph.grid(4, 1)
    >>> inst = Instance.mapf(g, [(0, 0)], [(3, 0)], kinematics=Kinematics(a_max=1.0))
    >>> sched = postprocess(inst, Plan.from_paths([[0, 1, 2, 3]]))
    >>> tr = refine(inst, sched)
    >>> round(tr.makespan, 3) <= sched.makespan + 1e-6, tr.robots[0].model
    (True, 'double_integrator')
    """
    _check_options(
        model=model,
        mode=mode,
        solver=solver,
        accel_weight=accel_weight,
        time_weight=time_weight,
        step_weight=step_weight,
        arrival_weight=arrival_weight,
        corridor=corridor,
        intervals_per_piece=intervals_per_piece,
        stretch=stretch,
        alpha_max=alpha_max,
        a_max=a_max,
        workers=workers,
    )
    t_start = time.perf_counter()
    net = schedule if isinstance(schedule, EventNetwork) else from_schedule(schedule)
    if net.num_agents != instance.num_agents or tuple(net.agent_names) != tuple(
        a.name for a in instance.agents
    ):
        raise InputError("the schedule's robots are not the instance's robots")
    if mode == "corridor" and corridor <= 0:
        raise OptionError("corridor mode needs a corridor half-width > 0")
    asked = solver
    if solver == "auto":
        solver = auto_solver(mode, net.num_agents)
        log.debug("refine: solver auto -> %s (%d robots, %s mode)", solver, net.num_agents, mode)
    solvers = AUTO_SOLVERS if asked == "auto" and solver not in PROFILE_SOLVERS else (solver,)
    windows = decouple(net, split)
    if isinstance(stretch, (int, float)) and not isinstance(stretch, bool) and stretch > 1:
        windows = windows.stretched(float(stretch))
    t_windows = time.perf_counter() - t_start

    models = [_model_of(instance, j, model) for j in range(net.num_agents)]
    if mode == "corridor" and "unicycle" in models:
        j = models.index("unicycle")
        raise OptionError(
            f"corridor mode is implemented for the double integrator only; "
            f"{net.agent_names[j]!r} is a unicycle (use mode='path', or model="
            "'double_integrator')"
        )
    knots = (windows.lo > 0) | np.isfinite(windows.hi)
    paths = [
        robot_path(
            net,
            j,
            models[j],
            _limits(instance, j, models[j], alpha_max, a_max),
            turns=models[j] == "unicycle",
            knots=knots,
        )
        for j in range(net.num_agents)
    ]
    opts = {
        "mode": mode,
        "corridor": float(corridor),
        "solvers": solvers,
        "weights": (
            float(accel_weight),
            float(time_weight),
            float(step_weight),
            float(arrival_weight),
        ),
        "base": int(intervals_per_piece),
    }
    t0 = time.perf_counter()
    found_stretch = None
    if solver in PROFILE_SOLVERS:
        if mode != "path":
            raise OptionError(f"solver {solver!r} works in mode='path' only")
        outs, windows, found_stretch = _solve_profiles(paths, windows, stretch, net)
        if solver == "profile+qp":
            outs = [o if o is None else _polish(o, windows) for o in outs]
    else:
        # Path mode: every robot once with a free stretch factor of its windows (the
        # smallest factor that makes it feasible, 1 for most robots); corridor mode: f = 1.
        opts["free"] = mode == "path"
        outs = _solve_all(paths, windows, opts, workers)
        opts["free"] = False
        failed = [j for j, o in enumerate(outs) if o is not None and not o["ok"]]
        late = [j for j, o in enumerate(outs) if o is not None and o["ok"] and _factor(o) > 1.0]
        # A factor a hair above 1 is round-off (windows met within 1e-9 of their times).
        for j in [j for j in late if _factor(outs[j]) <= 1.0 + 1e-9]:
            outs[j] = dict(outs[j], f=1.0)  # type: ignore[arg-type]
        late = [j for j in late if _factor(outs[j]) > 1.0]
        if stretch != "auto":
            # Close to 1: solve those robots with f = 1.
            for j in [j for j in late if 1.0 < _factor(outs[j]) <= 1.0 + STRETCH_RTOL / 10]:
                o = _solve_one(paths[j], windows, opts)
                outs[j] = o
                if not _ok(o):
                    failed.append(j)
            late = [j for j in late if _ok(outs[j]) and _factor(outs[j]) > 1.0]
        found_stretch = None
        if failed or late:
            found_stretch, sols = smallest_stretch(
                [paths[j] for j in late + failed],
                windows,
                opts,
                known=[_factor(outs[j]) for j in late] + [None] * len(failed),
                known_sols=[outs[j] for j in late] + [None] * len(failed),
            )
            if found_stretch is not None and (stretch == "auto" or found_stretch <= 1.0):
                # Every solution slowed down to the final factor stays feasible (the
                # monotonicity argument above): no robot is solved again.
                f = found_stretch
                if f > 1.0:
                    windows = windows.stretched(f)
                todo = set(late + failed)
                outs = [
                    o if not _ok(o) or j in todo else _dilate(o, f, paths[j])
                    for j, o in enumerate(outs)
                ]
                for j, (fj, o) in zip(late + failed, sols, strict=True):
                    outs[j] = None if o is None else _dilate(o, f / fj, paths[j])
                failed = late = []
            if failed or late:
                worst = (late + failed)[0]
                raise _infeasible(paths[worst], windows, opts, net, found_stretch, stretch)
    t_solve = time.perf_counter() - t0

    robots = []
    for j, (path, o) in enumerate(zip(paths, outs, strict=True)):
        robots.append(_robot_result(path, o, net, j))
    c = float(corridor) if mode == "corridor" else 0.0
    sd = max(net.safety_distance - 2 * c, 0.0)
    guarantee = _guarantee_text(net, mode, c, sd)
    solves = [o for o in outs if o is not None]
    stats: dict[str, Any] = {
        "windows_time": t_windows,
        "solve_time": t_solve,
        "total_time": time.perf_counter() - t_start,
        "robots_solved": len(solves),
        "solver_time_sum": sum(o["wall"] for o in solves),
        "iterations_sum": sum(o["iterations"] for o in solves),
        "ipopt_fallbacks": sum(1 for o in solves if o["solver"] != solvers[0]),
        "solver": solver,  # what ran; "auto" resolved by auto_solver
        "solver_asked": asked,
    }
    if solver == "profile+qp":
        stats["qp_fallbacks"] = sum(1 for o in solves if not o["qp_ok"])
        stats["accel_before"] = sum(o["accel_before"] for o in solves)
        stats["accel_after"] = sum(o["accel_after"] for o in solves)
    if found_stretch is not None:
        stats["stretch_needed"] = found_stretch
    return Trajectories(
        robots=tuple(robots),
        mode=mode,
        corridor=c,
        safety_distance=sd,
        schedule_safety_distance=net.safety_distance,
        stretch=windows.stretch,
        guarantee=guarantee,
        windows=windows,
        stats=stats,
        radius=tuple(float(r) for r in net.radius),
        margin=net.margin if net.enforced else 0.0,
        enforced=net.enforced,
    )


def _solve_profiles(
    paths: list[RobotPath], windows: Windows, stretch: Any, net: EventNetwork
) -> tuple[list[dict | None], Windows, float | None]:
    """``solver="profile"``: every robot at the factor asked for, or (``"auto"``) at its
    own smallest factor, then slowed down to the fleet's (the largest)."""
    base = windows.stretch
    outs: list[dict | None] = [None] * len(paths)
    factors = [1.0] * len(paths)
    failed: list[tuple[int, int]] = []
    best = 1.0
    for j, path in enumerate(paths):
        tick("robots", j, len(paths), stretch=best if stretch == "auto" else None)
        if path.num_pieces == 0:
            continue
        t0 = time.perf_counter()
        lo, hi = _effective_windows(path, windows, None)
        lo, hi = lo / base, hi / base
        # "auto": first at 1 (most robots), then at the largest factor so far (raised
        # by bisection when a robot needs more); solutions are slowed down later.
        f = base * best if stretch == "auto" else base
        pr = P.solve(path, f, lo, hi)
        if stretch == "auto":
            if pr.ok:
                factors[j] = best
            else:
                found = P.smallest(path, lo, hi, MAX_STRETCH, STRETCH_RTOL / 10, start=best)
                if found is None:
                    failed.append((j, -1))
                    continue
                factors[j], pr = found
                best = factors[j]
        if not pr.ok:
            failed.append((j, pr.failed_knot))
            continue
        outs[j] = {
            "ok": True,
            "f": 1.0,
            "X": pr.X,
            "U": pr.U,
            "pp": pr.pp,
            "wall": time.perf_counter() - t0,
            "iterations": pr.delays,
            "solver": "profile",
            "status": "profile",
            "tries": (),
            "N": pr.pp.N if pr.pp is not None else 0,
        }
    tick("robots", len(paths), len(paths), stretch=best if stretch == "auto" else None)
    if failed:
        j, k = failed[0]
        path = paths[j]
        need = [P.smallest(paths[i], *_unstretched(paths[i], windows), MAX_STRETCH, 1e-4)
                for i, _ in failed]  # fmt: skip
        factor = None if any(x is None for x in need) else max(x[0] for x in need if x)
        if k < 0:  # no factor helps: name the robot's goal
            ev = int(path.event_ids[-1])
        else:  # the end of a turn: name the vertex it turns at
            ev = int(path.knot_event[k]) if path.knot_event[k] >= 0 else int(path.knot_event[k - 1])
        where = net.where(ev)
        msg = (
            f"{where} cannot be passed inside its window with the profile solver "
            f"(v_max {path.limits.v_max:g}, a_max {path.limits.a_max:g})"
        )
        total = None if factor is None else base * factor
        if total is not None:
            msg += f"; stretching the schedule by {total:.4g} makes every robot feasible"
        raise InfeasibleWindowsError(msg, path.name, where, total)
    found_stretch = None
    if stretch == "auto":
        F = max(factors)
        found_stretch = F
        if F > 1.0:
            windows = windows.stretched(F)
            outs = [
                o if o is None else _dilate(o, F / factors[j], paths[j]) for j, o in enumerate(outs)
            ]
    for j, o in enumerate(outs):
        if o is not None and not _feasible(o["X"], o["U"], path_bounds(o["pp"], windows)):
            raise HierplanError(f"profile solver: the motion of {paths[j].name} fails its checks")
    return outs, windows, found_stretch


def _polish(o: dict, windows: Windows) -> dict:
    """``solver="profile+qp"``: the profile's motion smoothed by the QP of
    :mod:`hierplan_opt.trajectory.polish` (the profile's when the QP fails)."""
    t0 = time.perf_counter()
    r = polish(o["pp"], o["X"], o["U"], windows)
    return dict(
        o,
        X=r.X,
        U=r.U,
        pp=r.pp,
        N=r.pp.N,
        wall=o["wall"] + time.perf_counter() - t0,
        solver="profile+qp",
        status=r.status,
        qp_ok=r.ok,
        qp_time=r.wall,
        accel_before=r.before,
        accel_after=r.after,
    )


def _unstretched(path: RobotPath, windows: Windows) -> tuple[np.ndarray, np.ndarray]:
    lo, hi = _effective_windows(path, windows, None)
    return lo / windows.stretch, hi / windows.stretch


def _guarantee_text(net: EventNetwork, mode: str, c: float, sd: float) -> str:
    """What the trajectories keep, and why (formulations/trajectory.md, "Clearance")."""
    if not net.enforced:
        kept = (
            "the schedule was built without clearance (clearance=False): no distance "
            "between robots is guaranteed"
        )
    elif net.safety_distance <= 0:
        kept = "point robots (radii and margin 0): no distance is required"
    else:
        less = f" - 2c = r_i + r_j + {net.margin - 2 * c:.4g}" if c > 0 else ""
        kept = (
            "every precedence of the schedule holds, so by the claim theorem of MAPF-POST "
            f"(docs/post.md) robots i and j keep r_i + r_j + margin{less} between their "
            f"centres (smallest pair {sd:.4g} m)"
        )
    if mode == "path":
        return (
            "path mode: every robot moves forward on its planned polyline and passes every "
            f"event of the schedule inside its decoupled window; {kept}"
        )
    return (
        f"corridor mode: robots stay within {c:g} of the piece of their polyline between "
        f"the events they are between, and pass every event within {c:g} inside its "
        f"window; {kept} (2c = {2 * c:g} less than in path mode)"
    )


def _dilate(o: dict | None, f: float, path: RobotPath) -> dict | None:
    """A solution slowed down by ``f``: times and steps times ``f``, speeds over ``f``,
    accelerations over ``f**2``."""
    if o is None or f == 1.0:
        return o
    X, U = o["X"].copy(), o["U"].copy()
    dim = (X.shape[0] - 1) // 2
    X[dim : 2 * dim] /= f
    X[2 * dim] *= f
    U[:-1] /= f * f
    U[-1] *= f
    out = dict(o, X=X, U=U)
    if "traj" in o:  # corridor mode keeps the spatial motion
        out["traj"] = _trajectory(path, o["pp"], X, U, dim)
    return out


# ---------------------------------------------------------------------- solving
def _solve_one(
    path: RobotPath,
    windows: Windows,
    opts: dict,
    upto: int | None = None,
    warm: tuple[np.ndarray, np.ndarray] | None = None,
) -> dict | None:
    if path.num_pieces == 0:
        return None  # a robot that never moves
    if opts["mode"] == "corridor":
        return solve_corridor(path, windows, opts, warm=warm)
    pp = path_problem(path, opts["base"])
    lo, hi = _effective_windows(path, windows, upto)
    if not opts.get("free") and np.any(earliest_passage(path, lo) > hi + 1e-9):
        # Proven infeasible: no solver call needed.
        return {
            "ok": False,
            "X": None,
            "U": None,
            "pp": pp,
            "wall": 0.0,
            "iterations": 0,
            "solver": "bound",
            "status": "unreachable window",
            "tries": (),
            "N": pp.N,
        }
    free = bool(opts.get("free")) and upto is None and warm is None
    att = solve_path(
        pp,
        windows,
        solvers=opts["solvers"],
        weights=opts["weights"],
        upto=upto,
        warm=warm,
        free=free,
    )
    return {
        "ok": att.ok,
        "f": float(att.X[3, 0]) if free and att.ok else 1.0,
        "X": att.X,
        "U": att.U,
        "pp": pp,
        "wall": sum(t[1] for t in att.tries),
        "iterations": sum(t[2] for t in att.tries),
        "solver": att.result.solver,
        "status": att.result.status,
        "tries": att.tries,
        "N": pp.N,
    }


def _solve_chunk(args: tuple) -> list[dict | None]:
    paths, windows, opts, warm = args
    return [_solve_one(p, windows, opts, warm=w) for p, w in zip(paths, warm, strict=True)]


def _solve_all(
    paths: list[RobotPath],
    windows: Windows,
    opts: dict,
    workers: int,
    warm: list | None = None,
) -> list[dict | None]:
    warm = warm or [None] * len(paths)
    if workers <= 1 or len(paths) < 2 * workers:
        done: list[dict | None] = []
        for p, w in zip(paths, warm, strict=True):
            done.append(_solve_one(p, windows, opts, warm=w))
            tick("robots", len(done), len(paths))
        return done
    # Interleaved chunks balance long and short paths; every process builds its own NLPs
    # and gets the windows as plain arrays (the network's labels are closures).
    plain = SimpleNamespace(lo=windows.lo, hi=windows.hi, stretch=windows.stretch)
    chunks = [(paths[i::workers], plain, opts, warm[i::workers]) for i in range(workers)]
    out: list[dict | None] = [None] * len(paths)
    solved = 0
    with ProcessPoolExecutor(max_workers=workers) as ex:
        for i, res in enumerate(ex.map(_solve_chunk, chunks)):
            for k, r in enumerate(res):
                out[i + k * workers] = r
            solved += len(res)
            tick("robots", solved, len(paths))
    return out


def _solve_at(path: RobotPath, windows: Windows, opts: dict, factor: float) -> dict | None:
    return _solve_one(path, windows.stretched(factor) if factor > 1 else windows, opts)


def _factor(o: dict | None) -> float:
    """The stretch factor a solution was found at (1 unless its factor was free)."""
    return 1.0 if o is None else float(o.get("f", 1.0))


def _ok(o: dict | None) -> bool:
    return o is None or bool(o["ok"])


def smallest_stretch(
    paths: Sequence[RobotPath],
    windows: Windows,
    opts: dict,
    known: Sequence[float | None] | None = None,
    known_sols: Sequence[dict | None] | None = None,
) -> tuple[float | None, list[tuple[float, dict | None]]]:
    """The smallest factor (within :data:`STRETCH_RTOL`) that makes all ``paths`` feasible,
    and for every path a factor and a solution found there (to be slowed down to the
    final factor).

    ``known[i]``: a factor at which path ``i`` is known to be feasible, with its solution
    ``known_sols[i]`` (from a solve with a free factor, which is close to the smallest):
    the search then starts just below it. Robots are taken by decreasing known factor,
    then the others; a robot feasible at the best factor so far costs one solve, the
    others a bisection between that factor and a known or doubling bracket.
    """
    n = len(paths)
    known = list(known) if known is not None else [None] * n
    known_sols = list(known_sols) if known_sols is not None else [None] * n
    order = sorted(range(n), key=lambda i: -(known[i] or 0.0))
    best = 1.0
    steps = 0  # bisection steps, shown on the active progress
    sols: list[tuple[float, dict | None]] = [(1.0, None)] * n
    for i in order:
        path, fk = paths[i], known[i]
        if fk is not None and fk <= best:
            sols[i] = (fk, known_sols[i])
            continue
        o = _solve_at(path, windows, opts, best)
        if _ok(o):
            sols[i] = (best, o)
            continue
        lo = best
        o_at = None  # the factor of a known solution (slowed down to ``hi`` at the end)
        if fk is not None:
            # A hair above the known factor, whose solution meets its windows only to
            # the solver's tolerance.
            hi, o, o_at = fk * (1.0 + 1e-6), known_sols[i], fk
        else:
            hi = best * 2
            o = _solve_at(path, windows, opts, hi)
            while not _ok(o):
                lo, hi = hi, hi * 2
                if hi > MAX_STRETCH:
                    return None, sols
                o = _solve_at(path, windows, opts, hi)
        first = True
        while hi - lo > STRETCH_RTOL * lo:
            # A known factor is close to the smallest: probe just below it first.
            probe = first and fk is not None
            mid = max(hi / (1.0 + STRETCH_RTOL), lo) if probe else 0.5 * (lo + hi)
            first = False
            o_mid = _solve_at(path, windows, opts, mid)
            steps += 1
            tick("stretch steps", steps, robot=path.name, stretch=mid, feasible=_ok(o_mid))
            if _ok(o_mid):
                hi, o, o_at = mid, o_mid, None
            else:
                lo = mid
        if o_at is not None:
            # The known solution traded smoothness for a small factor: solve once more
            # at the factor found (the usual objective), keeping it if that fails.
            o_hi = _solve_at(path, windows, opts, hi)
            if _ok(o_hi):
                o, o_at = o_hi, None
        best = hi
        sols[i] = (hi if o_at is None else o_at, o)
    # A little room (a tenth of the precision) so that the factor, given back to
    # ``refine(stretch=...)``, is not met only to the solver's tolerance.
    return (best * (1.0 + STRETCH_RTOL / 10) if best > 1.0 else best), sols


def first_unmet(path: RobotPath, windows: Windows, opts: dict) -> tuple[int, str]:
    """The first knot whose window the robot cannot meet, and why.

    First the earliest-passage bound (a proof when it exceeds a window); otherwise the
    shortest prefix of the path, with windows up to knot ``m``, that has no solution.
    """
    lo, hi = _effective_windows(path, windows, None)
    E = earliest_passage(path, lo)
    late = np.flatnonzero(hi + 1e-9 < E)
    if len(late):
        i = int(late[0])
        return i, f"its limits let it pass there at {E[i]:.6g} s at the earliest"
    a, b = 0, len(path.knot_sigma) - 1  # prefix a feasible (start), prefix b not
    while b - a > 1:
        m = (a + b) // 2
        o = _solve_one(path, windows, opts, upto=m)
        if o is None or o["ok"]:
            a = m
        else:
            b = m
    return b, "no motion within its limits meets this and the earlier windows"


def _infeasible(
    path: RobotPath,
    windows: Windows,
    opts: dict,
    net: EventNetwork,
    found: float | None,
    stretch: Any,
) -> InfeasibleWindowsError:
    i, why = first_unmet(path, windows, opts)
    ev = int(path.knot_event[i])
    if ev < 0:  # the end of a turn: name the vertex it turns at
        ev = int(path.knot_event[i - 1])
    where = net.where(ev)
    lo, hi = float(windows.lo[ev]), float(windows.hi[ev])
    lim = path.limits
    msg = (
        f"{where} cannot be passed inside its window [{lo:.6g}, {hi:.6g}] s: {why} "
        f"(v_max {lim.v_max:g}, a_max {lim.a_max:g})"
    )
    if found is None:
        msg += f"; no stretch factor up to {MAX_STRETCH:g} helps"
    elif stretch == "auto":
        msg += f"; even after stretching the schedule by {found:.4g}"
    else:
        msg += (
            f"; stretching the schedule by {found:.4g} makes every robot feasible (stretch='auto')"
        )
    return InfeasibleWindowsError(msg, path.name, where, found)


def _robot_result(path: RobotPath, o: dict | None, net: EventNetwork, j: int) -> RobotTrajectory:
    lim = path.limits.as_dict()
    if o is None:
        P = path.knot_pos[:1]
        arr = {
            "t": np.zeros(1),
            "p": P.copy(),
            "v": np.zeros_like(P),
            "a": np.zeros((0, P.shape[1])),
            "theta": np.array([path.theta0]),
            "omega": np.zeros(1),
            "alpha": np.zeros(0),
            "event_times": np.zeros(len(net.events(j))),
        }
        stats: dict[str, Any] = {"solver": None, "iterations": 0, "solve_time": 0.0}
    else:
        if "traj" in o:
            arr = o["traj"]
        else:
            arr = path_trajectory(o["pp"], o["X"], o["U"], len(net.events(j)))
        stats = {
            "solver": o["solver"],
            "status": o["status"],
            "iterations": o["iterations"],
            "solve_time": o["wall"],
            "intervals": o["N"],
            "tries": o["tries"],
        }
        for key in ("qp_ok", "qp_time", "accel_before", "accel_after"):
            if key in o:
                stats[key] = o[key]
    for v in arr.values():
        v.setflags(write=False)
    return RobotTrajectory(
        name=path.name,
        model=path.model,
        t=arr["t"],
        p=arr["p"],
        v=arr["v"],
        a=arr["a"],
        theta=arr["theta"],
        omega=arr["omega"],
        alpha=arr["alpha"],
        event_times=arr["event_times"],
        limits=lim,
        stats=stats,
    )


__all__ = ["InfeasibleWindowsError", "Limits", "refine"]
