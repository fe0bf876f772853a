"""Solver results and the one status vocabulary every solver uses."""

from __future__ import annotations

from dataclasses import dataclass, field
from enum import StrEnum
from typing import Any

from hierplan_opt.core.plan import Plan
from hierplan_opt.core.reprs import short_repr


class Status(StrEnum):
    """Outcome of a solve.

    OPTIMAL: plan proven optimal for the objective. FEASIBLE: a valid plan (bounded-
    suboptimal solvers, or a time-out with an incumbent). INFEASIBLE: proven to have
    no plan. TIME_LIMIT: stopped by the time limit without a plan. ERROR: the solver
    failed (details in ``Result.stats["error"]``).
    """

    OPTIMAL = "OPTIMAL"
    FEASIBLE = "FEASIBLE"
    INFEASIBLE = "INFEASIBLE"
    TIME_LIMIT = "TIME_LIMIT"
    ERROR = "ERROR"

    def __str__(self) -> str:
        return self.value


@dataclass(frozen=True)
class Result:
    """What every solver returns.

    ``cost`` is the plan's cost under ``objective`` (sum of costs, or makespan);
    ``lower_bound`` is a proven lower bound on the optimal cost under ``objective`` when
    the solver knows one (equal to ``cost`` when OPTIMAL); :attr:`gap` is
    ``(cost - lower_bound) / cost``. ``stats`` holds solver statistics (expanded nodes,
    generated nodes, ...).

    Example
    -------
    >>> r = Result(Status.INFEASIBLE, None, solver="cbs", objective="soc")
    >>> r.solved, r.gap
    (False, None)
    >>> Result(Status.FEASIBLE, None, cost=110, lower_bound=100).gap
    0.09090909090909091
    """

    __repr__ = short_repr  # arrays and long tuples summarised (core/reprs)

    status: Status
    plan: Plan | None
    cost: float | None = None
    lower_bound: float | None = None
    runtime: float = 0.0
    solver: str = ""
    objective: str = "soc"
    stats: dict[str, Any] = field(default_factory=dict[str, Any])

    @property
    def solved(self) -> bool:
        """True when a plan is present (OPTIMAL or FEASIBLE)."""
        return self.plan is not None and self.status in (Status.OPTIMAL, Status.FEASIBLE)

    @property
    def bound_met(self) -> bool | None:
        """For a bounded solver (ECBS, EECBS: cost <= w * optimum): True when the plan is
        shown to be within the bound asked, False when it is not (e.g. the LaCAM plan
        returned at the time limit, ``stats["bound_met"] = False``, which the summary line
        and the plan file show too); None for solvers without such a bound.

        Example
        -------
        >>> Result(Status.FEASIBLE, None, cost=154, lower_bound=100,
        ...        stats={"bound_met": False}).bound_met
        False
        >>> Result(Status.OPTIMAL, None).bound_met is None
        True
        """
        met = self.stats.get("bound_met")
        return met if isinstance(met, bool) else None

    @property
    def gap(self) -> float | None:
        """The relative optimality gap (see :func:`relative_gap`); None when unknown."""
        return relative_gap(self.cost, self.lower_bound)


def relative_gap(cost: float | None, bound: float | None) -> float | None:
    """``(cost - bound) / cost``, as MIP and CP-SAT users read it: 0.0 is proven optimal.

    None when either number is unknown; 0.0 when the cost is 0 and meets the bound.

    Example
    -------
    >>> relative_gap(12, 10), relative_gap(8, 8), relative_gap(None, 3)
    (0.16666666666666666, 0.0, None)
    """
    if cost is None or bound is None:
        return None
    if cost <= 0:
        return 0.0 if bound >= cost else None
    return max(0.0, (cost - bound) / cost)
