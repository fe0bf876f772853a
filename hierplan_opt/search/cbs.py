"""Conflict-based search (CBS) with the accelerations of CBSH2-RTC, optimal for SOC or makespan.

High level: best-first search over a constraint tree (CT). Each CT node holds one
path per agent, each optimal under that agent's constraints; a node without
conflicts is a solution. A conflict is resolved by branching into children that each
forbid one way of having it.

Options (all on by default except ``disjoint_splitting``, each switchable; none changes
the optimal cost):

* ``prioritize_conflicts``: classify conflicts with MDDs as cardinal (both children
  cost more), semi-cardinal or non-cardinal, and split on the best class first
  (Boyarski et al. 2015);
* ``bypass``: when a child keeps the cost and has fewer conflicts, adopt its paths
  instead of branching (Boyarski et al. 2015);
* ``heuristic``: admissible high-level heuristic ``"wdg"`` (default), ``"dg"``,
  ``"cg"`` or ``"none"`` (Felner et al. 2018; Li et al. 2019), computed lazily when a
  node is selected;
* ``disjoint_splitting`` (off by default, as in CBSH2-RTC; see docs/cbs.md): one child
  gets a positive constraint (the agent *must* be there), the other the negative one,
  so children share no solution (Li et al. 2019);
* ``symmetry``: target reasoning -- when an agent crosses another agent's goal after
  that agent has finished, branch on the finished agent's arrival time (length
  constraints) instead of on a single vertex-time (Li et al. 2021); generalised
  corridor reasoning -- two agents meeting head-on in a chain of degree-2 vertices, or
  over one edge that all their optimal paths use (a pseudo-corridor), get range
  constraints at the corridor's exits with bounds from travel times under the node's
  constraints; corridor-target reasoning -- a goal inside such a chain that another
  agent passes: a length constraint on the goal's agent and a range constraint on the
  other (tried before target reasoning); such conflicts are split first within their
  class (Li et al. 2021);
  and, with ``rectangle`` (also on by default, 4-connected 2D grids only), rectangle
  reasoning -- a vertex conflict of two agents crossing a rectangle (of any class, as
  CBSH2-RTC does it for semi- and non-cardinal ones) is split with two barrier
  constraints (Li et al., AAAI 2019); with
  ``generalized_rectangle`` (off by default, needs ``rectangle``) also rectangles the
  agents enter anywhere (through a room's doors, say), drawn on the current paths and
  kept only when a joint search proves the barrier pair sound
  (:func:`.symmetry.generalized_rectangle_split`; after the generalised rectangle
  reasoning of Li et al., AIJ 2021), used where its class (by its barriers, as
  CBSH2-RTC does: cardinal when each child leaves its agent no path of the current
  cost) is not worse than the conflict's own.

``objective="makespan"`` iterates a makespan bound ``M`` upwards from the instance's
lower bound; for each ``M`` the same CBS runs with every path bounded by ``M`` until it
finds a conflict-free node (then ``M`` is optimal) or exhausts the (finite) tree.
"""

from __future__ import annotations

import logging
from typing import Any

from hierplan_opt import registry
from hierplan_opt.core.collector import paused_gc
from hierplan_opt.core.errors import OptionError
from hierplan_opt.core.highways import HIGHWAY_OPTIONS
from hierplan_opt.core.highways_learned import check_spec
from hierplan_opt.core.instance import Instance
from hierplan_opt.core.options import Option
from hierplan_opt.core.plan import Plan
from hierplan_opt.core.result import Result, Status
from hierplan_opt.core.timer import Deadline
from hierplan_opt.registry import solver
from hierplan_opt.search.cbs_engine import _CBS, HEURISTICS
from hierplan_opt.search.constraints import NO_BOUND, AgentConstraints

log = logging.getLogger(__name__)


