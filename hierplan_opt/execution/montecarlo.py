"""Monte Carlo runs of an execution: arrival-window probabilities, makespan and delay.

:func:`monte_carlo` repeats :func:`~hierplan_opt.execution.simulate` with seeds
``seed, seed + 1, ...``, in parallel processes; the runs' seeds drive every random
delay (a random disturbance's own ``seed`` would make every run draw the same delays, so
the batch replaces it and says so in the log), with a progress bar. For every way-point
at a vertex it estimates the probability that the robot gets there within its arrival
window (by the schedule's latest time).

The paper's delay-probability idea is ``replan_below``: the locations whose probability
falls below it are listed, and (with ``replan_solver``, the default) the plan is re-made
(:func:`delay_aware_replan`): the MAPF instance is solved again by the registered solver,
MAPF-POST turns the new plan into a schedule, and its target times are raised to the
``quantile`` of the executed times that a Monte Carlo batch of the new schedule under the
same delay model gives (rounds until every location is on time with at least the
threshold, at most ``MAX_ROUNDS``). The per-node quantiles of runs that each satisfy the
STN satisfy it too (``X_v >= X_u + lb`` in every run gives the same for quantiles), so
the buffered times are a schedule of the new STN: the plan validates and the schedule
replays. The price is a later planned makespan; the result reports both schedules'
probabilities and makespans side by side (``replanned``).
"""

from __future__ import annotations

import logging
import math
import os
import statistics as pystats
import time
from collections.abc import Sequence
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from hierplan_opt.core.errors import HierplanError, OptionError
from hierplan_opt.core.instance import Instance
from hierplan_opt.core.progress import Progress
from hierplan_opt.execution.chain import plan_and_post
from hierplan_opt.execution.disturbances import Disturbance, RandomDelays, Stop
from hierplan_opt.execution.follow import check_trajectories
from hierplan_opt.execution.replan import rescheduled
from hierplan_opt.execution.simulate import simulate
from hierplan_opt.execution.statistics import unsafe
from hierplan_opt.schedule.output import Schedule
from hierplan_opt.schedule.tpg import VERTEX

log = logging.getLogger(__name__)

#: Tolerance of the window check (seconds).
TOL = 1e-6
#: At most this many buffering rounds of a delay-aware re-plan.
MAX_ROUNDS = 8


@dataclass(frozen=True, eq=False)
class Replanned:
    """A delay-aware re-plan triggered by :func:`monte_carlo` (read-only).

    ``plan`` (valid for the instance) and ``schedule`` (its MAPF-POST schedule with
    target times buffered by the delay quantiles); ``result`` the Monte Carlo estimate
    of the new schedule (fresh seeds); ``rounds`` how many buffering rounds it took;
    ``solver`` the MAPF solver; ``quantile`` the quantile the targets were raised to.
    """

    plan: Any
    schedule: Schedule
    result: MonteCarloResult
    rounds: int
    solver: str
    quantile: float

    def summary(self) -> dict[str, Any]:
        return {
            "solver": self.solver,
            "rounds": self.rounds,
            "quantile": self.quantile,
            "planned_makespan": self.schedule.makespan,
            **{k: v for k, v in self.result.summary().items() if k != "replanned"},
        }


