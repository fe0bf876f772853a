"""Monte Carlo runs of an execution: arrival-window probabilities, makespan and delay.

:func:`monte_carlo` repeats :func:`~hierplan_opt.execution.simulate` with seeds
``seed, seed + 1, ...`` (random delays without a seed of their own draw from the run's
seed), in parallel processes, with a progress bar. For every way-point at a vertex it
estimates the probability that the robot gets there within its arrival window (by the
schedule's latest time); the paper's delay-probability idea is ``replan_below``: the
locations whose probability falls below it are listed and ``replan_advised`` is set.
"""

from __future__ import annotations

import logging
import math
import os
import statistics as pystats
from collections.abc import Sequence
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from hierplan_opt.core.errors import OptionError
from hierplan_opt.core.instance import Instance
from hierplan_opt.core.progress import Progress
from hierplan_opt.execution.disturbances import Disturbance
from hierplan_opt.schedule.output import Schedule
from hierplan_opt.schedule.tpg import VERTEX

log = logging.getLogger(__name__)

#: Tolerance of the window check (seconds).
TOL = 1e-6


@dataclass(frozen=True, eq=False)
class MonteCarloResult:
    """Summary of ``runs`` executions (read-only).

    ``on_time[k]`` is the share of runs in which vertex event ``nodes[k]`` (STN node of
    the schedule) happened by its latest time; ``locations`` names them
    (``agent at (x, y)``). ``makespans`` / ``delays`` (makespan minus planned) per run;
    ``runs_stats`` the statistics dict of each run; ``below`` the locations under
    ``replan_below``.
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

    @property
    def runs_per_second(self) -> float:
        return self.runs / self.wall_time if self.wall_time > 0 else math.inf

    def summary(self) -> dict[str, Any]:
        """Plain values for reports."""
        mk = self.makespans[np.isfinite(self.makespans)]
        q = np.percentile(mk, [5, 50, 95]).tolist() if len(mk) else [math.nan] * 3
        return {
            "runs": self.runs,
            "policy": self.policy,
            "collisions": self.collisions,
            "makespan_mean": float(mk.mean()) if len(mk) else math.nan,
            "makespan_p5_p50_p95": q,
            "delay_mean": float(np.nanmean(self.delays)) if len(self.delays) else math.nan,
            "on_time_min": float(self.on_time.min()) if len(self.on_time) else 1.0,
            "on_time_mean": float(self.on_time.mean()) if len(self.on_time) else 1.0,
            "handled": dict(self.handled),
            "below": list(self.below),
            "replan_advised": self.replan_advised,
            "runs_per_second": self.runs_per_second,
        }


def _one_run(args: tuple[Any, ...]) -> tuple[dict[str, Any], np.ndarray]:
    instance, schedule, disturbances, policy, seed, nodes = args
    from hierplan_opt.execution.simulate import simulate

    ex = simulate(instance, schedule, disturbances=disturbances, policy=policy, seed=seed)
    return ex.statistics, ex.event_times[nodes]


def _chunk(args: tuple[Any, ...]) -> list[tuple[dict[str, Any], np.ndarray]]:
    instance, schedule, disturbances, policy, seeds, nodes = args
    return [_one_run((instance, schedule, disturbances, policy, s, nodes)) for s in seeds]


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
    progress: bool | None = None,
) -> MonteCarloResult:
    """Run ``runs`` seeded executions of ``schedule`` under ``delay_model``.

    ``workers``: processes (default: the CPUs, at most ``runs``; 1 runs in this
    process). ``replan_below``: list the vertex events whose on-time probability is
    below it and set ``replan_advised``.

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
    """
    import time

    if not isinstance(runs, int) or runs < 1:
        raise OptionError(f"runs must be a positive integer, got {runs!r}")
    if replan_below is not None and not 0 <= replan_below <= 1:
        raise OptionError(f"replan_below must be a probability, got {replan_below!r}")
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
                results.append(_one_run((instance, schedule, delay_model, policy, s, nodes)))
                bar.advance(collisions=sum(r[0]["collisions"] for r in results))
        else:
            size = max(1, min(16, runs // (workers * 4)))
            chunks = [seeds[i : i + size] for i in range(0, runs, size)]
            with ProcessPoolExecutor(workers) as pool:
                futures = [
                    pool.submit(_chunk, (instance, schedule, delay_model, policy, c, nodes))
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
    below: tuple[str, ...] = ()
    if replan_below is not None:
        below = tuple(locations[k] for k in np.flatnonzero(on_time < replan_below).tolist())
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
        below=below,
        replan_advised=bool(below),
        handled=handled,
    )


def median(xs: Sequence[float]) -> float:
    """Median (NaN for an empty list)."""
    return float(pystats.median(xs)) if xs else math.nan
