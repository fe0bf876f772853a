"""The lifelong loop: reveal tasks, assign them, plan a window, execute tick by tick.

:func:`run_lifelong` simulates a LoRR problem for ``ticks`` execution ticks with the
Start-Kit's rules: ``numTasksReveal * teamSize`` tasks are revealed at all times, an
errand is done when its robot stands on it at the end of a tick, one errand per tick
(:func:`~hierplan_opt.search.windowed.errand_done`, the planner's rule too: a robot
that stands on its next errand when it gets the task stays there a tick), a task is
done after its last errand, and
the action model is :func:`~hierplan_opt.lifelong.model.step_state` with the delays of
the problem's ``delayConfig`` (:mod:`~hierplan_opt.lifelong.delays`). Every ``period``
ticks (the Start-Kit's ``planCommTimeLimit / actionMoveTimeLimit``, 10 by default) the
scheduler assigns revealed tasks to free robots and the planner plans a window from
where the robots are committed to be; the executor runs it under the delays.

Time here is simulated: the loop does not advance while the planner runs, and each
planning call's wall time is recorded (``planner_times``) to compare with the
Start-Kit's budgets (first call 1 s, then one call per second). The Start-Kit instead
runs the planner in a thread against the wall clock, and applies a plan one period
after the state it was planned from.

Each delay is put down to the first layer that absorbed it: ``slack`` (the robot would
have waited anyway on every delayed tick), ``adg`` (the robot lost motion, but its next
action is late by no more than its slack in the window's temporal network: robots that
depend on it wait through the dependency graph and the window ends on time), ``stn``
(late beyond that slack: the window's temporal network is re-solved from that action,
:mod:`~hierplan_opt.lifelong.temporal`, pushing the targets of the robots after it) or
``replan`` (a planning call came while it was still delayed, and planned from where it
stood).
"""

from __future__ import annotations

import logging
import random
import time
from dataclasses import dataclass, field
from typing import Any

from hierplan_opt.core.collector import paused_gc
from hierplan_opt.core.errors import InputError
from hierplan_opt.core.progress import tick
from hierplan_opt.io.lorr import LorrProblem, encode_path
from hierplan_opt.lifelong.delays import DelayStream
from hierplan_opt.lifelong.executor import ADGExecutor
from hierplan_opt.lifelong.guidance import RegistryGuide
from hierplan_opt.lifelong.model import (
    CR,
    FW,
    LETTERS,
    NA,
    Distances,
    Grid,
    RobotState,
    W,
    step_state,
)
from hierplan_opt.lifelong.planner import PLANNERS, WindowedLaCAM, WindowedPIBT, errand_done
from hierplan_opt.lifelong.scheduler import SCHEDULERS, assign, chain_length

log = logging.getLogger(__name__)

#: Actions planned per call (default), and for fleets over LARGE_FLEET robots.
WINDOW = 6
WINDOW_LARGE = 4
LARGE_FLEET = 1000
#: Seconds a planning call keeps for itself after the planner's deadline (bookkeeping).
BUDGET_MARGIN = 0.05
#: Output segment length of the Start-Kit's path strings (its ``simulate(..., 100)``).
SEGMENT = 100


@dataclass
class Task:
    """A revealed task: its id, errands, reveal time, progress and robot."""

    id: int
    errands: tuple[int, ...]
    revealed: int
    next: int = 0
    robot: int = -1
    done_at: int = -1


