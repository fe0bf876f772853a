"""The front door: ``solve(instance, solver=..., **options) -> Result``."""

from __future__ import annotations

import logging
import math
import time
from dataclasses import replace
from typing import Any

from hierplan_opt import registry
from hierplan_opt.core.errors import OptionError
from hierplan_opt.core.instance import Instance
from hierplan_opt.core.result import Result, Status
from hierplan_opt.core.validate import validate

log = logging.getLogger(__name__)

OBJECTIVES = ("soc", "makespan")


def solve(
    instance: Instance,
    solver: str = "cbs",
    *,
    time_limit: float | None = None,
    seed: int = 0,
    objective: str | None = None,
    **options: Any,
) -> Result:
    """Solve ``instance`` with a registered solver and validate what it returns.

    ``objective`` defaults to ``"soc"`` for MAPF and ``"makespan"`` for TAPF (and for
    solvers that only optimise makespan). Options a solver does not know are refused.
    A plan that fails the validator is never passed on: the result becomes ERROR with
    the violations in ``stats["violations"]``.

    Example
    -------
    >>> from hierplan_opt.core.graph import Graph
    >>> g = Graph.grid(5, 2, obstacles=[(0, 1), (1, 1), (3, 1), (4, 1)])
    >>> inst = Instance.mapf(g, [(0, 0), (1, 0)], [(4, 0), (3, 0)])
    >>> r = solve(inst, "cbs", time_limit=10)
    >>> r.status, r.cost
    (<Status.OPTIMAL: 'OPTIMAL'>, 8)
    """
    info = registry.get(solver)
    problem = "tapf" if instance.is_tapf else "mapf"
    if problem not in info.problems:
        raise OptionError(
            f"solver {solver!r} does not solve {problem.upper()} instances "
            f"(it solves: {', '.join(sorted(p.upper() for p in info.problems))})"
        )
    if info.one_team and len(instance.teams) > 1:
        raise OptionError(
            f"solver {solver!r} solves anonymous MAPF (one team); this instance has "
            f"{len(instance.teams)} teams (use 'cbm')"
        )
    if objective is None:
        objective = "soc" if problem == "mapf" and "soc" in info.objectives else "makespan"
    if objective not in OBJECTIVES:
        raise OptionError(f"unknown objective {objective!r} (use 'soc' or 'makespan')")
    if objective not in info.objectives:
        raise OptionError(
            f"solver {solver!r} does not optimise {objective!r} "
            f"(it does: {', '.join(sorted(info.objectives))})"
        )
    if time_limit is not None and (
        isinstance(time_limit, bool) or not math.isfinite(time_limit) or time_limit <= 0
    ):
        raise OptionError(f"time_limit must be a positive number of seconds, got {time_limit!r}")
    known = info.options()
    for key in options:
        if key not in known:
            raise OptionError(
                f"solver {solver!r} has no option {key!r} "
                f"(its options: {', '.join(known) or 'none'})"
            )
    fn = info.load()
    t0 = time.perf_counter()
    result: Result = fn(instance, time_limit=time_limit, seed=seed, objective=objective, **options)
    runtime = time.perf_counter() - t0
    result = replace(result, runtime=runtime, solver=solver, objective=objective)
    if result.plan is not None:
        violations = validate(instance, result.plan)
        if violations:
            log.error("solver %s returned an invalid plan: %s", solver, violations[0])
            stats = dict(result.stats)
            stats["violations"] = [str(v) for v in violations]
            stats["error"] = f"invalid plan: {violations[0]}"
            return replace(result, status=Status.ERROR, plan=None, cost=None, stats=stats)
        cost = result.plan.cost(objective)
        if result.cost is not None and result.cost != cost:
            log.error("solver %s reported cost %s but its plan costs %s", solver, result.cost, cost)
            stats = dict(result.stats)
            stats["error"] = f"reported cost {result.cost} but the plan costs {cost}"
            return replace(result, status=Status.ERROR, stats=stats)
        result = replace(result, cost=cost)
    return result
