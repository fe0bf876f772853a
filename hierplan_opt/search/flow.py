"""Anonymous MAPF (TAPF with one team) by max-flow on the time-expanded network.

Yu & LaValle (2013): a team of K exchangeable robots can reach its K targets within T
timesteps iff the time-expanded network of horizon T (vertex capacities 1, swap
gadgets, see :mod:`hierplan_opt.search.flow_network`) carries a flow of value K. Feasibility
is monotone in T (robots can wait), so the smallest such T, searched upward from the
makespan lower bound, is the optimal makespan. At that horizon a min-cost flow with
unit cost per move then picks, among all makespan-optimal plans, one with the fewest
moves ("total travel"); the flow also fixes which robot takes which target.
"""

from __future__ import annotations

import logging
import time

from hierplan_opt.core.instance import Instance
from hierplan_opt.core.options import Option
from hierplan_opt.core.plan import Plan
from hierplan_opt.core.result import Result, Status
from hierplan_opt.core.timer import Deadline
from hierplan_opt.registry import solver
from hierplan_opt.search.assignment import team_makespan_bound
from hierplan_opt.search.flow_network import TeamDistances, TeamFlowNetwork, smallest_horizon

log = logging.getLogger(__name__)


@solver(
    "flow",
    Option("search", "choice", "horizon search", choices=("doubling", "linear")),
    Option(
        "min_cost", "bool", "fewest moves at the optimal horizon (none: by size)", optional=True
    ),
    Option("min_cost_arcs", "int", "largest network for min_cost=none to minimise moves", low=0),
)
def solve(
    instance: Instance,
    *,
    time_limit: float | None = None,
    seed: int = 0,
    objective: str = "makespan",
    search: str = "doubling",
    min_cost: bool | None = None,
    min_cost_arcs: int = 300_000,
) -> Result:
    """Optimal makespan for anonymous MAPF (one team), then fewest moves at it.

    Parameters
    ----------
    instance
        A TAPF instance with exactly one team.
    time_limit
        Wall-clock seconds; on expiry the result is TIME_LIMIT with the proven bound.
    seed
        Unused (the method is deterministic); accepted for the common signature.
    objective
        Only ``"makespan"``.
    search
        ``"doubling"`` (gallop from the lower bound, then bisect) or ``"linear"``.
    min_cost
        Minimise the number of moves at the optimal horizon (else keep the max-flow
        paths). ``None`` (default) does so when the network has at most
        ``min_cost_arcs`` arcs: OR-Tools' min-cost flow takes seconds per 100k arcs
        on these networks, while its max flow takes milliseconds.
    min_cost_arcs
        Size limit for ``min_cost=None``.

    Example
    -------
    >>> from hierplan_opt.core.graph import Graph
    >>> g = Graph.grid(4, 1)
    >>> inst = Instance.tapf(g, [([(0, 0), (1, 0)], [(2, 0), (3, 0)])])
    >>> r = solve(inst)
    >>> r.status.value, r.cost, r.stats["total_moves"]
    ('OPTIMAL', 2, 4)
    """
    del seed
    deadline = Deadline(time_limit)
    t0 = time.perf_counter()
    g = instance.graph
    team = instance.teams[0]
    starts = [instance.agents[i].start for i in team.agents]
    targets = list(team.targets)
    k = len(starts)
    # The bottleneck assignment value bounds the makespan at least as well as the
    # nearest-target bound and is usually much closer to the optimum.
    lb = max(instance.makespan_lower_bound(), team_makespan_bound(g, starts, targets))
    dists = TeamDistances(g, starts, targets)
    stats: dict = {"horizon_checks": 0, "network_nodes": 0, "network_arcs": 0}
    last: dict[int, TeamFlowNetwork] = {}

    def feasible(t: int) -> bool:
        net = TeamFlowNetwork(g, starts, targets, t, distances=dists)
        stats["horizon_checks"] += 1
        stats["network_nodes"] = max(stats["network_nodes"], net.num_nodes)
        stats["network_arcs"] = max(stats["network_arcs"], net.num_arcs)
        value = net.max_flow()
        log.debug("flow: horizon %d carries %d of %d robots", t, value, k)
        if value == k:
            last.clear()
            last[t] = net
        return value == k

    # Directed graphs can be infeasible beyond what quick_infeasibility detects; on
    # undirected graphs a one-team instance that passes it always has a plan.
    upper = lb + g.num_vertices * k if g.directed else None
    horizon, bound = smallest_horizon(feasible, lb, deadline=deadline, strategy=search, upper=upper)
    stats["max_flow_time"] = time.perf_counter() - t0
    if horizon is None:
        if deadline.expired():
            stats["stopped_by"] = "time_limit"
            return Result(
                Status.TIME_LIMIT, None, lower_bound=bound, objective=objective, stats=stats
            )
        stats["error"] = f"no plan with makespan <= {upper} on this directed graph"
        return Result(Status.ERROR, None, lower_bound=bound, objective=objective, stats=stats)
    net = last.get(horizon) or TeamFlowNetwork(g, starts, targets, horizon, distances=dists)
    t1 = time.perf_counter()
    if min_cost is None:
        min_cost = net.num_arcs <= min_cost_arcs
    # OR-Tools' min-cost flow cannot be interrupted: skip it when it would likely
    # overrun the budget (measured here: roughly 20-70 microseconds per arc).
    if min_cost and deadline.remaining() < 5e-5 * net.num_arcs:
        min_cost = False
        stats["min_cost_skipped"] = "time limit"
    res = net.min_cost_flow(k, net.move_cost) if min_cost and not deadline.expired() else None
    # Plain max-flow when min-cost is off or the time ran out before it.
    flows = net.solve_max_flow()[1] if res is None else res[1]
    stats["min_cost_time"] = time.perf_counter() - t1
    team_paths = net.extract_paths(flows)
    paths: list[list[int]] = [[] for _ in instance.agents]
    for idx, p in zip(team.agents, team_paths, strict=True):
        paths[idx] = p
    plan = Plan.from_paths(paths)
    stats["total_moves"] = sum(
        sum(1 for a, b in zip(p, p[1:], strict=False) if a != b) for p in plan.paths
    )
    stats["sum_of_costs"] = plan.sum_of_costs
    stats["min_cost"] = res is not None
    stats["assignment"] = {
        instance.agents[i].name: g.plain_location(p[-1])
        for i, p in zip(team.agents, team_paths, strict=True)
    }
    return Result(
        Status.OPTIMAL,
        plan,
        cost=plan.makespan,
        lower_bound=horizon,
        objective=objective,
        stats=stats,
    )
