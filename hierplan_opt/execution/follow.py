"""Following refined trajectories (:func:`hierplan_opt.trajectory.refine`) in execution.

With ``simulate(..., trajectories=T)`` each robot plays its refined motion
``p_j(tau)`` on its own *trajectory clock* ``tau``: the event loop of
:mod:`.simulate` runs unchanged, with the refined event times as targets and the
refined duration of every piece (one way-point to the next) as its duration, so a
robot passes its way-points exactly when its trajectory does unless it is held.
Afterwards the executed motion is ``p_j(tau_j(t))`` with a piecewise-linear clock:

* ``tau`` runs at rate 1 (at the slow factor ``f`` on a slowed piece: positions on the
  refined path, velocity times ``f``, acceleration times ``f**2``);
* it stops during a **hold**: a halt (stop disturbance, random delay) and the wait at a
  way-point whose Type-2 predecessors have not happened (the TPG rule). A hold is an
  instantaneous stop: the velocity jumps to zero and back, so the refined acceleration
  limit does not hold across a hold; afterwards the robot continues its trajectory
  *time-shifted* by the hold (it never speeds up to catch up).

The robot always stays on its refined path and passes its way-points in the TPG
order, so the pair distance ``Trajectories.required(i, j)`` of the refinement carries
over. After a MAPF re-plan the new schedule is refined again (same mode, ``stretch=
"auto"``) and followed the same way; the way to a new start vertex is the event loop's
constant-velocity hand-over; a re-plan that cannot be refined is followed at constant
velocity (the log says which).

In ``robot`` mode the event times of this run pace the robot-mode controller
(:mod:`.robot`): bounded acceleration along the polylines, holds braked for; its
distances are checked against the schedule's ``r_i + r_j + margin``.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

import numpy as np

from hierplan_opt.core.errors import InputError, OptionError
from hierplan_opt.execution.state import ExecState
from hierplan_opt.trajectory.result import Trajectories

if TYPE_CHECKING:
    from hierplan_opt.trajectory.result import Trajectories

#: Largest sampling step of the executed motion (seconds).
MAX_STEP = 0.05


def check_trajectories(schedule: Any, traj: Trajectories, mode: str = "agent") -> None:
    """Refuse trajectories that were not refined from ``schedule`` (one line)."""

    if not isinstance(traj, Trajectories):
        raise OptionError(f"trajectories must be a Trajectories object, got {type(traj).__name__}")
    names = tuple(schedule.agent_names)
    if traj.agent_names != names:
        extra = sorted(set(traj.agent_names) - set(names))
        missing = sorted(set(names) - set(traj.agent_names))
        why = (
            f"robots {', '.join(extra[:3]) or '-'} not in the schedule, "
            f"{', '.join(missing[:3]) or '-'} missing"
            if extra or missing
            else "robots in another order"
        )
        raise InputError(f"the trajectories do not match the schedule's robots ({why})")
    tpg = schedule.stn.tpg
    for j, r in enumerate(traj.robots):
        m = int(tpg.agent_ptr[j + 1] - tpg.agent_ptr[j])
        if len(r.event_times) != m:
            raise InputError(
                f"the trajectory of {r.name} has {len(r.event_times)} way-point events, the "
                f"schedule {m}: refine this schedule (same objective and margin)"
            )


def _clock(
    sim: ExecState,
    g: int,
    e: np.ndarray,
    times: np.ndarray,
    rate: np.ndarray,
    first: int,
    end: float,
) -> list[tuple[float, float]]:
    """Breakpoints ``(t, tau)`` of robot ``g``'s trajectory clock until ``end``."""
    holds = sorted(sim.holds[g])
    pts: list[tuple[float, float]] = [(0.0, float(e[0]))]
    m = len(e)
    for k in range(1, m):
        t_a = float(times[first + k - 1])
        t_b = float(times[first + k]) if not np.isnan(times[first + k]) else end
        if np.isnan(t_a) or t_b < t_a:
            break
        tau, goal, f = float(e[k - 1]), float(e[k]), max(float(rate[first + k]), 1e-9)
        pts.append((t_a, tau))
        cur = t_a
        for hs, he in [*holds, (t_b, t_b)]:
            if (he <= cur or hs >= t_b) and hs != t_b:
                continue
            hs, he = max(hs, cur), min(he, t_b)
            if tau < goal:  # moves from cur to hs
                reach = cur + (goal - tau) / f
                if reach <= hs:
                    pts.append((reach, goal))
                    tau = goal
                else:
                    tau += f * (hs - cur)
                    pts.append((hs, tau))
            pts.append((he, tau))  # held until he
            cur = he
        if not np.isnan(times[first + k]):
            pts.append((t_b, goal))  # at its way-point (snaps within tolerance)
        else:
            pts.append((t_b, tau))
            break
    return pts