@solver(
    "cbs",
    Option("prioritize_conflicts", "bool", "split cardinal, then semi-cardinal conflicts first"),
    Option("bypass", "bool", "adopt a child's paths when it keeps the cost, fewer conflicts"),
    Option("heuristic", "choice", "admissible high-level heuristic", choices=HEURISTICS),
    Option("disjoint_splitting", "bool", "positive/negative constraint children"),
    Option("symmetry", "bool", "target, corridor and rectangle reasoning"),
    Option("rectangle", "bool", "rectangle reasoning (4-connected 2D grids)"),
    Option(
        "generalized_rectangle",
        "bool",
        "also rectangles the agents enter anywhere, proved by a joint search (needs rectangle)",
    ),
    Option("corridor_target", "bool", "corridor-target reasoning (goals inside corridors)"),
    Option("node_limit", "int", "stop after this many high-level expansions", low=1, optional=True),
    *HIGHWAY_OPTIONS,
)
def solve(
    instance: Instance,
    *,
    time_limit: float | None = None,
    seed: int = 0,
    objective: str = "soc",
    prioritize_conflicts: bool = True,
    bypass: bool = True,
    heuristic: str = "wdg",
    disjoint_splitting: bool = False,
    symmetry: bool = True,
    rectangle: bool = True,
    generalized_rectangle: bool = False,
    corridor_target: bool = False,
    node_limit: int | None = None,
    highways: str | None = None,
    w_hwy: float = 2.0,
    hwy_mode: str = "heuristic",
) -> Result:
    """Optimal MAPF by conflict-based search (sum of costs or makespan).

    Parameters
    ----------
    instance
        A MAPF instance (one goal per agent).
    time_limit
        Seconds; on expiry the result is TIME_LIMIT with the proven lower bound.
    seed
        Unused (the search is deterministic); accepted for the common signature.
    objective
        ``"soc"`` (sum of costs) or ``"makespan"``.
    prioritize_conflicts, bypass, heuristic, disjoint_splitting, symmetry, rectangle
        The accelerations (see the module docstring); ``heuristic`` is one of
        ``"wdg"``, ``"dg"``, ``"cg"``, ``"none"``. ``symmetry=False`` switches off all
        symmetry reasoning (target, corridor, rectangle); ``rectangle=False`` only the
        rectangle part (which also needs ``prioritize_conflicts``).
    generalized_rectangle
        Generalised rectangle reasoning (part of ``rectangle``; see the module docstring).
        Off by default: sound and tested, but on the reference instances it cut few CT
        nodes (room-32-32-4-even-1 k30: 19,482 against 20,027) and no time (median
        CPU about 6 % more there); see ``docs/cbs.md``.
    corridor_target
        Corridor-target reasoning (a goal inside a corridor; part of ``symmetry``). Off
        by default: sound and tested, but on the MovingAI reference instances it changed
        no high-level node count and cost about 18 % CPU on room-32-32-4-even-1 k30
        (the travel searches of its bounds; see ``docs/cbs.md``).
    node_limit
        Stop after this many high-level expansions (TIME_LIMIT with the lower bound).
    highways, w_hwy, hwy_mode
        CBS+HWY(w_hwy) instead (:mod:`hierplan_opt.search.highways`, sum of costs only):
        prefer these directed edges, cost at most ``w_hwy`` times the optimum.

    Example
    -------
    >>> from hierplan_opt.core.graph import Graph
    >>> g = Graph.grid(5, 2, obstacles=[(0, 1), (1, 1), (3, 1), (4, 1)])
    >>> inst = Instance.mapf(g, [(0, 0), (1, 0)], [(4, 0), (3, 0)])
    >>> r = solve(inst)
    >>> r.status, r.cost
    (<Status.OPTIMAL: 'OPTIMAL'>, 8)
    """
    if highways is not None:
        if objective != "soc":
            raise OptionError("cbs with highways optimises the sum of costs only (objective soc)")
        check_spec(instance, highways, "cbs")
        if node_limit is not None:
            raise OptionError(
                "cbs with highways runs ECBS(1)+HWY, which has no node_limit; drop one of them"
            )
        # CBS+HWY(w_hwy) is ECBS(1)+HWY(w_hwy) (search.highways), reached through the
        # registry: solvers do not import each other.
        ecbs = registry.get("ecbs").load()
        return ecbs.fn(
            instance, time_limit=time_limit, w=1.0, polish=False, lacam="off",
            highways=highways, w_hwy=w_hwy, hwy_mode=hwy_mode, bypass=bypass,
        )  # fmt: skip
    opts = dict(
        prioritize=prioritize_conflicts,
        bypass=bypass,
        disjoint=disjoint_splitting,
        symmetry=symmetry,
        rectangle=rectangle,
        gr=generalized_rectangle,
        corridor_target=corridor_target,
        node_limit=node_limit,
    )
    # Millions of objects, no cycles: the cyclic collector finds nothing (core.collector).
    with paused_gc():
        return _search(instance, Deadline(time_limit), objective, heuristic, opts)


