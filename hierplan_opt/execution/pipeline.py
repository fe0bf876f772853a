"""The whole hierarchy in one library call: :func:`run` (plan -> validate -> MAPF-POST
-> [refine] -> execution under disturbances). ``hierplan run`` is this call with a
report."""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

from hierplan_opt.core.errors import OptionError
from hierplan_opt.core.instance import Instance
from hierplan_opt.core.result import Result
from hierplan_opt.execution.chain import plan_and_post
from hierplan_opt.execution.disturbances import Disturbance, check_disturbances
from hierplan_opt.execution.simulate import simulate
from hierplan_opt.execution.state import MODES, Execution
from hierplan_opt.registry import cost_keyword
from hierplan_opt.schedule.output import Schedule

if TYPE_CHECKING:
    from hierplan_opt.trajectory.result import Trajectories


@dataclass(frozen=True)
class Run:
    """Result of :func:`run`: every stage's output (None where the chain stopped:
    ``why`` says where) and the seconds each stage took (``times``)."""

    result: Result
    schedule: Schedule | None
    execution: Execution | None
    trajectories: Trajectories | None = None
    why: str = ""
    times: dict[str, float] = field(default_factory=dict)

    @property
    def ok(self) -> bool:
        """Executed without a collision and with every working robot at its goal."""
        ex = self.execution
        if ex is None:
            return False
        st = ex.statistics
        return st["collisions"] == 0 and not st["stranded"]


def run(
    instance: Instance,
    solver: str = "cbs",
    *,
    post: str = "makespan",
    disturbances: Sequence[Disturbance] = (),
    policy: str = "replan",
    mode: str = "agent",
    time_limit: float | None = 60.0,
    cost: str | None = None,
    objective: str | None = None,
    margin: float | None = None,
    refine: bool = False,
    a_max: float | None = None,
    seed: int = 0,
    dt: float = 0.1,
    replan_solver: str = "auto",
    replan_time_limit: float = 30.0,
    solver_options: dict[str, Any] | None = None,
) -> Run:
    """Plan ``instance`` with ``solver`` (validated; ``cost``: ``"soc"`` or ``"makespan"``,
    ``objective=`` its deprecated name), MAPF-POST it (objective ``post``),
    optionally refine it into smooth trajectories (``a_max``: the acceleration limit of
    robots whose kinematics give none, as in :func:`~hierplan_opt.trajectory.refine`),
    and execute it under ``disturbances`` with the execution ``policy`` (see
    :func:`.simulate`).

    Example
    -------
    >>> from hierplan_opt import Graph
    >>> from hierplan_opt.execution import Stop
    >>> inst = Instance.mapf(Graph.grid(4, 1), [(1, 0), (0, 0)], [(3, 0), (2, 0)])
    >>> r = run(inst, "cbs", disturbances=[Stop("agent0", 1.5, at_time=0.5)])
    >>> r.ok, r.result.cost, r.execution.statistics["finished"]
    (True, 4, 2)
    """
    t0 = time.perf_counter()
    planned = plan_and_post(
        instance,
        solver,
        time_limit=time_limit,
        seed=seed,
        cost=cost_keyword(cost, objective),
        post=post,
        margin=margin,
        **(solver_options or {}),
    )
    times = {"solve": planned.solve_time, "post": planned.post_time}
    if planned.schedule is None:
        return Run(planned.result, None, None, why=planned.why, times=times)
    schedule = planned.schedule
    check_disturbances(disturbances, instance, schedule)  # before refining or simulating
    traj = None
    if refine:
        from hierplan_opt.trajectory import refine as refine_schedule  # heavy module (CasADi)

        t1 = time.perf_counter()
        traj = refine_schedule(instance, schedule, stretch="auto", a_max=a_max)
        times["refine"] = time.perf_counter() - t1
    if mode not in MODES:
        raise OptionError(f"unknown mode {mode!r} (use {', '.join(MODES)})")
    t2 = time.perf_counter()
    ex = simulate(
        instance,
        schedule,
        disturbances=disturbances,
        policy=policy,
        mode=mode,
        seed=seed,
        dt=dt,
        solver=replan_solver,
        replan_time_limit=replan_time_limit,
        trajectories=traj,
    )
    times["simulate"] = time.perf_counter() - t2
    times["total"] = time.perf_counter() - t0
    return Run(planned.result, schedule, ex, traj, times=times)