@dataclass
class LifelongResult:
    """What a run did: counts, per-call planner times, delay handling and the log."""

    problem: str
    ticks: int
    tasks_finished: int
    planner_times: list[float]
    delays: int
    handled: dict[str, int]
    waits_on_delayed: int
    waits: dict[str, int]
    cycles_broken: int
    wall_time: float
    preprocess_time: float = 0.0
    budget: float | None = None
    cut_calls: int = 0
    steps_planned: int = 0
    stn_resolves: int = 0
    stn_pushed: float = 0.0
    log: dict[str, Any] = field(repr=False, default_factory=dict)

    @property
    def throughput(self) -> float:
        """Tasks finished per tick."""
        return self.tasks_finished / self.ticks if self.ticks else 0.0

    def summary(self) -> dict[str, Any]:
        """The figures as a flat dict (the CLI and the bench print these)."""
        pt = sorted(self.planner_times)
        return {
            "problem": self.problem,
            "ticks": self.ticks,
            "tasks_finished": self.tasks_finished,
            "throughput": round(self.throughput, 4),
            "delays": self.delays,
            "handled": dict(self.handled),
            "waits_on_delayed": self.waits_on_delayed,
            "stn_resolves": self.stn_resolves,
            "stn_pushed_ticks": round(self.stn_pushed, 1),
            "waits": dict(self.waits),
            "planner_calls": len(pt),
            "planner_s_median": round(pt[len(pt) // 2], 4) if pt else 0.0,
            "planner_s_max": round(pt[-1], 4) if pt else 0.0,
            "budget_s": self.budget,
            "over_budget_calls": sum(x > self.budget for x in pt) if self.budget else 0,
            "calls_cut_by_deadline": self.cut_calls,
            "steps_per_call": round(self.steps_planned / len(pt), 2) if pt else 0.0,
            "preprocess_s": round(self.preprocess_time, 2),
            "wall_s": round(self.wall_time, 2),
        }


def run_lifelong(
    problem: LorrProblem,
    *,
    ticks: int,
    scheduler: str = "hungarian",
    planner: str = "pibt",
    period: int = 10,
    window: int | None = None,
    seed: int = 0,
    congestion: float = 0.0,
    delays: DelayStream | None = None,
    max_table_bytes: int = 1 << 30,
    table_seconds: float | None = 0.3,
    preprocess_seconds: float = 30.0,
    budget: float | None = 1.0,
) -> LifelongResult:
    """Run the lifelong loop on ``problem`` for ``ticks`` ticks (see the module doc).

    ``window`` defaults to 6 actions, 4 above 1,000 robots. ``delays`` defaults to the
    problem's own ``delayConfig`` stream. ``budget`` is each planning call's time in
    seconds (the Start-Kit's: a plan per second of wall time; None: no limit): the
    planner returns the steps done by then (robots without a plan wait); calls that
    still take longer are counted as over budget. After every
    planning call the active progress (:func:`hierplan_opt.core.progress.reporting`)
    gets the tick and the tasks finished. Bad settings raise
    :class:`~hierplan_opt.core.errors.InputError` before any work.

    Example
    -------
    >>> import numpy as np
    >>> from hierplan_opt.io.lorr import LorrProblem
    >>> p = LorrProblem("line", 1, 5, np.zeros(5, dtype=bool), (0,), ((4,), (0,)),
    ...                 agent_counter=1)
    >>> r = run_lifelong(p, ticks=40)
    >>> r.tasks_finished, r.log["numTaskFinished"]
    (4, 4)
    """
    if ticks < 1:
        raise InputError(f"ticks must be at least 1, got {ticks}")
    if scheduler not in SCHEDULERS:
        raise InputError(f"unknown scheduler {scheduler!r} (use: {', '.join(SCHEDULERS)})")
    if planner not in PLANNERS:
        raise InputError(f"unknown planner {planner!r} (use: {', '.join(PLANNERS)})")
    if window is None:  # fewer steps for large fleets: a call must stay near a second
        window = WINDOW if problem.team_size <= LARGE_FLEET else WINDOW_LARGE
    if period < 1 or window < 1:
        raise InputError(f"period and window must be at least 1, got {period} and {window}")
    if budget is not None and not budget > BUDGET_MARGIN:
        raise InputError(f"budget must be more than {BUDGET_MARGIN} s, got {budget}")
    if congestion < 0:
        raise InputError(f"congestion must be >= 0, got {congestion}")
    if delays is not None and delays.n != problem.team_size:
        raise InputError(
            f"the delays are for {delays.n} robots, the problem has {problem.team_size}"
        )
    if problem.agent_size > 1.0:
        raise InputError(
            f"agentSize {problem.agent_size} > 1: footprints reach into neighbouring cells, "
            "which the cell-based executor does not guard"
        )
    t0 = time.perf_counter()
    grid = Grid(problem.rows, problem.cols, problem.blocked)
    dist = Distances(grid, max_table_bytes, table_seconds)
    kind = WindowedLaCAM if planner == "lacam" else WindowedPIBT
    pl = kind(grid, dist, window=window, seed=seed, congestion=congestion)
    guide = None
    if planner.endswith("-guided"):  # guide paths from the registry's solver of that name
        guide = RegistryGuide(grid, planner.removesuffix("-guided"), seed=seed)
    ex = ADGExecutor(grid.moves)
    stream = delays if delays is not None else DelayStream(problem.delay, problem.team_size)
    n = problem.team_size
    k = problem.agent_counter
    robots = [RobotState(loc) for loc in problem.starts]
    rng = random.Random(seed)
    prio = [rng.random() for _ in range(n)]

    tasks: dict[int, Task] = {}
    all_tasks: list[Task] = []
    next_id = 0
    current = [-1] * n
    finished = 0
    events: list[list[int]] = []
    schedule: list[list[tuple[int, int]]] = [[] for _ in range(n)]
    chains: dict[int, int] = {}

    def reveal(t: int) -> None:
        nonlocal next_id
        while len(tasks) < problem.reveal_count:
            errands = problem.tasks[next_id % len(problem.tasks)]
            task = Task(next_id, errands, t)
            tasks[next_id] = task
            all_tasks.append(task)
            next_id += 1

    # one byte per robot and tick (10,000 robots x 5,000 ticks: 50 MB, not 400 MB of lists)
    letters = [bytearray() for _ in range(n)]
    codes = LETTERS.encode()
    snaps: list[list[tuple[int, int, int, int]]] = [[] for _ in range(n)]
    planner_times: list[float] = []
    handled = {"slack": 0, "adg": 0, "stn": 0, "replan": 0}
    lost = [0] * n  # delayed ticks on which the robot would have moved
    open_delay = [False] * n
    pending = [0] * n  # the staged action (index in its window) a delay held up

    def settle(i: int, now: int) -> None:
        """Robot i's delay is over: put it down to slack, adg or stn."""
        if lost[i] == 0:
            handled["slack"] += 1
            return
        s = robots[i]
        ready = now + (k - s.count if s.count > 0 and s.cur != NA else 0)
        handled[ex.absorb_delay(i, pending[i], ready, grid.cols)] += 1

    waits_on_delayed = 0
    waits = {"delayed": 0, "blocked": 0, "idle": 0, "no_task": 0}
    cycles = 0
    n_delays = 0
    cut_calls = steps_planned = 0
    reveal(0)
    # preprocessing (the Start-Kit allows 30 s): the tables of the revealed errands
    p0 = time.perf_counter()
    dist.prefetch([e for tk in tasks.values() for e in tk.errands], budget=preprocess_seconds)
    preprocess = time.perf_counter() - p0

    for t in range(ticks):
        if t % period == 0:
            # No cyclic GC pass inside a timed call (a full pass over a large run's
            # objects takes up to 0.5 s); it runs again between calls.
            with paused_gc():
                # ---- plan: assign, then a window from the committed states
                c0 = time.perf_counter()
                dist.new_round()
                free = [i for i in range(n) if current[i] < 0]
                if free:
                    open_ids = [tid for tid, tk in tasks.items() if tk.robot < 0]
                    for tid in open_ids:
                        if tid not in chains:
                            chains[tid] = chain_length(dist, tasks[tid].errands)
                    got = assign(
                        scheduler,
                        dist,
                        free,
                        [_committed(robots[i], grid.moves)[0] for i in free],
                        open_ids,
                        [tasks[tid].errands for tid in open_ids],
                        [chains[tid] for tid in open_ids],
                    )
                    for i, tid in got.items():
                        current[i] = tid
                        tasks[tid].robot = i
                        schedule[i].append((t, tid))
                        prio[i] = rng.random()
                locs, oris, errands = [], [], []
                for i in range(n):
                    loc, ori = _committed(robots[i], grid.moves)
                    locs.append(loc)
                    oris.append(ori)
                    tk = tasks.get(current[i])
                    errands.append(_to_plan(robots[i], loc, tk) if tk is not None else ())
                dist.prefetch([e[0] for e in errands if e])
                paths = guide.paths(locs, errands, prio) if guide is not None else None
                limit = None if budget is None else c0 + budget - BUDGET_MARGIN
                plan = pl.plan(locs, oris, errands, prio, paths, deadline=limit)
                cut_calls += plan.cut
                steps_planned += plan.steps
                cycles += plan.cycles_broken
                ex.load(plan, robots, t, k)
                for i in range(n):
                    if current[i] >= 0:
                        prio[i] += 1.0
                    if open_delay[i] and stream.delayed(i):
                        handled["replan"] += 1
                        open_delay[i] = False
                planner_times.append(time.perf_counter() - c0)
            tick("ticks", t, ticks, finished=finished)
        # ---- delays, commands, one tick of motion
        for a, _d in stream.next_tick():
            n_delays += 1
            if open_delay[a]:  # back to back with its previous delay
                settle(a, t)
            open_delay[a] = True
            lost[a] = 0
            pending[a] = ex.started_n[a]
        # commands from the state at the start of the tick (all robots at once) ...
        delayed = [stream.delayed(i) for i in range(n)]
        cmds = ex.commands(robots, delayed, k)
        for i in range(n):
            s = robots[i]
            if t % SEGMENT == 0:
                r, c = divmod(s.loc, grid.cols)
                snaps[i].append((r, c, s.ori, s.count))
            if delayed[i]:
                if not ex.idle(i, s) and ex.command(i, s) != W:
                    lost[i] += 1
                waits["delayed"] += 1
                continue
            if open_delay[i]:  # its delay just ended
                settle(i, t)
                open_delay[i] = False
            if cmds[i] == W:
                b = ex.blocked_by[i]
                if b >= 0 and delayed[b]:
                    waits_on_delayed += 1
                idle_kind = "blocked" if b != -1 else "no_task" if current[i] < 0 else "idle"
                waits[idle_kind] += 1
        # ... then the motion, then the cells released
        for i in range(n):
            s = robots[i]
            a = cmds[i]
            in_progress = s.count > 0 and s.cur != NA
            prev_loc = s.loc
            step_state(s, a, grid.moves, k)
            if a != W and not in_progress:
                ex.started(i)
            elif not in_progress and not delayed[i]:
                ex.waited(i)  # a staged wait (held on an errand) is done
            if s.loc != prev_loc:
                ex.left(i, prev_loc)
            letters[i].append(codes[a])
        # ---- tasks: errands reached at timestep t + 1, then reveal
        ts = t + 1
        for i in range(n):
            tid = current[i]
            if tid < 0:
                continue
            tk = tasks[tid]
            if errand_done(robots[i].loc, tk.errands, tk.next):  # the planner's rule too
                tk.next += 1
                prio[i] = rng.random()
                if tk.next == len(tk.errands):
                    tk.done_at = ts
                    current[i] = -1
                    del tasks[tid]
                    finished += 1
                events.append([ts, i, tid, tk.next])
        reveal(ts)
    for i in range(n):
        if open_delay[i]:
            settle(i, ticks)
    tick("ticks", ticks, ticks, finished=finished)

    paths = [encode_path(letters[i].decode(), snaps[i], SEGMENT) for i in range(n)]
    out_log = {
        "actionModel": "MAPF_T",
        "version": "2026 LoRR",
        "teamSize": n,
        "numTaskFinished": finished,
        "makespan": ticks,
        "numPlannerErrors": 0,
        "numScheduleErrors": 0,
        "numEntryTimeouts": 0,
        "agentMaxCounter": k,
        "outputSegmentSize": SEGMENT,
        "delayIntervals": [[[a, b] for a, b in iv] for iv in stream.intervals],
        "start": [[*divmod(loc, grid.cols), "E"] for loc in problem.starts],
        "actualPaths": paths,
        "events": events,
        "tasks": [
            [tk.id, tk.revealed, [x for loc in tk.errands for x in divmod(loc, grid.cols)]]
            for tk in all_tasks
        ],
        "plannerTimes": [round(x, 6) for x in planner_times],
        "errors": [],
        "actualSchedule": [",".join(f"{a}:{b}" for a, b in sc) for sc in schedule],
        "plannerSchedule": [",".join(f"{a}:{b}" for a, b in sc) for sc in schedule],
        "scheduleErrors": [],
        "hierplan": {
            "scheduler": scheduler,
            "planner": planner,
            "period": period,
            "window": window,
            "seed": seed,
            "budget": budget,
            "callsCut": cut_calls,
            "delaysExact": stream.exact,
            "distanceTables": dist.made_total,
            "distanceSeconds": round(dist.seconds, 3),
            "distanceFallbacks": dist.fallbacks,
            "guideCalls": guide.calls if guide is not None else 0,
            "guidePlans": guide.solved if guide is not None else 0,
        },
    }
    return LifelongResult(
        problem=problem.name,
        ticks=ticks,
        tasks_finished=finished,
        planner_times=planner_times,
        delays=n_delays,
        handled=handled,
        waits_on_delayed=waits_on_delayed,
        waits=waits,
        cycles_broken=cycles,
        wall_time=time.perf_counter() - t0,
        preprocess_time=preprocess,
        budget=budget,
        cut_calls=cut_calls,
        steps_planned=steps_planned,
        stn_resolves=ex.stn_resolves,
        stn_pushed=ex.stn_pushed,
        log=out_log,
    )


def _to_plan(s: RobotState, loc: int, tk: Task) -> tuple[int, ...]:
    """The errands of ``tk`` left for the planner, from the robot's committed cell ``loc``.

    A robot with an action in progress stands on ``loc`` at the end of that action (a
    rotation: at the end of every tick), where :func:`errand_done` credits the next
    errand if it is there: that one is not planned again (the planner would hold the
    robot a tick for it)."""
    rest = tk.errands[tk.next :]
    if s.count > 0 and s.cur != NA and errand_done(loc, rest, 0):
        return rest[1:]
    return rest


def _committed(s: RobotState, moves: tuple[int, int, int, int]) -> tuple[int, int]:
    """Where a robot will be once its action in progress ends (cell, orientation)."""
    if s.count > 0 and s.cur == FW:
        return s.loc + moves[s.ori], s.ori
    if s.count > 0 and s.cur != NA:
        return s.loc, (s.ori + (1 if s.cur == CR else 3)) % 4
    return s.loc, s.ori


__all__ = ["PLANNERS", "LifelongResult", "run_lifelong"]
