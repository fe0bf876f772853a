"""The slack, STN and ADG layers of the execution hierarchy, as functions of an
:class:`~.state.ExecState` (testable without the event loop).

* slack: :func:`lateness` and :func:`slack_decision` - is robot's next node late, and
  does its slack (latest time against the schedule's makespan and deadlines) absorb it;
* stn: :func:`stn_resolve` - the incremental STN re-solve (its release raised, executed
  events fixed at their times - an executed node's release never above its time -,
  successors pushed in topological order);
* adg: :func:`initial_targets` / :func:`latest_times` - no schedule, every node as soon
  as its dependencies allow.

Re-ordering (:mod:`.reorder`) and re-planning (:mod:`.replan`) are the other layers.
"""

from __future__ import annotations

import numpy as np

from hierplan_opt.execution.state import TOL, ExecState, rebound
from hierplan_opt.schedule.solve_graph import earliest_times, fix_and_propagate

#: STNs with at least this many nodes are re-solved by one vectorised pass.
FULL_PASS_NODES = 20_000


def lateness(state: ExecState, n: int) -> tuple[float, float]:
    """``(late, slack)`` of node ``n``: how far its physical arrival is behind its
    target, and how far its target may move (latest - target), in seconds."""
    return float(state.phys[n] - state.T[n]), float(state.latest[n] - state.T[n])


def slack_decision(state: ExecState, n: int) -> tuple[str, float, str]:
    """``(verdict, late, note)``: ``on time``, ``absorbed`` (the slack layer handles
    it: nothing re-computed) or ``escalate`` (the next layer must).

    Example
    -------
    >>> import numpy as np
    >>> s = ExecState.__new__(ExecState)
    >>> s.policy, s.layers = "stn", ("slack", "stn")
    >>> s.phys, s.T, s.latest = np.array([3.0, 9.0]), np.array([2.0, 5.0]), np.array([4.0, 6.0])
    >>> slack_decision(s, 0)[0], slack_decision(s, 1)[0]
    ('absorbed', 'escalate')
    """
    late, slack = lateness(state, n)
    if late <= TOL * max(1.0, abs(float(state.T[n]))):
        return "on time", 0.0, "on time"
    ok = late <= slack + TOL
    if state.policy in ("adg", "naive") or ok or "stn" not in state.layers:
        note = "absorbed by slack" if ok else f"not absorbed ({late - slack:.3g} s past slack)"
        if state.policy in ("adg", "naive"):
            note = "no schedule to repair" if state.policy == "adg" else "clock followed"
        return "absorbed", late, note
    return "escalate", late, ""


def stn_resolve(state: ExecState, n: int | list[int], now: float) -> list[int]:
    """Incremental STN re-solve: the release of node ``n`` (or of each node of a list)
    raised to when the robot can be there, executed events fixed, successors pushed
    (topological order). Updates the state's STN and targets; robots on their way to a
    node whose target moved slow down from ``now`` on. Returns the queued nodes whose
    time changed (to queue again).

    Raises :class:`~hierplan_opt.schedule.solve_graph.InconsistentSTNError` (deadlines).
    """
    nodes = [n] if isinstance(n, int) else list(n)
    stn = state.stn
    release = np.array(stn.release, dtype=float)
    # An executed event's time is a fact, its release was a prediction: a robot may pass
    # a node a little before the release an earlier re-solve gave it (a physical robot
    # counts as there within its reach tolerance), which must not make the STN
    # inconsistent.
    done = ~np.isnan(state.t)
    release[done] = np.minimum(release[done], state.t[done])
    fixed: dict[int, float] = {}
    for v in nodes:
        release[v] = max(release[v], float(state.phys[v]))
        if v > 0 and not np.isnan(state.t[v - 1]):
            fixed[v - 1] = float(state.t[v - 1])
    new_stn = rebound(stn, release=release)
    times = np.where(np.isnan(state.t), state.T, state.t)
    if stn.num_nodes >= FULL_PASS_NODES:
        # Large STNs: one vectorised earliest-times pass from the current times (the
        # same answer as pushing the successors; cheaper when many are pushed).
        floor = rebound(new_stn, release=np.maximum(new_stn.release, times))
        new_T = earliest_times(floor)
    else:
        new_T = fix_and_propagate(new_stn, times, fixed, changed=nodes)
    state.counts["stn_resolves"] += 1
    changed = np.flatnonzero((new_T > state.T + TOL) & np.isnan(state.t))
    state.stn = new_stn
    state.T = np.where(np.isnan(state.t), new_T, state.T)
    again = []
    moving = changed[~np.isnan(state.phys[changed])]  # robots on their way there
    for v in moving[state.T[moving] > state.phys[moving]].tolist():
        g = state.gid[state.agent_of(v)]
        if state.traj[g] and state.traj[g][-1][0] < now < state.phys[v]:
            state.record(g, now, state.traj_pos(g, now, v))
        state.phys[v] = float(state.T[v])
        if state.in_heap[v]:
            again.append(v)
    return again


def initial_targets(policy: str, targets: np.ndarray) -> np.ndarray:
    """The targets a phase starts from: the schedule's, or 0 for ``adg`` (each node as
    soon as its dependencies allow)."""
    return np.zeros_like(targets) if policy == "adg" else targets


def latest_times(policy: str, latest: np.ndarray, targets: np.ndarray) -> np.ndarray:
    """How late each node may be before the STN layer acts (``adg``: never)."""
    return np.full(len(targets), np.inf) if policy == "adg" else np.maximum(latest, targets)
