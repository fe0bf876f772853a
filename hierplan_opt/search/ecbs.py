"""ECBS(w): bounded-suboptimal conflict-based search (Barer et al., SoCS 2014).

Both levels are focal searches with the same suboptimality factor ``w``:

* low level (:func:`hierplan_opt.search.focal.focal_path`): each agent's path costs at
  most ``w * lb_i``, where ``lb_i`` is the low-level ``f_min`` when the path was found (a
  lower bound on the agent's optimal cost under its constraints), and FOCAL prefers
  states with fewer conflicts with the other agents' paths;
* high level (:class:`_ECBS`): OPEN holds constraint-tree nodes ordered by ``LB(N) =
  sum_i lb_i``; FOCAL = {N in OPEN : cost(N) <= w * LB_min} ordered by the number of
  conflicts.

A conflict-free node taken from FOCAL costs at most ``w * LB_min <= w * optimal``.
The search reports ``lower_bound = LB_min`` so ``cost / lower_bound`` is the proven
suboptimality.

The conflict split is a target conflict (an agent on another's goal after that one
has arrived for good, or as it arrives) when there is one, else the earliest. When the
pair was split on before in the branch, each child replans its agent with conflicts
with the other one weighted heavily in the low level's FOCAL (``focal_path(...,
partner=)``), so the new path avoids that agent rather than meeting it one step later
(the ping-pong of two agents head-on in an aisle); the order of FOCAL is free, so the
bound is untouched. With
``polish=True`` the solution is finally improved agent by agent (shortest path around
the others, never longer), which keeps the plan valid and the bound.

EECBS (:mod:`hierplan_opt.search.eecbs`) is a subclass: explicit estimation search at
the high level, and bypassing. See ``docs/ecbs.md``.

Anytime (option ``lacam``): with a time limit, LaCAM (:mod:`hierplan_opt.search.lacam`)
computes a plan in at most ``LACAM_SHARE`` of it, once the search has run
``FALLBACK_AFTER_S`` seconds (or ``FALLBACK_AFTER_SHARE`` of a shorter limit), so a
search that ends sooner never pays for it; when the search's limit runs out, that plan
is returned (FEASIBLE, with the search's own lower bound; its cost need not be within
``w``, and then ``stats["bound_met"]`` is False: :attr:`Result.bound_met
<hierplan_opt.core.result.Result.bound_met>`, the summary line and the plan file say
so), so a caller gets a plan whenever one was found. ``lacam="start"``
also stops the search as soon as ``w * LB_min`` covers the LaCAM plan's cost and
returns the cheaper of the two plans; ``"off"`` runs the plain search.
"""

from __future__ import annotations

from hierplan_opt.core.highways import HIGHWAY_OPTIONS
from hierplan_opt.core.instance import Instance
from hierplan_opt.core.result import Result
from hierplan_opt.registry import solver
from hierplan_opt.search.ecbs_engine import (
    _ECBS,
    BYPASS_OPTION,
    LACAM_OPTION,
    POLISH_OPTION,
    W_OPTION,
    run_search,
    run_with_highways,
)


@solver("ecbs", W_OPTION, POLISH_OPTION, LACAM_OPTION, *HIGHWAY_OPTIONS, BYPASS_OPTION)
def solve(
    instance: Instance,
    *,
    time_limit: float | None = None,
    seed: int = 0,
    objective: str = "soc",
    w: float = 1.2,
    polish: bool = True,
    lacam: str = "fallback",
    highways: str | None = None,
    w_hwy: float = 2.0,
    hwy_mode: str = "heuristic",
    bypass: bool = False,
) -> Result:
    """ECBS(w): a plan whose sum of costs is at most ``w`` times the optimum.

    Parameters
    ----------
    w
        Suboptimality factor (``>= 1``) used by both the low and the high level.
    polish
        After the search, give each agent in turn a shortest path around the others'
        paths when that is shorter (keeps the plan valid and the bound; typically
        2-4 % lower cost). ``False`` returns the plain ECBS solution.
    lacam
        ``"fallback"`` (default): with a time limit, LaCAM's plan (found in at most a
        quarter of it) is returned when the search runs out of time; ``"start"``: also
        without a time limit, and the search stops as soon as its bound covers that
        plan; ``"off"``: no LaCAM.
    highways, w_hwy, hwy_mode
        ECBS(w)+HWY(w_hwy) (:mod:`hierplan_opt.search.highways`): prefer these directed
        edges; the bound becomes ``w * w_hwy`` (LaCAM is not used then).
    bypass
        Adopt a child's path in its parent when that lowers the number of conflicts
        within the bound (as EECBS does by default; CBS with highways runs this search
        with ``w = 1`` and its own ``bypass``).

    Returns
    -------
    Result
        FEASIBLE (OPTIMAL when the cost meets the lower bound) with ``lower_bound`` the
        smallest LB in OPEN; when the limit runs out, FEASIBLE with LaCAM's plan if it
        found one (``stats["plan_from"] == "lacam"``; its cost need not be within ``w``:
        ``Result.bound_met`` is False when it is not shown to be), else
        TIME_LIMIT with the lower bound; INFEASIBLE when proven.

    Example
    -------
    >>> from hierplan_opt.core.graph import Graph
    >>> g = Graph.grid(5, 2, obstacles=[(0, 1), (1, 1), (3, 1), (4, 1)])
    >>> inst = Instance.mapf(g, [(0, 0), (1, 0)], [(4, 0), (3, 0)])
    >>> r = solve(inst, w=1.5)
    >>> r.cost <= 1.5 * 8, r.cost / r.lower_bound <= 1.5
    (True, True)
    """
    del objective  # the sum of costs only; the seed is LaCAM's
    if highways is not None:
        return run_with_highways(
            _ECBS, instance, time_limit, highways=highways, w_hwy=w_hwy, hwy_mode=hwy_mode,
            w=w, polish=polish, bypass=bypass,
        )  # fmt: skip
    return run_search(
        _ECBS, instance, time_limit, seed, w=w, polish=polish, bypass=bypass, lacam=lacam
    )
