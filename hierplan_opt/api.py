"""The front door: ``solve(instance, solver=..., **options) -> Result``."""

from __future__ import annotations

import logging
import time
from dataclasses import replace
from typing import Any

from hierplan_opt import registry
from hierplan_opt.core.errors import OptionError
from hierplan_opt.core.instance import Instance
from hierplan_opt.core.result import Result, Status
from hierplan_opt.core.validate import validate

log = logging.getLogger(__name__)

#: Seconds ``solve`` may take unless told otherwise (the CLI's default too).
DEFAULT_TIME_LIMIT = 60.0


def solve(
    instance: Instance,
    solver: str = "cbs",
    *,
    time_limit: float | None = DEFAULT_TIME_LIMIT,
    seed: int = 0,
    objective: str | None = None,
    **options: Any,
) -> Result:
    """Solve ``instance`` with a registered solver and validate what it returns.

    ``time_limit`` is a wall-clock budget in seconds (default 60, like the CLI; None
    means no limit): on expiry the result is TIME_LIMIT with the best proven lower bound
    (or FEASIBLE with the best plan found). ``objective`` defaults to ``"soc"`` for MAPF
    and ``"makespan"`` for TAPF (and for solvers that only optimise makespan). Every
    option is checked before any work (unknown ones are refused), and the cheap checks
    of :func:`hierplan_opt.registry.cheap_infeasibility` answer INFEASIBLE at once where
    they can (see :func:`hierplan_opt.registry.run`). A plan that fails the validator is
    never passed on: the result becomes ERROR with the violations in
    ``stats["violations"]``.

    Example
    -------
    >>> from hierplan_opt.core.graph import Graph
    >>> g = Graph.grid(5, 2, obstacles=[(0, 1), (1, 1), (3, 1), (4, 1)])
    >>> inst = Instance.mapf(g, [(0, 0), (1, 0)], [(4, 0), (3, 0)])
    >>> r = solve(inst, "cbs", time_limit=10)
    >>> r.status, r.cost
    (<Status.OPTIMAL: 'OPTIMAL'>, 8)
    """
    t0 = time.perf_counter()
    if instance.meta.get("edge_conflicts"):  # an annotated roadmap's extra conflicts
        from hierplan_opt.search.libmrp import ANNOTATED_SOLVERS

        if solver not in ANNOTATED_SOLVERS:
            raise OptionError(
                f"solver {solver!r} knows vertex and swap conflicts only; this annotated "
                f"roadmap has {len(instance.meta['edge_conflicts'])} more conflicting move "
                f"pairs (use {' or '.join(ANNOTATED_SOLVERS)})"
            )
    if instance.meta.get("free_agents"):  # task-free robots: the solve picks their ends
        from hierplan_opt.search.libmrp import solved_free_robots

        result, instance = solved_free_robots(
            solver, instance, time_limit=time_limit, seed=seed, objective=objective, **options
        )
    else:
        result = registry.run(
            solver, instance, time_limit=time_limit, seed=seed, objective=objective, **options
        )
    result = replace(result, runtime=time.perf_counter() - t0)
    if result.plan is None:
        return result
    violations: list[Any] = validate(instance, result.plan)
    if not violations and instance.meta.get("edge_conflicts"):
        from hierplan_opt.search.libmrp import annotated_violations

        violations = annotated_violations(instance, result.plan)
    if violations:
        log.error("solver %s returned an invalid plan: %s", solver, violations[0])
        stats = dict(result.stats)
        stats["violations"] = [str(v) for v in violations]
        stats["error"] = f"invalid plan: {violations[0]}"
        return replace(result, status=Status.ERROR, plan=None, cost=None, stats=stats)
    cost = result.plan.cost(result.objective)
    if result.cost is not None and result.cost != cost:
        log.error("solver %s reported cost %s but its plan costs %s", solver, result.cost, cost)
        stats = dict(result.stats)
        stats["error"] = f"reported cost {result.cost} but the plan costs {cost}"
        return replace(result, status=Status.ERROR, stats=stats)
    return replace(result, cost=cost)
