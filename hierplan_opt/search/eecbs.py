"""EECBS(w): explicit-estimation CBS (Li, Ruml and Koenig, AAAI 2021).

Same low level as ECBS (focal space-time A*, :mod:`hierplan_opt.search.focal`), but
the high level is an explicit estimation search over the constraint tree with three
lists:

* CLEANUP: open nodes by their lower bound ``LB(N)`` (sum of the agents' low-level
  lower bounds);
* OPEN: open nodes by ``f^(N) = cost(N) + h^(N)``, where ``h^`` is learned online: the
  average cost increase per expansion times the number of conflicts, corrected by the
  average error of "conflicts left" as a distance-to-go (``d / (1 - eps_d)``);
* FOCAL: ``{N in OPEN : f^(N) <= w * LB_min}`` ordered by the number of conflicts.

Selection (as in EES): the best FOCAL node if its cost is within ``w * LB_min``, else
the best OPEN node if its cost is, else the best CLEANUP node (which raises
``LB_min``). Every node satisfies ``cost(N) <= w * LB(N)``, so any conflict-free node
selected costs at most ``w * LB_min <= w * optimal``.

Bypassing (on by default): when a child has fewer conflicts than its parent and costs
at most ``w * LB_min``, its path replaces the parent's without adding a constraint.
"""

from __future__ import annotations

from hierplan_opt.core.instance import Instance
from hierplan_opt.core.result import Result
from hierplan_opt.search.ecbs import focal_cbs


def solve(
    instance: Instance,
    *,
    time_limit: float | None = None,
    seed: int = 0,
    objective: str = "soc",
    w: float = 1.2,
    bypass: bool = True,
    polish: bool = True,
) -> Result:
    """EECBS(w): a plan whose sum of costs is at most ``w`` times the optimum.

    Parameters
    ----------
    w
        Suboptimality factor (``>= 1``), used at both levels.
    bypass
        Adopt a child's path in its parent when that lowers the number of conflicts
        within the bound.
    polish
        After the search, give each agent in turn a shortest path around the others'
        paths when that is shorter (keeps validity and the bound).

    Example
    -------
    >>> from hierplan_opt.core.graph import Graph
    >>> g = Graph.grid(5, 2, obstacles=[(0, 1), (1, 1), (3, 1), (4, 1)])
    >>> inst = Instance.mapf(g, [(0, 0), (1, 0)], [(4, 0), (3, 0)])
    >>> r = solve(inst, w=1.2)
    >>> r.cost <= 1.2 * 8, r.cost / r.lower_bound <= 1.2
    (True, True)
    """
    del seed  # deterministic
    return focal_cbs(
        instance,
        time_limit=time_limit,
        objective=objective,
        w=w,
        explicit_estimation=True,
        bypass=bool(bypass),
        solver="eecbs",
        polish=bool(polish),
    )
