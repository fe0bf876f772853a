"""The front door: ``solve(instance, solver=..., **options) -> Result``."""

from __future__ import annotations

import logging
import time
from dataclasses import replace
from typing import Any

from hierplan_opt import registry
from hierplan_opt.core.errors import OptionError
from hierplan_opt.core.instance import Instance
from hierplan_opt.core.result import Result
from hierplan_opt.registry import DEFAULT_TIME_LIMIT
from hierplan_opt.search import libmrp

log = logging.getLogger(__name__)

__all__ = ["DEFAULT_TIME_LIMIT", "solve"]


def solve(
    instance: Instance,
    solver: str = "cbs",
    *,
    time_limit: float | None = DEFAULT_TIME_LIMIT,
    seed: int = 0,
    cost: str | None = None,
    objective: str | None = None,
    **options: Any,
) -> Result:
    """Solve ``instance`` with a registered solver and validate what it returns.

    ``time_limit`` is a wall-clock budget in seconds (default 60, like the CLI; None
    means no limit): on expiry the result is TIME_LIMIT with the best proven lower bound
    (or FEASIBLE with the best plan found). ``cost`` is what the plan minimises, in
    steps: ``"soc"`` (sum of costs) or ``"makespan"``; it defaults to ``"soc"`` for MAPF
    and ``"makespan"`` for TAPF (and for solvers that only optimise makespan).
    ``objective=`` is its old name, deprecated (a :class:`DeprecationWarning`): an
    objective is a schedule's, in seconds (:func:`hierplan_opt.postprocess`). Every
    option is checked before any work (unknown ones are refused), and the cheap checks
    of :func:`hierplan_opt.registry.cheap_infeasibility` answer INFEASIBLE at once where
    they can (see :func:`hierplan_opt.registry.run`). A plan that fails the validator is
    never passed on (:func:`hierplan_opt.registry.checked`, the one check of a plan): the
    result becomes ERROR with the violations in ``stats["violations"]``. ``runtime`` is
    the solve's wall time without that check.

    Solvers and their options (``**options``; ``hierplan info --solvers`` lists the same,
    ``hierplan solve --set name=value`` sets them). Optimal: OPTIMAL is a proven optimum;
    bounded: cost <= w * optimum; heuristic: no bound.

    ``cbm`` (MAPF/TAPF, optimal): Conflict-based min-cost flow: optimal makespan for
        teams (TAPF).
        - tie_break: auto|cost|avoid|none (default auto) -- how a team avoids the
          others' paths
        - cost_arcs: integer >= 0 (default 60000) -- largest network for tie_break=auto
          to use cost
        - repair_rounds: integer >= 0 (default 0) -- rounds of local re-planning per
          node (0: off)
    ``cbs`` (MAPF, optimal): Conflict-based search with MDD prioritisation, bypass, WDG
        heuristic, disjoint splitting and symmetry reasoning.
        - prioritize_conflicts: true/false (default true) -- split cardinal, then
          semi-cardinal conflicts first
        - bypass: true/false (default true) -- adopt a child's paths when it keeps the
          cost, fewer conflicts
        - heuristic: wdg|dg|cg|none (default wdg) -- admissible high-level heuristic
        - disjoint_splitting: true/false (default false) -- positive/negative constraint
          children
        - symmetry: true/false (default true) -- target, corridor and rectangle
          reasoning
        - rectangle: true/false (default true) -- rectangle reasoning (4-connected 2D
          grids)
        - generalized_rectangle: true/false (default false) -- also rectangles the agents
          enter anywhere, proved by a joint search (needs rectangle)
        - corridor_target: true/false (default false) -- corridor-target reasoning
          (goals inside corridors)
        - node_limit: integer >= 1 or none (default none) -- stop after this many
          high-level expansions
        - highways: instance|crisscross|corridors|learned|flow or none (default none) --
          prefer these directed edges: the instance's own, or generated
        - w_hwy: number >= 1 and < 1e+09 (default 2.0) -- highway factor: off-highway
          edges cost this much more
        - hwy_mode: heuristic|cost (default heuristic) -- inflate the heuristic or the
          edge costs off the highways
    ``cpsat`` (MAPF/TAPF, optimal): Time-expanded CP-SAT model (OR-Tools).
        - workers: integer >= 1 (default 2) -- CP-SAT's parallel search workers
        - hint: solver name or none (default none) -- solver whose plan seeds the search
          (none: no hint)
        - max_horizon: integer >= 1 or none (default none) -- largest horizon tried
          (none: a safe cap)
    ``ecbs`` (MAPF, bounded): Enhanced CBS: focal search on both levels, cost <= w *
        optimal.
        - w: number >= 1 and < 1e+09 (default 1.2) -- suboptimality bound: cost <= w *
          optimum
        - polish: true/false (default true) -- shorten paths one by one after the search
        - lacam: fallback|start|off (default fallback) -- LaCAM's plan when the limit
          runs out (fallback), also as an early stop (start), or off
        - highways: instance|crisscross|corridors|learned|flow or none (default none) --
          prefer these directed edges: the instance's own, or generated
        - w_hwy: number >= 1 and < 1e+09 (default 2.0) -- highway factor: off-highway
          edges cost this much more
        - hwy_mode: heuristic|cost (default heuristic) -- inflate the heuristic or the
          edge costs off the highways
        - bypass: true/false (default false) -- adopt a child's path when it lowers the
          conflicts in the bound
    ``eecbs`` (MAPF, bounded): Explicit-estimation CBS: cost <= w * optimal.
        - w: number >= 1 and < 1e+09 (default 1.2) -- suboptimality bound: cost <= w *
          optimum
        - bypass: true/false (default true) -- adopt a child's path when it lowers the
          conflicts in the bound
        - polish: true/false (default true) -- shorten paths one by one after the search
        - lacam: fallback|start|off (default fallback) -- LaCAM's plan when the limit
          runs out (fallback), also as an early stop (start), or off
        - highways: instance|crisscross|corridors|learned|flow or none (default none) --
          prefer these directed edges: the instance's own, or generated
        - w_hwy: number >= 1 and < 1e+09 (default 2.0) -- highway factor: off-highway
          edges cost this much more
        - hwy_mode: heuristic|cost (default heuristic) -- inflate the heuristic or the
          edge costs off the highways
    ``flow`` (TAPF, optimal): Max-flow on the time-expanded network: anonymous MAPF (one
        team).
        - search: doubling|linear (default doubling) -- horizon search
        - min_cost: true/false or none (default none) -- fewest moves at the optimal
          horizon (none: by size)
        - min_cost_arcs: integer >= 0 (default 300000) -- largest network for
          min_cost=none to minimise moves
    ``hungarian`` (TAPF, heuristic): Hungarian target assignment by distance, then a
        MAPF solver.
        - mapf_solver: solver name (default cbs) -- MAPF solver for the assigned goals
        - mapf_options: options of the mapf_solver solver or none (default none) --
          options of that solver
    ``lacam`` (MAPF, heuristic): LaCAM*: complete, anytime (search + LNS refinement),
        optimal given time.
        - anytime: number >= 0 or none (default none) -- seconds of improvement after
          the first plan (none: until the time limit, so lacam runs the whole
          --time-limit unless it proves the optimum; 0: return the first plan, --set
          anytime=0)
        - refine: true/false (default true) -- interleave LNS refinement with the search
        - guide: true/false (default true) -- guide paths (space utilisation) in the
          anytime phase
        - swap: true/false (default true) -- PIBT's swap technique (undirected graphs)
        - mc: integer >= 1 (default 1) -- PIBT runs per successor in the anytime search
          (Monte-Carlo)
    ``mip`` (MAPF/TAPF, optimal): Time-expanded network MIP (Pyomo + HiGHS).
        - lp_check: true/false (default true) -- reject a horizon when its LP relaxation
          is infeasible
        - max_horizon: integer >= 1 or none (default none) -- largest horizon tried
          (none: a safe cap)
    ``pibt`` (MAPF, heuristic): PIBT: one-step priority inheritance with backtracking
        (fast, incomplete).
        - max_steps: integer >= 1 or none (default none) -- give up after this many
          steps (none: 10 |V| + 1000)
        - swap: true/false (default true) -- PIBT's swap technique (undirected graphs)

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
    annotated = bool(instance.meta.get("edge_conflicts"))  # a roadmap's extra conflicts
    if annotated and solver not in libmrp.ANNOTATED_SOLVERS:
        raise OptionError(
            f"solver {solver!r} knows vertex and swap conflicts only; this annotated "
            f"roadmap has {len(instance.meta['edge_conflicts'])} more conflicting move "
            f"pairs (use {' or '.join(libmrp.ANNOTATED_SOLVERS)})"
        )
    kind = registry.cost_keyword(cost, objective)  # (solvers call it "objective")
    common: dict[str, Any] = {"time_limit": time_limit, "seed": seed, "objective": kind}
    if instance.meta.get("free_agents"):  # task-free robots: the solve picks their ends
        result, instance = libmrp.solved_free_robots(solver, instance, **common, **options)
    else:
        result = registry.run(solver, instance, **common, **options)
    result = replace(result, runtime=time.perf_counter() - t0)
    return registry.checked(instance, result, libmrp.annotated_violations if annotated else None)