@dataclass(frozen=True, eq=False)
class MonteCarloResult:
    """Summary of ``runs`` executions (read-only).

    ``on_time[k]`` is the share of runs in which vertex event ``nodes[k]`` (STN node of
    the schedule) happened by its latest time; ``locations`` names them
    (``agent at (x, y)``). ``makespans`` / ``delays`` (makespan minus planned) per run;
    ``runs_stats`` the statistics dict of each run; ``samples[run, k]`` the executed
    time of ``nodes[k]`` (NaN: never); ``below`` the locations under ``replan_below``;
    ``replanned`` the delay-aware re-plan it triggered (None: none).
    """

    runs: int
    policy: str
    nodes: np.ndarray
    locations: tuple[str, ...]
    on_time: np.ndarray
    makespans: np.ndarray
    delays: np.ndarray
    collisions: int
    runs_stats: tuple[dict[str, Any], ...]
    wall_time: float
    below: tuple[str, ...] = ()
    replan_advised: bool = False
    handled: dict[str, int] = field(default_factory=dict)
    planned_makespan: float = math.nan
    replanned: Replanned | None = None
    samples: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))

    def on_time_of(self, location: str) -> float:
        """On-time probability of one location (its label in ``locations``)."""
        return float(self.on_time[self.locations.index(location)])

    @property
    def unsafe_runs(self) -> int:
        """Runs with a collision or the guaranteed distance not kept."""
        return sum(unsafe(s) for s in self.runs_stats)

    @property
    def stranded_runs(self) -> int:
        """Runs that left a working robot away from its goal (broken robots aside)."""
        return sum(bool(s["stranded"]) for s in self.runs_stats)

    @property
    def failed_runs(self) -> int:
        """Runs that are unsafe or left a working robot away from its goal."""
        return sum(unsafe(s) or bool(s["stranded"]) for s in self.runs_stats)

    @property
    def runs_per_second(self) -> float:
        return self.runs / self.wall_time if self.wall_time > 0 else math.inf

    def summary(self) -> dict[str, Any]:
        """Plain values for reports."""
        # Over the runs that reached a makespan (NaN, without a warning, when none did).
        mk = self.makespans[np.isfinite(self.makespans)]
        q = np.percentile(mk, [5, 50, 95]).tolist() if len(mk) else [math.nan] * 3
        delays = self.delays[np.isfinite(self.delays)]
        return {
            "runs": self.runs,
            "policy": self.policy,
            "collisions": self.collisions,
            "failed_runs": self.failed_runs,
            "unsafe_runs": self.unsafe_runs,
            "stranded_runs": self.stranded_runs,
            "makespan_mean": float(mk.mean()) if len(mk) else math.nan,
            "makespan_p5_p50_p95": q,
            "delay_mean": float(delays.mean()) if len(delays) else math.nan,
            "on_time_min": float(self.on_time.min()) if len(self.on_time) else 1.0,
            "on_time_mean": float(self.on_time.mean()) if len(self.on_time) else 1.0,
            "handled": dict(self.handled),
            "below": list(self.below),
            "replan_advised": self.replan_advised,
            "runs_per_second": self.runs_per_second,
            "planned_makespan": self.planned_makespan,
            "replanned": self.replanned.summary() if self.replanned is not None else None,
        }


def _one_run(args: tuple[Any, ...]) -> tuple[dict[str, Any], np.ndarray]:
    instance, schedule, disturbances, policy, seed, nodes, mode, traj = args

    ex = simulate(
        instance,
        schedule,
        disturbances=disturbances,
        policy=policy,
        seed=seed,
        mode=mode,
        trajectories=traj,
    )
    return ex.statistics, ex.event_times[nodes]


def _chunk(args: tuple[Any, ...]) -> list[tuple[dict[str, Any], np.ndarray]]:
    instance, schedule, disturbances, policy, seeds, nodes, mode, traj = args
    return [
        _one_run((instance, schedule, disturbances, policy, s, nodes, mode, traj)) for s in seeds
    ]


