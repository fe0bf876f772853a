"""Solver results and the one status vocabulary every solver uses."""

from __future__ import annotations

from dataclasses import dataclass, field
from enum import StrEnum
from typing import Any

from hierplan_opt.core.plan import Plan


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

    ``cost`` is the plan's cost under ``objective``; ``lower_bound`` is a proven lower
    bound on the optimal cost when the solver knows one (equal to ``cost`` when
    OPTIMAL). ``stats`` holds solver statistics (expanded nodes, generated nodes, ...).

    Example
    -------
    >>> r = Result(Status.INFEASIBLE, None, solver="cbs", objective="soc")
    >>> r.solved, r.gap
    (False, None)
    """

    status: Status
    plan: Plan | None
    cost: float | None = None
    lower_bound: float | None = None
    runtime: float = 0.0
    solver: str = ""
    objective: str = "soc"
    stats: dict[str, Any] = field(default_factory=dict)

    @property
    def solved(self) -> bool:
        """True when a plan is present (OPTIMAL or FEASIBLE)."""
        return self.plan is not None and self.status in (Status.OPTIMAL, Status.FEASIBLE)

    @property
    def gap(self) -> float | None:
        """``cost / lower_bound`` (1.0 means proven optimal); None when unknown."""
        if self.cost is None or self.lower_bound is None:
            return None
        if self.lower_bound <= 0:
            return 1.0 if self.cost <= 0 else None
        return self.cost / self.lower_bound
