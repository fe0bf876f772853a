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

from heapq import heappop, heappush
from typing import Any

from hierplan_opt.core.highways import HIGHWAY_OPTIONS
from hierplan_opt.core.instance import Instance
from hierplan_opt.core.options import Option
from hierplan_opt.core.result import Result
from hierplan_opt.core.timer import Deadline
from hierplan_opt.registry import solver
from hierplan_opt.search.ecbs_engine import (
    _ECBS,
    LACAM_OPTION,
    POLISH_OPTION,
    W_OPTION,
    _Node,
    run_search,
    run_with_highways,
)

#: Cap on the learned one-step error of "conflicts left" as a distance-to-go. The
#: estimate ``d / (1 - eps_d)`` explodes as ``eps_d -> 1`` (resolving one conflict often
#: creates others), which empties FOCAL and degrades EECBS to best-first search on LB;
#: capping keeps the inflation at most 2x. Any estimate keeps the bound.
_MAX_EPS_D = 0.5


class _EECBS(_ECBS):
    """ECBS's constraint tree searched by explicit estimation (OPEN by f^, CLEANUP by LB)."""

    name = "eecbs"

    def __init__(self, instance: Instance, deadline: Deadline, **options: Any) -> None:
        super().__init__(instance, deadline, **options)  # see _ECBS
        self.open_fhat: list[tuple[float, int, _Node]] = []
        # Online error estimates: expansions seen, summed cost increase per expansion,
        # summed error of the number of conflicts as a distance-to-go.
        self.err_n = 0
        self.err_c = 0.0
        self.err_d = 0.0

    def estimate(self, node: _Node) -> float:
        """``f^(N) = cost + eps_c * conflicts / (1 - eps_d)`` from the errors so far."""
        if self.err_n == 0:
            return float(node.cost)
        eps_c = self.err_c / self.err_n
        eps_d = min(self.err_d / self.err_n, _MAX_EPS_D)
        return node.cost + eps_c * len(node.conflicts) / (1.0 - eps_d)

    def focal_key(self, node: _Node) -> float:
        """FOCAL admits ``f^(N) <= w * LB_min``; the node also enters OPEN by ``f^``."""
        node.fhat = self.estimate(node)
        heappush(self.open_fhat, (node.fhat, node.id, node))
        return node.fhat

    def select(self) -> _Node:
        """FOCAL's best if within the bound, else OPEN's best if it is, else CLEANUP's."""
        stats = self.stats
        if self.focal and self.focal[0][3].cost <= self.bound:
            stats["selected_focal"] += 1
            return heappop(self.focal)[3]
        open_fhat = self.open_fhat
        while open_fhat and open_fhat[0][2].closed:
            heappop(open_fhat)
        best_f = open_fhat[0][2] if open_fhat else None
        if best_f is not None and best_f.cost <= self.bound:
            stats["selected_open"] += 1
            return best_f
        stats["selected_cleanup"] += 1
        return self.open_lb[0][2]

    def learn(self, node: _Node, children: list[_Node]) -> None:
        """Update the one-step errors from the best child of an expansion."""
        if not children:
            return
        best = min(children, key=lambda c: (c.cost, len(c.conflicts)))
        self.err_n += 1
        self.err_c += max(0, best.cost - node.cost)
        self.err_d += max(0, len(best.conflicts) - (len(node.conflicts) - 1))


@solver(
    "eecbs",
    W_OPTION,
    Option("bypass", "bool", "adopt a child's path when it lowers the conflicts in the bound"),
    POLISH_OPTION,
    LACAM_OPTION,
    *HIGHWAY_OPTIONS,
)
def solve(
    instance: Instance,
    *,
    time_limit: float | None = None,
    seed: int = 0,
    objective: str = "soc",
    w: float = 1.2,
    bypass: bool = True,
    polish: bool = True,
    lacam: str = "fallback",
    highways: str | None = None,
    w_hwy: float = 2.0,
    hwy_mode: str = "heuristic",
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
    lacam
        LaCAM's plan as a fallback when the limit runs out (``"fallback"``, default),
        also as an early stop once the bound covers it (``"start"``), or ``"off"``;
        see :func:`hierplan_opt.search.ecbs.solve`.
    highways, w_hwy, hwy_mode
        EECBS(w)+HWY(w_hwy) (:mod:`hierplan_opt.search.highways`); bound ``w * w_hwy`` (no LaCAM).

    Example
    -------
    >>> from hierplan_opt.core.graph import Graph
    >>> cross = Instance.mapf(Graph.grid(3, 3), [(0, 1), (1, 0)], [(2, 1), (1, 2)])
    >>> r = solve(cross, w=1.2)  # the optimum is 5 (one agent waits once)
    >>> r.cost <= 1.2 * 5 and r.lower_bound <= 5 <= r.cost
    True
    """
    del objective  # the sum of costs only; the seed is LaCAM's
    if highways is not None:
        return run_with_highways(
            _EECBS, instance, time_limit, highways=highways, w_hwy=w_hwy, hwy_mode=hwy_mode,
            w=w, polish=polish, bypass=bypass,
        )  # fmt: skip
    return run_search(
        _EECBS, instance, time_limit, seed, w=w, polish=polish, bypass=bypass, lacam=lacam
    )