def _search(
    instance: Instance, deadline: Deadline, objective: str, heuristic: str, opts: dict[str, Any]
) -> Result:
    """The body of :func:`solve` without highways (options already mapped to ``_CBS``'s)."""
    g = instance.graph
    starts = instance.starts
    goals = instance.goals
    g.fill_distances(goals)  # the lists the search reads (no arrays made)
    if objective == "soc":
        roots = [AgentConstraints.root(g.n, x) for x in goals]
        cbs = _CBS(g, starts, goals, roots, deadline, heuristic=heuristic, **opts)  # type: ignore[arg-type]
        node = cbs.search()
        stats: dict[str, Any] = dict(cbs.stats)
        if node is None:
            if cbs.exhausted:  # pragma: no cover - SOC CT never empties on a solvable tree
                return Result(Status.INFEASIBLE, None, stats=stats)
            lb = max(cbs.lower_bound, instance.soc_lower_bound())
            stats.update(_limit_stats(cbs, deadline))
            return Result(Status.TIME_LIMIT, None, lower_bound=lb, stats=stats)
        plan = Plan.from_paths(node.paths)
        return Result(Status.OPTIMAL, plan, cost=plan.sum_of_costs, lower_bound=node.g, stats=stats)

    # Makespan: iterate the bound M upwards; CBS bounded by M (greedy order) per M.
    m = instance.makespan_lower_bound()
    total: dict[str, Any] = {}
    while True:
        roots = [AgentConstraints.root(g.n, x, max_finish=m) for x in goals]
        cbs = _CBS(g, starts, goals, roots, deadline, heuristic="none", greedy=True, **opts)  # type: ignore[arg-type]
        node = cbs.search()
        for key, val in cbs.stats.items():
            total[key] = total.get(key, 0) + val
        total["makespan_bound"] = m
        if node is not None:
            plan = Plan.from_paths(node.paths)
            return Result(Status.OPTIMAL, plan, cost=plan.makespan, lower_bound=m, stats=total)
        if not cbs.exhausted:
            total.update(_limit_stats(cbs, deadline))
            return Result(Status.TIME_LIMIT, None, lower_bound=m, stats=total)
        log.info("CBS makespan: no plan with makespan %d", m)
        m += 1
        if m > NO_BOUND:  # pragma: no cover
            break
    return Result(Status.TIME_LIMIT, None, lower_bound=m, stats=total)  # pragma: no cover


def _limit_stats(cbs: _CBS, deadline: Deadline) -> dict[str, str]:
    """``stopped_by`` (and for memory the reason) of a search that a limit stopped:
    ``"node_limit"`` (option ``node_limit``), ``"memory_limit"`` or ``"time_limit"``."""
    if cbs.stopped_by is not None:
        return {"stopped_by": cbs.stopped_by}
    return deadline.limit_stats("CBS")