def monte_carlo(
    instance: Instance,
    schedule: Schedule,
    delay_model: Sequence[Disturbance],
    *,
    runs: int = 100,
    workers: int | None = None,
    seed: int = 0,
    policy: str = "replan",
    replan_below: float | None = None,
    replan_solver: str | None = "auto",
    progress: bool | None = None,
    mode: str = "agent",
    trajectories: Any = None,
) -> MonteCarloResult:
    """Run ``runs`` seeded executions of ``schedule`` under ``delay_model``.

    ``mode``: as in :func:`~hierplan_opt.execution.simulate` (``robot``: statistics
    and on-time probabilities of the robot-mode runs, bounded acceleration included).
    ``trajectories``: refined trajectories of ``schedule`` that every run follows (the
    delay-aware re-plan makes a new schedule, followed at constant velocity).

    ``workers``: processes (default: the CPUs, at most ``runs``; 1 runs in this
    process). ``replan_below``: list the vertex events whose on-time probability is
    below it and set ``replan_advised``; then, unless ``replan_solver`` is None,
    re-plan with :func:`delay_aware_replan` (same runs, workers and policy, fresh
    seeds) and return its plan, schedule and estimate in ``replanned`` (``auto``: ECBS
    for MAPF, CBM for teams).

    Example
    -------
    >>> from hierplan_opt import Graph, Plan
    >>> from hierplan_opt.schedule import postprocess
    >>> from hierplan_opt.execution import RandomDelays
    >>> inst = Instance.mapf(Graph.grid(4, 1), [(1, 0), (0, 0)], [(3, 0), (2, 0)])
    >>> s = postprocess(inst, Plan.from_paths([[1, 2, 3], [0, 1, 2]]))
    >>> mc = monte_carlo(inst, s, [RandomDelays(0.5, "constant", 1.0)], runs=20, workers=1,
    ...                  progress=False, replan_below=0.9)
    >>> mc.collisions, mc.runs, mc.replan_advised, mc.on_time.shape
    (0, 20, True, (6,))
    >>> new = mc.replanned
    >>> float(mc.on_time.min()) < 0.9 <= float(new.result.on_time.min())
    True
    >>> new.schedule.makespan > s.makespan  # the buffer's price
    True
    """
    if not isinstance(runs, int) or runs < 1:
        raise OptionError(f"runs must be a positive integer, got {runs!r}")
    if replan_below is not None and not 0 <= replan_below <= 1:
        raise OptionError(f"replan_below must be a probability, got {replan_below!r}")
    if mode not in ("agent", "robot", "replay"):
        raise OptionError(f"unknown mode {mode!r} (use agent, robot, replay)")
    if trajectories is not None:
        check_trajectories(schedule, trajectories)
    res = _estimate(
        instance, schedule, delay_model, runs, workers, seed, policy, progress, mode, trajectories
    )
    if replan_below is None:
        return res
    below = tuple(res.locations[k] for k in np.flatnonzero(res.on_time < replan_below).tolist())
    new = None
    if below and replan_solver is not None:
        log.info("%d location(s) below %g on time: delay-aware re-plan", len(below), replan_below)
        new = delay_aware_replan(
            instance,
            schedule,
            delay_model,
            threshold=replan_below,
            solver=replan_solver,
            runs=runs,
            workers=workers,
            seed=seed + runs,
            policy=policy,
            progress=progress,
            mode=mode,
        )
    return replace(res, below=below, replan_advised=bool(below), replanned=new)


def per_run_seeds(delay_model: Sequence[Disturbance]) -> list[Disturbance]:
    """The delay model a batch runs: random delays lose a seed of their own.

    With its own seed a :class:`~hierplan_opt.execution.RandomDelays` draws the same
    delays whatever the run's seed, and a batch of identical runs estimates nothing.

    Example
    -------
    >>> from hierplan_opt.execution import RandomDelays
    >>> per_run_seeds([RandomDelays(0.1, seed=1)])[0].seed is None
    True
    """

    out: list[Disturbance] = []
    for d in delay_model:
        if isinstance(d, RandomDelays) and d.seed is not None:
            log.info(
                "monte carlo: random delays' own seed %d dropped: each run draws from its seed",
                d.seed,
            )
            d = replace(d, seed=None)
        out.append(d)
    return out


