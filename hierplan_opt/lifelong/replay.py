"""Independent replay of a LoRR log: footprints never overlap, every move is legal.

:func:`check_log` reads nothing but the problem and the log's JSON (``start``,
``actualPaths``, ``delayIntervals``, ``events``, ``tasks``, ``numTaskFinished``) and
re-runs the robots tick by tick with its own copy of the action rules (it shares no
code with the loop that wrote the log). It reports:

* invalid actions: a forward move out of the map or into a blocked cell, an action in
  progress replaced by another one, a delayed robot that does not wait;
* collisions: two footprints (squares of side ``agentSize``) whose swept boxes overlap
  during a tick, with the Start-Kit's own test (open intervals, a 1e-6 tolerance) --
  touching is allowed, any overlap is not; footprints below half a counter step are
  checked at that size, so two robots on one point always collide, however small;
* task events whose robot is not on the errand, and a finished count that does not
  match the events.

It reads the Start-Kit's logs too, so both programs' runs are checked the same way.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from hierplan_opt.core.errors import InputError
from hierplan_opt.io.lorr import LorrProblem, decode_path

_EPS = 1e-6
_DR = {0: (0, 1), 1: (1, 0), 2: (0, -1), 3: (-1, 0)}  # orientation -> (d_row, d_col)


@dataclass
class ReplayReport:
    """The outcome of :func:`check_log`; ``ok`` when nothing was found."""

    ticks: int = 0
    robots: int = 0
    invalid: int = 0
    collisions: int = 0
    bad_events: int = 0
    tasks_finished: int = 0
    problems: list[str] = field(default_factory=list)

    @property
    def ok(self) -> bool:
        """No invalid action, no collision, no bad event."""
        return not (self.invalid or self.collisions or self.bad_events)

    def note(self, text: str) -> None:
        """Keep the first few problems as examples."""
        if len(self.problems) < 10:
            self.problems.append(text)


def _interval(d0: float, dv: float, lo: float, hi: float) -> tuple[float, float] | None:
    if -_EPS < dv < _EPS:
        return (0.0, 1.0) if lo + _EPS < d0 < hi - _EPS else None
    t0, t1 = (lo - d0) / dv, (hi - d0) / dv
    if t0 > t1:
        t0, t1 = t1, t0
    te = _EPS / abs(dv)
    a, b = max(0.0, t0 + te), min(1.0, t1 - te)
    return (a, b) if a <= b else None


def boxes_collide(
    a: tuple[float, float, float, float], b: tuple[float, float, float, float], size: float
) -> bool:
    """Whether two squares of side ``size`` moving linearly from ``(x0, y0)`` to
    ``(x1, y1)`` over one tick overlap at some moment (the Start-Kit's swept test).

    Example
    -------
    >>> boxes_collide((0, 0, 1, 0), (1, 0, 1, 1), 1.0)  # into a cell being left sideways
    True
    >>> boxes_collide((0, 0, 1, 0), (1, 0, 2, 0), 1.0)  # following in line
    False
    """
    ix = _interval(a[0] - b[0], (a[2] - a[0]) - (b[2] - b[0]), -size, size)
    if ix is None:
        return False
    iy = _interval(a[1] - b[1], (a[3] - a[1]) - (b[3] - b[1]), -size, size)
    if iy is None:
        return False
    return max(ix[0], iy[0]) <= min(ix[1], iy[1])


def check_log(problem: LorrProblem, log: dict[str, Any]) -> ReplayReport:
    """Replay ``log`` on ``problem`` (see the module doc).

    Example
    -------
    >>> import numpy as np
    >>> p = LorrProblem("t", 1, 3, np.zeros(3, dtype=bool), (0, 2), ((1,),), agent_counter=1)
    >>> log = {"start": [[0, 0, "E"], [0, 2, "E"]], "makespan": 1,
    ...        "actualPaths": ["[(0,0,0,0,0):(F 1)]", "[(0,0,2,0,0):(W 1)]"]}
    >>> check_log(p, log).ok
    True
    >>> log["actualPaths"][1] = "[(0,0,2,2,0):(F 1)]"  # facing west, into robot 0's cell
    >>> r = check_log(p, log); r.collisions, r.problems[0]
    (1, 'tick 0: robots 0 and 1 overlap')
    """
    rep = ReplayReport()
    rows, cols, k = problem.rows, problem.cols, problem.agent_counter
    # Positions are multiples of 1/k: squares of half a step still catch two robots on
    # one point (or passing through each other) when the footprint is smaller than that.
    size = max(problem.agent_size, 0.5 / k)
    blocked = problem.blocked
    paths = log.get("actualPaths")
    if not isinstance(paths, list) or len(paths) != problem.team_size:
        raise InputError(f"log: actualPaths must list {problem.team_size} robots")
    n = len(paths)
    ticks = int(log.get("makespan", 0))
    r_, c_, o_, cnt_, cur_, acts = [], [], [], [], [], []
    for i, text in enumerate(paths):
        (r, c, o, cnt), letters = decode_path(text, f"log: actualPaths[{i}]")
        if r * cols + c != problem.starts[i]:
            rep.invalid += 1
            rep.note(
                f"robot {i} starts at ({r},{c}), the problem says {problem.rc(problem.starts[i])}"
            )
        r_.append(r)
        c_.append(c)
        o_.append(o)
        cnt_.append(cnt)
        cur_.append("T")
        acts.append(letters)
        ticks = max(ticks, len(letters))
    delayed: dict[int, list[tuple[int, int]]] = {}
    for i, ivs in enumerate(log.get("delayIntervals", []) or []):
        for s, e in ivs:
            delayed.setdefault(i, []).append((int(s), int(e)))
    rep.ticks, rep.robots = ticks, n
    # positions of every robot after each tick are kept only for the task check
    at_time: dict[int, list[int]] = {0: [r_[i] * cols + c_[i] for i in range(n)]}
    want_times = {int(e[0]) for e in log.get("events", []) or []}

    for t in range(ticks):
        x0 = [0.0] * n
        y0 = [0.0] * n
        x1 = [0.0] * n
        y1 = [0.0] * n
        for i in range(n):
            a = acts[i][t] if t < len(acts[i]) else "W"
            fx, fy = _offset(o_[i], cnt_[i], cur_[i], k)
            x0[i], y0[i] = c_[i] + fx, r_[i] + fy
            if any(s <= t < e for s, e in delayed.get(i, ())) and a != "W":
                rep.invalid += 1
                rep.note(f"tick {t}: robot {i} acts ({a}) while delayed")
            if cnt_[i] > 0 and cur_[i] != "T" and a not in ("W", cur_[i]):
                rep.invalid += 1
                rep.note(f"tick {t}: robot {i} does {a} in the middle of {cur_[i]}")
                a = cur_[i]
            if cnt_[i] > 0 and cur_[i] != "T" and a == "W":
                x1[i], y1[i] = x0[i], y0[i]
                continue
            if a == "F":
                dr, dc = _DR[o_[i]]
                nr, nc = r_[i] + dr, c_[i] + dc
                if not (0 <= nr < rows and 0 <= nc < cols) or blocked[nr * cols + nc]:
                    rep.invalid += 1
                    rep.note(f"tick {t}: robot {i} moves from ({r_[i]},{c_[i]}) into a wall")
                    x1[i], y1[i] = x0[i], y0[i]
                    continue
                cnt_[i] += 1
                if cnt_[i] >= k:
                    r_[i], c_[i], cnt_[i], cur_[i] = nr, nc, 0, "T"
                else:
                    cur_[i] = "F"
            elif a in ("R", "C"):
                cnt_[i] += 1
                if cnt_[i] >= k:
                    o_[i] = (o_[i] + (1 if a == "R" else 3)) % 4
                    cnt_[i], cur_[i] = 0, "T"
                else:
                    cur_[i] = a
            fx, fy = _offset(o_[i], cnt_[i], cur_[i], k)
            x1[i], y1[i] = c_[i] + fx, r_[i] + fy
        # swept boxes of robots in nearby cells
        bins: dict[tuple[int, int], list[int]] = {}
        for i in range(n):
            bins.setdefault((int(y0[i]), int(x0[i])), []).append(i)
        reach = int(size) + 2
        for i in range(n):
            bi, bj = int(y0[i]), int(x0[i])
            for dr in range(-reach, reach + 1):
                for dc in range(-reach, reach + 1):
                    for j in bins.get((bi + dr, bj + dc), ()):
                        if j <= i:
                            continue
                        if boxes_collide(
                            (x0[i], y0[i], x1[i], y1[i]), (x0[j], y0[j], x1[j], y1[j]), size
                        ):
                            rep.collisions += 1
                            rep.note(f"tick {t}: robots {i} and {j} overlap")
        if t + 1 in want_times:
            at_time[t + 1] = [r_[i] * cols + c_[i] for i in range(n)]
    _check_events(problem, log, at_time, rep)
    return rep


def _offset(o: int, cnt: int, cur: str, k: int) -> tuple[float, float]:
    if cur != "F" or cnt <= 0:
        return 0.0, 0.0
    dr, dc = _DR[o]
    f = cnt / k
    return dc * f, dr * f


def _check_events(
    problem: LorrProblem, log: dict[str, Any], at: dict[int, list[int]], rep: ReplayReport
) -> None:
    tasks: dict[int, list[int]] = {}
    for entry in log.get("tasks", []) or []:
        tid, _rev, flat = entry
        tasks[int(tid)] = [
            int(flat[j]) * problem.cols + int(flat[j + 1]) for j in range(0, len(flat), 2)
        ]
    done = 0
    for ev in log.get("events", []) or []:
        t, robot, tid, seq = (int(x) for x in ev)
        errands = tasks.get(tid)
        if errands is None or not 1 <= seq <= len(errands):
            rep.bad_events += 1
            rep.note(f"event {ev}: no such task or errand")
            continue
        if at.get(t, [None] * (robot + 1))[robot] != errands[seq - 1]:
            rep.bad_events += 1
            rep.note(f"event {ev}: robot {robot} is not on errand {seq} of task {tid}")
            continue
        if seq == len(errands):
            done += 1
    rep.tasks_finished = done
    claimed = log.get("numTaskFinished")
    if claimed is not None and int(claimed) != done:
        rep.bad_events += 1
        rep.note(f"numTaskFinished is {claimed} but the events finish {done} tasks")


__all__ = ["ReplayReport", "boxes_collide", "check_log"]