def follow_run(sim: ExecState, dt: float) -> tuple[list[np.ndarray], float]:
    """Executed ``(time, coords...)`` per robot (instance coordinates) and the bound on
    how much closer two robots may come between samples than the samples show.

    Phase by phase: on a refined schedule the robot's trajectory clock, on one followed
    at constant velocity (a re-plan that could not be refined) and on the way to a
    re-plan's start vertex the event loop's way-points."""
    scale = float(sim.schedule0.scale)
    h = min(float(dt), MAX_STEP)
    out: list[np.ndarray] = []
    acc = 0.0
    for g in range(sim.K):
        rows: list[np.ndarray] = []
        prev_end: float | None = None
        for p, ph in enumerate(sim.phases):
            if g not in ph.agents:
                continue
            j = ph.agents.index(g)
            tpg = ph.stn.tpg
            times = ph.times
            first = int(tpg.agent_ptr[j])
            last_idx = int(tpg.agent_ptr[j + 1]) - 1
            done = np.flatnonzero(~np.isnan(times[first : last_idx + 1]))
            if not len(done):
                continue
            t_first = float(times[first])
            end = float(times[first + done[-1]])
            if sim.broken[g] and done[-1] != last_idx - first:
                end = max(end, float(sim.traj[g][-1][0]))  # broke down on the way
            if prev_end is not None:  # on the way to the new start vertex
                rows.append(_records(sim, g, prev_end, t_first, closed=False))
            traj = sim.follows.get(p)
            if traj is None:
                rows.append(_records(sim, g, t_first, end, closed=True))
            else:
                r = traj.robots[j]
                rate = sim.rates.get(p)
                rate = rate if rate is not None else np.ones(len(times))
                pts = _clock(sim, g, r.event_times, times, rate, first, end)
                ct = np.maximum.accumulate(np.array([q[0] for q in pts]))
                ctau = np.array([q[1] for q in pts])
                t0 = 0.0 if p == 0 else t_first
                grid = np.arange(t0, end + h, h)
                ts = np.unique(np.concatenate([ct[ct >= t0], grid[grid < end], [t0, end]]))
                tau = np.interp(ts, ct, ctau)
                rows.append(np.column_stack([ts, r.state(tau)["p"] / scale]))
                if len(r.a):
                    acc = max(acc, float(np.max(np.linalg.norm(r.a, axis=1))))
            prev_end = end
        if prev_end is not None:  # anything recorded after (none but a broken robot's stop)
            rows.append(_records(sim, g, prev_end, math.inf, closed=False))
        arr = np.vstack([x for x in rows if len(x)])
        keep = np.ones(len(arr), dtype=bool)
        keep[1:] = arr[1:, 0] > arr[:-1, 0] + 1e-12
        out.append(arr[keep])
    # Between samples a pair's relative position leaves the chord by <= A h^2 / 8.
    return out, 2.0 * acc * h * h / 8.0


def refined_position(sim: ExecState, j: int, now: float) -> np.ndarray:
    """Where robot ``j`` (of the running phase) is at ``now`` on its refined trajectory
    (instance coordinates)."""
    traj = sim.follows[len(sim.phases) - 1]
    g = sim.gid[j]
    r = traj.robots[j]
    first = int(sim.S.tpg.agent_ptr[j])
    pts = _clock(sim, g, r.event_times, sim.t, sim.rate, first, now)
    ct = np.maximum.accumulate(np.array([q[0] for q in pts]))
    tau = float(np.interp(now, ct, np.array([q[1] for q in pts])))
    return r.state(np.array([tau]))["p"][0] / float(sim.schedule0.scale)


def _records(sim: ExecState, g: int, t0: float, t1: float, *, closed: bool) -> np.ndarray:
    """The event loop's way-points of robot ``g`` in ``[t0, t1]`` (open: ``(t0, t1)``)."""
    eps = 1e-12
    if closed:
        pts = [(t, q) for t, q in sim.traj[g] if t0 - eps <= t <= t1 + eps]
    else:
        pts = [(t, q) for t, q in sim.traj[g] if t0 + eps < t < t1 - eps]
    if not pts:
        return np.zeros((0, 1 + sim.S.tpg.node_coord.shape[1]))
    return np.array([[t, *q] for t, q in pts], dtype=float)


def required_distance(sim: ExecState) -> Any:
    """``required(i, j)`` over every refined phase: the smallest of their distances."""
    follows = [(sim.phases[p].agents, t) for p, t in sorted(sim.follows.items())]

    def required(a: int, b: int) -> float:
        need = math.inf
        for agents, traj in follows:
            if a in agents and b in agents:
                need = min(need, float(traj.required(agents.index(a), agents.index(b))))
        return need

    return required