def _estimate(
    instance: Instance,
    schedule: Schedule,
    delay_model: Sequence[Disturbance],
    runs: int,
    workers: int | None,
    seed: int,
    policy: str,
    progress: bool | None,
    mode: str = "agent",
    trajectories: Any = None,
) -> MonteCarloResult:
    """The Monte Carlo batch itself (no threshold)."""
    delay_model = per_run_seeds(delay_model)

    assert schedule.stn is not None
    tpg = schedule.stn.tpg
    nodes = np.flatnonzero(tpg.node_kind == VERTEX)
    if workers is None:
        workers = os.cpu_count() or 1
    workers = max(1, min(int(workers), runs))
    seeds = list(range(seed, seed + runs))
    t0 = time.perf_counter()
    results: list[tuple[dict[str, Any], np.ndarray]] = []
    with Progress(f"monte carlo {policy}", runs, unit="runs", enabled=progress) as bar:
        if workers == 1:
            for s in seeds:
                one = (instance, schedule, delay_model, policy, s, nodes, mode, trajectories)
                results.append(_one_run(one))
                bar.advance(collisions=sum(r[0]["collisions"] for r in results))
        else:
            size = max(1, min(16, runs // (workers * 4)))
            chunks = [seeds[i : i + size] for i in range(0, runs, size)]
            with ProcessPoolExecutor(workers) as pool:
                futures = [
                    pool.submit(
                        _chunk,
                        (instance, schedule, delay_model, policy, c, nodes, mode, trajectories),
                    )
                    for c in chunks
                ]
                for fut in futures:
                    part = fut.result()
                    results += part
                    bar.advance(len(part), collisions=sum(r[0]["collisions"] for r in results))
    wall = time.perf_counter() - t0
    stats = tuple(r[0] for r in results)
    times = np.array([r[1] for r in results]).reshape(len(results), len(nodes))
    latest = schedule.latest[nodes]
    on_time = np.mean(times <= latest[None, :] + TOL, axis=0)
    locations = tuple(tpg.label(int(v)) for v in nodes)
    makespans = np.array([s["makespan"] for s in stats], dtype=float)
    handled: dict[str, int] = {}
    for s in stats:
        for k, v in s["handled"].items():
            handled[k] = handled.get(k, 0) + v
    return MonteCarloResult(
        runs=runs,
        policy=policy,
        nodes=nodes,
        locations=locations,
        on_time=on_time,
        makespans=makespans,
        delays=makespans - schedule.makespan,
        collisions=int(sum(s["collisions"] for s in stats)),
        runs_stats=stats,
        wall_time=wall,
        handled=handled,
        planned_makespan=schedule.makespan,
        samples=times,
    )


def delay_aware_replan(
    instance: Instance,
    schedule: Schedule,
    delay_model: Sequence[Disturbance],
    *,
    threshold: float,
    solver: str = "auto",
    runs: int = 100,
    workers: int | None = None,
    seed: int = 0,
    policy: str = "replan",
    time_limit: float = 60.0,
    progress: bool | None = None,
    mode: str = "agent",
) -> Replanned:
    """A new plan and a schedule whose locations are on time with ``threshold``.

    The instance is solved again by ``solver`` (validated; ``auto``: ECBS for MAPF,
    CBM for teams), MAPF-POST makes its
    schedule (the old schedule's margin), then every round runs a Monte Carlo batch
    and raises each node's release to the ``quantile`` (halfway between ``threshold``
    and 1) of its executed times, until the batch of the buffered schedule finds every
    location on time with at least ``threshold`` or ``MAX_ROUNDS`` rounds are done.
    Raises :class:`~hierplan_opt.core.errors.HierplanError` when the solver finds no
    plan.
    """

    if solver == "auto":
        solver = "cbm" if instance.is_tapf else "ecbs"
    planned = plan_and_post(instance, solver, time_limit=time_limit, margin=schedule.margin)
    if planned.schedule is None:
        raise HierplanError(f"delay-aware re-plan: {planned.why}")
    res, sched = planned.result, planned.schedule
    assert res.plan is not None
    delay_model = _on_schedule(delay_model, sched)
    q = threshold + (1.0 - threshold) / 2
    est = _estimate(instance, sched, delay_model, runs, workers, seed, policy, progress, mode)
    rounds = 0
    while rounds < MAX_ROUNDS and est.on_time.min(initial=1.0) < threshold:
        rounds += 1
        stn = sched.stn
        assert stn is not None
        release = np.array(stn.release, dtype=float)
        # Every node's executed time in every run (vertex nodes sampled; the pieces in
        # between follow from the STN's lower bounds when the times are propagated).
        never = np.where(np.isnan(est.samples), np.inf, est.samples)  # never: not on time
        quant = np.quantile(never, q, axis=0, method="higher")
        ok = np.isfinite(quant)
        release[est.nodes[ok]] = np.maximum(release[est.nodes[ok]], quant[ok])
        sched, _ = rescheduled(sched, stn.with_bounds(release=release), delay_quantile=q)
        est = _estimate(
            instance,
            sched,
            delay_model,
            runs,
            workers,
            seed + rounds * runs,
            policy,
            progress,
            mode,
        )
    return Replanned(res.plan, sched, est, rounds, solver, q)


def _on_schedule(delay_model: Sequence[Disturbance], schedule: Schedule) -> list[Disturbance]:
    """The delay model without the stops at way-points the new ``schedule`` does not have
    (way-points are counted on the old schedule; the re-plan's robots may have fewer)."""
    out: list[Disturbance] = []
    for d in delay_model:
        if isinstance(d, Stop) and d.at_waypoint is not None:
            k = schedule.agent_names.index(d.agent)
            if d.at_waypoint >= len(schedule.waypoints[k].arrival):
                log.info(
                    "delay-aware re-plan: %s has no way-point %d: its stop is dropped",
                    d.agent,
                    d.at_waypoint,
                )
                continue
        out.append(d)
    return out


def median(xs: Sequence[float]) -> float:
    """Median (NaN for an empty list)."""
    return float(pystats.median(xs)) if xs else math.nan
