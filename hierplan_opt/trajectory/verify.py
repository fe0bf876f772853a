"""Independent verification of refined trajectories (nothing here trusts the optimiser).

Every robot is sampled every ``dt`` seconds from its piecewise-quadratic motion, and:

* **limits** — speeds ``|p(t+dt) - p(t)| / dt`` and accelerations
  ``|p(t+dt) - 2 p(t) + p(t-dt)| / dt^2`` from the *positions* (finite differences are
  averages of the true derivatives, so a trajectory within its limits always passes),
  plus the exact values on the grid nodes; unicycles also their turn rate and the
  absence of sideways motion;
* **windows and path** — at the time the trajectory claims to pass each schedule event,
  the robot is at the event (within ``tol``; within the corridor ``c`` in corridor
  mode), that time lies in the event's decoupled window (within ``tol + 1e-8 t``, the
  bound accuracy of IPOPT), the times are in path order, and between two events every
  sample lies on the segment joining them (path mode) or
  within ``c`` of the path around it (corridor mode);
* **distance** — the minimum distance between any two robots over continuous time,
  against the distance the pair must keep, ``r_i + r_j + margin`` (minus ``2 c`` in
  corridor mode) with the radii of ``instance`` when given: between two samples the
  relative position ``r(t)`` differs from the straight line joining its samples by at
  most ``A dt^2 / 8``, where ``A = A_i + A_j`` and ``A_i`` is the largest acceleration
  of robot ``i``'s pieces (read from the motion itself, not from its limits), so the
  closest approach of that line minus ``A dt^2 / 8`` is a sound lower bound. Pairs
  whose bounding boxes over a block of samples are farther apart than ``radius`` are
  skipped (they are that far apart).

The report says whether every check passed, the smallest distance found and the
smallest margin of any pair over its required distance.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from hierplan_opt.core.errors import InputError
from hierplan_opt.core.instance import Instance
from hierplan_opt.core.reprs import short_repr
from hierplan_opt.trajectory.result import RobotTrajectory, Trajectories

#: Default sampling step (seconds).
DEFAULT_DT = 0.02
#: Relative tolerance of the window check (seconds per second of the event's time).
WINDOW_RTOL = 1e-8
#: Samples per block of the pairwise check.
BLOCK = 256


@dataclass(frozen=True)
class VerifyReport:
    """What :func:`verify` found."""

    __repr__ = short_repr  # arrays and long tuples summarised (core/reprs)

    ok: bool
    problems: tuple[str, ...]
    num_problems: int
    min_distance: float
    min_pair: tuple[str, str] | None
    min_time: float | None
    safety_distance: float
    worst_gap: float
    worst_pair: tuple[str, str] | None
    max_speed_ratio: float
    max_accel_ratio: float
    max_omega_ratio: float
    max_path_error: float
    max_window_error: float
    dt: float
    samples: int
    pairs_checked: int
    time: float

    def message(self) -> str:
        """One line for the CLI."""
        dist = f"{self.min_distance:.4g}" if math.isfinite(self.min_distance) else "inf"
        head = "verified" if self.ok else "NOT verified"
        gap = f"{self.worst_gap:+.4g}" if math.isfinite(self.worst_gap) else "inf"
        line = (
            f"{head}: min distance {dist} (reported {self.safety_distance:.4g}; closest "
            f"pair vs its r_i + r_j + margin {gap} m), "
            f"max speed {self.max_speed_ratio:.3f}, accel {self.max_accel_ratio:.3f} "
            f"of the limits, path error {self.max_path_error:.2g} m, dt {self.dt:g} s"
        )
        if self.problems:
            more = f" (and {self.num_problems - 1} more)" if self.num_problems > 1 else ""
            line += f"; {self.problems[0]}{more}"
        return line


def verify(
    traj: Trajectories,
    instance: Instance | None = None,
    *,
    dt: float = DEFAULT_DT,
    tol: float = 1e-6,
    radius: float | None = None,
    max_problems: int = 20,
) -> VerifyReport:
    """Check ``traj`` against its limits, windows, path and safety distance.

    ``instance`` gives the limits (``v_max``, ``a_max``, ``omega_max``); without it the
    limits recorded in the trajectories are used.

    Example
    -------
    >>> from hierplan_opt.core.graph import Graph
    >>> from hierplan_opt.core.instance import Kinematics
    >>> from hierplan_opt.core.plan import Plan
    >>> from hierplan_opt.schedule import postprocess
    >>> from hierplan_opt.trajectory import refine
    >>> g = Graph.grid(4, 2)
    >>> inst = Instance.mapf(g, [(0, 0), (0, 1)], [(3, 0), (3, 1)],
    ...                      kinematics=Kinematics(a_max=2.0))
    >>> sched = postprocess(inst, Plan.from_paths([[0, 1, 2, 3], [4, 5, 6, 7]]))
    >>> rep = verify(refine(inst, sched, stretch="auto"), inst)
    >>> rep.ok, round(rep.min_distance, 2)
    (True, 1.0)
    """
    if not (isinstance(dt, (int, float)) and math.isfinite(dt) and dt > 0):
        raise InputError(f"dt must be a positive number, got {dt!r}")
    t_start = time.perf_counter()
    win = traj.windows
    if win is None:
        raise InputError("the trajectories carry no windows to verify against")
    net = win.network
    K = traj.num_agents
    H = traj.makespan
    S = int(math.floor(H / dt + 1e-9)) + 2
    ts = np.arange(S) * dt
    problems: list[str] = []
    count = [0]

    def bad(msg: str) -> None:
        count[0] += 1
        if len(problems) < max_problems:
            problems.append(msg)

    corridor = traj.corridor if traj.mode == "corridor" else 0.0
    vmax = np.zeros(K)
    amax = np.zeros(K)
    ratios = {"v": 0.0, "a": 0.0, "w": 0.0}
    path_err = 0.0
    win_err = 0.0
    positions = np.empty((S, K, traj.dim))
    for j, r in enumerate(traj.robots):
        lim = dict(r.limits)
        if instance is not None:
            # The instance's limits where it gives them; the ones the trajectory was
            # built for otherwise (``refine(..., a_max=1)`` on a MovingAI instance: before,
            # the check skipped them and reported "accel 0.000 of the limits")
            k = instance.agents[j].kinematics
            lim["v_max"] = float(k.v_max)
            lim["a_max"] = float(k.a_max) if k.a_max else lim.get("a_max", math.inf)
            if r.model == "unicycle":
                lim["omega_max"] = (
                    float(k.omega_max) if k.omega_max else lim.get("omega_max", math.inf)
                )
        vmax[j] = lim["v_max"]
        amax[j] = float(np.linalg.norm(r.a, axis=1).max(initial=0.0)) if len(r.a) else 0.0
        # After its last piece (and last event) a robot stands still: the samples from
        # there on are copies of one sample, so the checks below run on the prefix up to
        # two samples past that point (every distinct value) and the rest is filled in.
        m = min(S, int(np.searchsorted(ts, _rest_time(r), side="left")) + 2)
        st = r.state(ts[:m])
        P = st["p"]
        positions[:m, j] = P
        positions[m:, j] = P[-1]
        # ---- continuity of the pieces (bounds the finite-difference error) ---------------
        h = np.diff(r.t)
        if len(h):
            end = r.p[:-1] + r.v[:-1] * h[:, None] + 0.5 * r.a * (h * h)[:, None]
            jump = float(np.abs(end - r.p[1:]).max())
            vjump = float(np.abs(r.v[:-1] + r.a * h[:, None] - r.v[1:]).max())
        else:
            jump = vjump = 0.0
        if jump > 1e-5 or vjump > 1e-5:
            bad(f"{r.name}: the motion jumps by {max(jump, vjump):.2g} between grid intervals")
        # ---- limits from finite differences and on the nodes -------------------------
        vfd = np.linalg.norm(np.diff(P, axis=0), axis=1) / dt
        vnode = np.linalg.norm(r.v, axis=1)
        vr = max(float(vfd.max(initial=0.0)), float(vnode.max(initial=0.0))) / lim["v_max"]
        ratios["v"] = max(ratios["v"], vr)
        if vr > 1 + tol + jump / (dt * lim["v_max"]):
            bad(f"{r.name}: speed {vr * lim['v_max']:.6g} > v_max {lim['v_max']:g}")
        if math.isfinite(lim["a_max"]) and S > 2:
            afd = np.linalg.norm(P[2:] - 2 * P[1:-1] + P[:-2], axis=1) / (dt * dt)
            anode = np.linalg.norm(r.a, axis=1) if len(r.a) else np.zeros(1)
            ar = max(float(afd.max(initial=0.0)), float(anode.max(initial=0.0))) / lim["a_max"]
            ratios["a"] = max(ratios["a"], ar)
            if ar > 1 + tol + 4 * jump / (dt * dt * lim["a_max"]):
                bad(f"{r.name}: acceleration {ar * lim['a_max']:.6g} > a_max {lim['a_max']:g}")
        if r.model == "unicycle":
            th = np.unwrap(st["theta"])
            om = np.abs(np.diff(th)) / dt
            wmax = lim["omega_max"]
            wr = max(float(om.max(initial=0.0)), float(np.abs(r.omega).max(initial=0.0))) / wmax
            ratios["w"] = max(ratios["w"], wr)
            if wr > 1 + tol + jump / dt:
                bad(f"{r.name}: turn rate {wr * wmax:.6g} > omega_max {wmax:g}")
            # No sideways motion: the velocity points along the heading.
            mid_v = np.diff(P, axis=0) / dt
            thm = 0.5 * (th[1:] + th[:-1])
            side = np.abs(-mid_v[:, 0] * np.sin(thm) + mid_v[:, 1] * np.cos(thm))
            back = mid_v[:, 0] * np.cos(thm) + mid_v[:, 1] * np.sin(thm)
            worst = max(float(side.max(initial=0.0)), float(-back.min(initial=0.0)))
            if worst > 1e-4 + jump / dt + lim["v_max"] * float(om.max(initial=0.0)) * dt:
                bad(f"{r.name}: a differential-drive robot moves sideways ({worst:.3g} m/s)")
        # ---- windows and path ------------------------------------------------------------
        ev = np.array(list(net.events(j)), dtype=np.int64)
        et = np.asarray(r.event_times, dtype=float)
        if len(et) != len(ev):
            bad(f"{r.name}: {len(et)} event times for {len(ev)} way-points")
            continue
        if np.any(np.diff(et) < -tol):
            bad(f"{r.name}: passes its way-points out of order")
        lo, hi = win.lo[ev], win.hi[ev]
        over = np.maximum(lo - et, et - hi)
        win_err = max(win_err, float(over.max(initial=0.0)))
        # Within tol plus 1e-8 of the time (IPOPT meets bounds to 1e-8 relative).
        for i in np.flatnonzero(over > tol + WINDOW_RTOL * np.abs(et)).tolist():
            bad(
                f"{net.where(int(ev[i]))} passed at {et[i]:.6g} s, outside its window "
                f"[{lo[i]:.6g}, {hi[i]:.6g}]"
            )
        Pe = net.pos[ev]
        at = r.state(et)["p"]
        off = np.linalg.norm(at - Pe, axis=1)
        allowed = corridor + 1e-5
        for i in np.flatnonzero(off > allowed).tolist():
            bad(f"{net.where(int(ev[i]))}: the robot is {off[i]:.3g} m away when it passes it")
        path_err = max(path_err, float(np.max(off - corridor, initial=0.0)))
        seg = np.clip(np.searchsorted(et, ts[:m], side="right") - 1, 0, max(len(ev) - 2, 0))
        if len(ev) > 1:
            if corridor > 0:
                dist = np.full(m, np.inf)
                for shift in (-1, 0, 1):
                    s2 = np.clip(seg + shift, 0, len(ev) - 2)
                    d = _point_segment(P, Pe[s2], Pe[s2 + 1])
                    dist = np.minimum(dist, d)
            else:
                dist = _point_segment(P, Pe[seg], Pe[seg + 1])
            err = float(dist.max()) - corridor
            path_err = max(path_err, err)
            if err > 1e-5:
                k = int(np.argmax(dist))
                what = "its path" if corridor == 0 else f"its corridor of {corridor:g}"
                bad(f"{r.name}: {dist[k] - corridor:.3g} m off {what} at t = {ts[k]:.6g}")

    # ---- minimum distance between robots over continuous time ---------------------------
    need = _required(traj, instance)
    claimed = traj.safety_distance
    if radius is None:
        radius = max(2.0 * float(need.max(initial=0.0)), float(net.scale))
    best = (math.inf, None, None)
    worst = (math.inf, None, None)
    checked: set[tuple[int, int]] = set()
    for b0 in range(0, S - 1, BLOCK):
        b1 = min(S, b0 + BLOCK + 1)
        blk = positions[b0:b1]
        lo_b, hi_b = blk.min(axis=0), blk.max(axis=0)
        gap = np.maximum(
            0.0,
            np.maximum(lo_b[:, None, :] - hi_b[None, :, :], lo_b[None, :, :] - hi_b[:, None, :]),
        )
        near = np.sqrt((gap * gap).sum(axis=2)) <= radius
        ii, jj = np.nonzero(np.triu(near, 1))
        if not len(ii):
            continue
        checked.update(zip(ii.tolist(), jj.tolist(), strict=True))
        r = blk[:, ii] - blk[:, jj]  # (B, pairs, dim) relative positions
        r0, dr = r[:-1], r[1:] - r[:-1]
        dd = (dr * dr).sum(axis=2)
        s = np.clip(-(r0 * dr).sum(axis=2) / np.where(dd > 0, dd, 1.0), 0.0, 1.0)
        closest = np.linalg.norm(r0 + dr * s[..., None], axis=2)
        lower = np.maximum(closest - (amax[ii] + amax[jj])[None, :] * dt * dt / 8.0, 0.0)
        margin = lower - need[ii, jj][None, :]
        # The sampled bound is conservative by up to (a_i + a_j) dt^2 / 8: a pair that
        # keeps exactly its distance (0.7 m, two robots waiting side by side) read
        # 0.6999. Where it falls short, the exact minimum of the piecewise-quadratic
        # motions over the block decides (issue 34).
        t0b, t1b = float(ts[b0]), float(ts[b1 - 1])
        for q in np.flatnonzero(margin.min(axis=0) < -tol).tolist():
            a, c = int(ii[q]), int(jj[q])
            d_exact, t_exact = _exact_min_distance(traj.robots[a], traj.robots[c], t0b, t1b)
            column = np.full(lower.shape[0], np.inf)
            column[int(np.argmin(np.abs(ts[b0 : b0 + len(column)] - t_exact)))] = d_exact
            lower[:, q] = column
            margin[:, q] = column - need[a, c]
        k = np.unravel_index(int(np.argmin(lower)), lower.shape)
        val = float(lower[k])
        if val < best[0]:
            a, c = int(ii[k[1]]), int(jj[k[1]])
            best = (val, (traj.robots[a].name, traj.robots[c].name), float(ts[b0 + k[0]]))
        k = np.unravel_index(int(np.argmin(margin)), margin.shape)
        val = float(margin[k])
        if val < worst[0]:
            a, c = int(ii[k[1]]), int(jj[k[1]])
            worst = (val, (a, c), float(ts[b0 + k[0]]))
    min_d = best[0] if best[0] <= radius else math.inf
    if worst[1] is not None and worst[0] < -tol:
        a, c = worst[1]
        bad(
            f"robots {traj.robots[a].name} and {traj.robots[c].name} come within "
            f"{worst[0] + need[a, c]:.4g} m of each other near t = {worst[2]:.6g}, below "
            f"the {need[a, c]:.4g} m they must keep"
        )
    worst_pair = None
    if worst[1] is not None:
        worst_pair = (traj.robots[worst[1][0]].name, traj.robots[worst[1][1]].name)
    return VerifyReport(
        ok=count[0] == 0,
        problems=tuple(problems),
        num_problems=count[0],
        min_distance=min_d,
        min_pair=best[1] if math.isfinite(min_d) else None,
        min_time=best[2] if math.isfinite(min_d) else None,
        safety_distance=claimed,
        worst_gap=worst[0] if worst[1] is not None else math.inf,
        worst_pair=worst_pair,
        max_speed_ratio=ratios["v"],
        max_accel_ratio=ratios["a"],
        max_omega_ratio=ratios["w"],
        max_path_error=max(path_err, 0.0),
        max_window_error=max(win_err, 0.0),
        dt=float(dt),
        samples=S,
        pairs_checked=len(checked),
        time=time.perf_counter() - t_start,
    )


def _required(traj: Trajectories, instance: Instance | None) -> np.ndarray:
    """``(K, K)`` distances the pairs must keep: what the trajectories report
    (:meth:`Trajectories.required`) and, when ``instance`` is given and they report a
    guarantee, ``r_i + r_j + margin`` (``- 2 c``) with its radii (the physical robots)."""
    K = traj.num_agents
    if traj.radius:
        rad = np.asarray(traj.radius, dtype=float)
        d = rad[:, None] + rad[None, :] + traj.margin
        out = np.where(d > 0, np.maximum(d - 2.0 * traj.corridor, 0.0), 0.0)
        if not traj.enforced:
            out = np.zeros((K, K))
    else:
        out = np.zeros((K, K))
    # The reported smallest distance holds for every pair.
    out = np.maximum(out, float(traj.safety_distance))
    if instance is not None and traj.enforced and traj.safety_distance > 0:
        rad = np.array([a.kinematics.radius for a in instance.agents], dtype=float)
        d = rad[:, None] + rad[None, :] + traj.margin
        out = np.maximum(out, np.maximum(d - 2.0 * traj.corridor, 0.0))
    out = out.reshape(K, K).copy()
    np.fill_diagonal(out, 0.0)
    return out


def _rest_time(r: RobotTrajectory) -> float:
    """The time from which ``r`` stands still at its last position (its last piece and
    its last event are over; :meth:`RobotTrajectory.state` holds the position)."""
    last = float(r.t[-1]) if len(r.t) else 0.0
    if len(r.event_times):
        last = max(last, float(np.max(r.event_times)))
    return last


def _exact_min_distance(
    ra: RobotTrajectory, rb: RobotTrajectory, t0: float, t1: float
) -> tuple[float, float]:
    """The smallest distance between ``ra`` and ``rb`` over ``[t0, t1]`` and when:
    exact for the piecewise-quadratic motions (on each interval between their grid
    nodes the squared distance is a quartic; its minimum is at an end or a root of its
    derivative).

    Example
    -------
    >>> z = np.zeros((2, 2))
    >>> still = RobotTrajectory("a", "double_integrator", np.array([0.0, 2.0]),
    ...     np.array([[0.0, 0.0], [0.0, 0.0]]), z, np.zeros((1, 2)), np.zeros(2),
    ...     np.zeros(2), np.zeros(1), np.zeros(1), {})
    >>> mover = RobotTrajectory("b", "double_integrator", np.array([0.0, 2.0]),
    ...     np.array([[-1.0, 0.7], [1.0, 0.7]]), np.array([[1.0, 0.0], [1.0, 0.0]]),
    ...     np.zeros((1, 2)), np.zeros(2), np.zeros(2), np.zeros(1), np.zeros(1), {})
    >>> d, t = _exact_min_distance(still, mover, 0.0, 2.0)
    >>> round(d, 12), round(t, 12)
    (0.7, 1.0)
    """
    knots = np.concatenate([ra.t, rb.t, [t0, t1]])
    knots = np.unique(knots[(knots >= t0) & (knots <= t1)])
    best = (math.inf, t0)
    for lo, hi in zip(knots[:-1], knots[1:], strict=True):
        length = float(hi - lo)
        mid = np.array([0.5 * (lo + hi)])
        sa, sb = ra.state(np.array([lo])), rb.state(np.array([lo]))
        c0 = sa["p"][0] - sb["p"][0]
        c1 = sa["v"][0] - sb["v"][0]
        c2 = 0.5 * (ra.state(mid)["a"][0] - rb.state(mid)["a"][0])
        # d/dtau |c0 + c1 tau + c2 tau^2|^2 / 2: a cubic in tau
        cubic = [
            2.0 * float(c2 @ c2),
            3.0 * float(c1 @ c2),
            float(c1 @ c1) + 2.0 * float(c0 @ c2),
            float(c0 @ c1),
        ]
        taus = [0.0, length]
        if any(abs(x) > 0 for x in cubic):
            roots = np.roots(np.trim_zeros(np.array(cubic), "f"))
            taus += [float(r.real) for r in roots if abs(r.imag) < 1e-9 and 0 < r.real < length]
        for tau in taus:
            d = float(np.linalg.norm(c0 + c1 * tau + c2 * tau * tau))
            if d < best[0]:
                best = (d, float(lo) + tau)
    if len(knots) < 2:
        d = float(
            np.linalg.norm(ra.state(np.array([t0]))["p"][0] - rb.state(np.array([t0]))["p"][0])
        )
        best = (d, t0)
    return best


def _point_segment(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise distances of the points ``p`` from the segments ``ab`` (the closest
    point of a segment is the clipped projection; a zero-length segment is its point)."""
    u = b - a
    d = p - a
    uu = np.einsum("ij,ij->i", u, u)
    s = np.clip(np.einsum("ij,ij->i", d, u) / np.where(uu > 0, uu, 1.0), 0.0, 1.0)
    w = d - u * s[:, None]
    return np.sqrt(np.einsum("ij,ij->i", w, w))
