"""PIBT: priority inheritance with backtracking (Okumura, Machida, Défago, Tamura, AIJ 2022).

PIBT plans one timestep for all agents at once. Agents choose in priority order; each
takes the free neighbour (or its own vertex) closest to its goal. An agent that wants a
vertex occupied by an undecided agent lends it its priority: the occupant must move
away first, recursively; if it cannot, the requester backtracks to its next choice.
A configuration produced this way is always free of vertex and swap conflicts.

Two refinements from the LaCAM papers (Okumura, IJCAI 2023):

* **Dynamic priorities**: an agent's priority grows by one each timestep it is not at
  its goal and falls back to its fractional tie-breaker when it arrives, so agents
  that have waited long get precedence (the "elapsed time" rule of the AIJ paper).
* **Swap**: in a corridor two agents heading at each other deadlock plain PIBT. When
  the agent ahead cannot give way before the corridor ends and a junction lies behind
  the requester, the requester *retreats* and pulls the other agent along until they
  reach the junction and pass each other.

:class:`~hierplan_opt.search.pibt_engine.Space` (the graph in compact vertex ids with
every agent's distance table) and :class:`~hierplan_opt.search.pibt_engine.PIBT` (the
one-step configuration generator) live in :mod:`hierplan_opt.search.pibt_engine`,
shared with LaCAM (:mod:`hierplan_opt.search.lacam`). :func:`solve` runs PIBT alone,
step after step, until every agent is at its goal; it is fast but incomplete, and says
so: a run that does not reach the goals ends with status TIME_LIMIT and no plan.
"""

from __future__ import annotations

import logging

from hierplan_opt.core.errors import OptionError
from hierplan_opt.core.instance import Instance
from hierplan_opt.core.options import Option
from hierplan_opt.core.result import Result, Status
from hierplan_opt.core.timer import Deadline
from hierplan_opt.registry import solver
from hierplan_opt.search.pibt_engine import (
    NIL,
    PIBT,
    SWAP_OPTION,
    initial_priorities,
    next_priorities,
    prepare,
    priority_order,
)

log = logging.getLogger(__name__)


@solver(
    "pibt",
    Option(
        "max_steps",
        "int",
        "give up after this many steps (none: 10 |V| + 1000)",
        low=1,
        optional=True,
    ),
    SWAP_OPTION,
)
def solve(
    instance: Instance,
    *,
    time_limit: float | None = None,
    seed: int = 0,
    objective: str = "soc",
    max_steps: int | None = None,
    swap: bool = True,
) -> Result:
    """Run PIBT until every agent is at its goal (fast, incomplete).

    Parameters
    ----------
    max_steps
        Give up after this many timesteps (default: ``10 * |V| + 1000``).
    swap
        Use the swap extension (undirected graphs); ``False`` is vanilla PIBT.

    Returns
    -------
    Result
        FEASIBLE with the plan (OPTIMAL when its cost meets the sum of distances),
        TIME_LIMIT without a plan when the time or step limit ran out first (PIBT may
        livelock; use ``lacam``, which is complete), INFEASIBLE for a shared or
        unreachable goal. ``lower_bound`` is the sum of distances.

    Example
    -------
    >>> from hierplan_opt.core.graph import Graph
    >>> g = Graph.grid(5, 2, obstacles=[(0, 1), (1, 1), (3, 1), (4, 1)])
    >>> inst = Instance.mapf(g, [(0, 0), (1, 0)], [(4, 0), (3, 0)])
    >>> r = solve(inst, time_limit=5)
    >>> r.status.value, r.plan.sum_of_costs
    ('FEASIBLE', 8)
    """
    if objective != "soc":
        raise OptionError(f"pibt does not optimise {objective!r}")
    deadline = Deadline(time_limit)
    prepared = prepare(instance, deadline, seed)
    if isinstance(prepared, Result):
        return prepared
    space, lb = prepared
    limit = max_steps if max_steps is not None else 10 * space.nv + 1000
    pibt = PIBT(space, seed, swap=swap)
    goals = space.goals
    goal_t = tuple(goals)
    q: list[int] = list(space.starts)
    configs: list[list[int]] = [q]
    prio = initial_priorities(space)
    steps = 0
    reason = ""
    stopped_by = ""  # the limit that ended the run: "max_steps" or "time_limit"
    while tuple(q) != goal_t:
        if steps >= limit:
            reason, stopped_by = f"step limit {limit} reached", "max_steps"
            break
        if deadline.expired():
            reason, stopped_by = "time limit reached", "time_limit"
            break
        q_to = [NIL] * space.n_agents
        if not pibt.step(q, q_to, priority_order(prio)):  # pragma: no cover - PIBT invariant
            reason = "PIBT found no configuration"
            break
        q = q_to
        configs.append(q)
        prio = next_priorities(prio, q, goals)
        steps += 1
    stats: dict[str, object] = {"steps": steps}
    if reason:
        log.info("pibt: %s without reaching the goals", reason)
        stats["reason"] = reason
        if stopped_by:
            stats["stopped_by"] = stopped_by
        return Result(Status.TIME_LIMIT, None, lower_bound=lb, stats=stats)
    plan = space.plan(configs)
    cost = plan.sum_of_costs
    status = Status.OPTIMAL if cost == lb else Status.FEASIBLE
    return Result(status, plan, cost=cost, lower_bound=lb, stats=stats)
