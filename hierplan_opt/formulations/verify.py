"""Certify that a plan is optimal, or report how far from optimal it may be.

Mathematics: ``formulations/verify.md``. The check is independent of the solver that
made the plan: the plan is validated by :func:`~hierplan_opt.core.validate.validate`,
then an exact time-expanded formulation (CP-SAT or MIP) decides the question:

* makespan ``M``: the plan is optimal iff ``M`` equals the distance lower bound or the
  network with horizon ``M - 1`` has no flow (one feasibility solve);
* sum of costs ``U``: the plan is optimal iff ``U`` equals the distance lower bound or
  the minimum over the network with slack ``U - LB`` (which contains the plan and every
  optimal plan) is ``U``.

No model is built whose estimated size exceeds the memory budget
(:mod:`hierplan_opt.formulations.memory`): the verdict is then "unknown" with the reason
("the cpsat model at horizon 180 would need ~31 GB ...").
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

from hierplan_opt.core.errors import OptionError
from hierplan_opt.core.instance import Instance
from hierplan_opt.core.plan import Plan
from hierplan_opt.core.result import Result, Status, relative_gap
from hierplan_opt.core.timer import Deadline
from hierplan_opt.core.validate import Violation, validate
from hierplan_opt.formulations.cpsat import CpSatBackend
from hierplan_opt.formulations.horizon import Outcome, detours, solve_with
from hierplan_opt.formulations.memory import ModelTooLarge, check_model
from hierplan_opt.formulations.mip import MipBackend
from hierplan_opt.formulations.time_expanded import TimeExpandedNetwork

if TYPE_CHECKING:
    from hierplan_opt.formulations.horizon import Backend

METHODS = ("cpsat", "mip")


#: The verdict on a plan in words, for each outcome.
VERDICTS = {
    Status.OPTIMAL: "optimal",
    Status.FEASIBLE: "suboptimal",
    Status.INFEASIBLE: "invalid",
    Status.TIME_LIMIT: "unknown",
}


@dataclass(frozen=True)
class VerifyResult:
    """The verdict on a plan.

    ``outcome`` is in the one status vocabulary: OPTIMAL (proven optimal), FEASIBLE
    (valid, but a cheaper plan exists; ``better_plan`` holds one, ``optimum`` the optimal
    cost when it was found), INFEASIBLE (the plan is invalid, see ``violations``) or
    TIME_LIMIT (stopped by the time limit, or a model would exceed the memory budget:
    ``reason`` says so; ``lower_bound`` is the best proven bound).
    :attr:`status` says it in words: "optimal", "suboptimal", "invalid", "unknown".
    ``proof`` says what settled it ("lower bound", "pruning", "cpsat", "mip").
    """

    outcome: Status
    objective: str
    method: str
    cost: int | None = None
    optimum: int | None = None
    lower_bound: int | None = None
    better_plan: Plan | None = None
    violations: tuple[Violation, ...] = ()
    proof: str = ""
    runtime: float = 0.0
    stats: dict = field(default_factory=dict)
    reason: str = ""

    @property
    def status(self) -> str:
        """The verdict in words (see :data:`VERDICTS`)."""
        return VERDICTS[self.outcome]

    @property
    def optimal(self) -> bool:
        """True when the plan is proven optimal."""
        return self.outcome is Status.OPTIMAL

    @property
    def gap(self) -> float | None:
        """``(cost - lower_bound) / cost`` like :attr:`Result.gap`; None when unknown."""
        return relative_gap(self.cost, self.lower_bound)

    @property
    def excess(self) -> int | None:
        """``cost - lower_bound``: how much the plan may exceed the optimum."""
        if self.cost is None or self.lower_bound is None:
            return None
        return self.cost - self.lower_bound

    def message(self) -> str:
        """One line for people, as ``hierplan verify`` prints it."""
        obj = "sum of costs" if self.objective == "soc" else "makespan"
        if self.outcome is Status.INFEASIBLE:
            return f"invalid plan: {self.violations[0]}" + (
                f" (and {len(self.violations) - 1} more)" if len(self.violations) > 1 else ""
            )
        if self.outcome is Status.OPTIMAL:
            return f"optimal ({obj} {self.cost}, proven by {self.proof} in {self.runtime:.2f} s)"
        if self.outcome is Status.FEASIBLE:
            best = (
                f"the optimum is {self.optimum}"
                if self.optimum is not None
                else f"a plan of {obj} {self.better_plan.cost(self.objective)} exists"  # type: ignore[union-attr]
            )
            return (
                f"not optimal: {obj} {self.cost}, {best} (excess {self.excess}, "
                f"gap {self.gap:.4f}, "
                f"proven by {self.proof} in {self.runtime:.2f} s)"
            )
        why = self.reason or f"time limit reached after {self.runtime:.2f} s"
        return (
            f"unknown: {obj} {self.cost}, proven lower bound {self.lower_bound} "
            f"(excess at most {self.excess}, gap at most {self.gap:.4f}); {why}"
        )


def _backend(method: str) -> Backend:
    if method == "cpsat":
        return CpSatBackend()
    if method == "mip":
        return MipBackend()
    raise OptionError(f"unknown verification method {method!r} (use 'cpsat' or 'mip')")


def verify(
    instance: Instance,
    plan: Plan,
    *,
    objective: str | None = None,
    method: str = "cpsat",
    time_limit: float | None = None,
    seed: int = 0,
) -> VerifyResult:
    """Certify that ``plan`` is optimal for ``objective`` on ``instance`` (or say why not).

    ``objective`` defaults to ``"soc"`` for MAPF and ``"makespan"`` for TAPF.

    Example
    -------
    >>> from hierplan_opt.core.graph import Graph
    >>> g = Graph.grid(5, 2, obstacles=[(0, 1), (1, 1), (3, 1), (4, 1)])
    >>> inst = Instance.mapf(g, [(0, 0), (1, 0)], [(4, 0), (3, 0)])
    >>> good = Plan.from_paths([[0, 1, 2, 3, 4], [1, 2, 7, 2, 3]])
    >>> verify(inst, good, objective="soc").message()  # doctest: +ELLIPSIS
    'optimal (sum of costs 8, proven by cpsat in ... s)'
    >>> slow = Plan.from_paths([[0, 0, 1, 2, 3, 4], [1, 2, 7, 7, 2, 3]])
    >>> r = verify(inst, slow, objective="soc", method="mip")
    >>> r.status, r.cost, r.optimum
    ('suboptimal', 10, 8)
    """
    t0 = time.perf_counter()
    if objective is None:
        objective = "makespan" if instance.is_tapf else "soc"
    if objective not in ("soc", "makespan"):
        raise OptionError(f"unknown objective {objective!r} (use 'soc' or 'makespan')")
    backend = _backend(method)
    deadline = Deadline(time_limit)

    def done(outcome: Status, **kw: Any) -> VerifyResult:
        return VerifyResult(outcome, objective, method, runtime=time.perf_counter() - t0, **kw)

    violations = validate(instance, plan)
    if violations:
        return done(Status.INFEASIBLE, violations=tuple(violations))
    cost = plan.cost(objective)
    lb = instance.soc_lower_bound() if objective == "soc" else instance.makespan_lower_bound()
    if cost <= lb:
        return done(Status.OPTIMAL, cost=cost, optimum=cost, lower_bound=lb, proof="lower bound")

    remaining = None if time_limit is None else deadline.remaining()
    if objective == "makespan":
        # A small network (little detour) often finds a shorter plan at once; only the
        # full network can prove that none exists.
        small_detours = detours(instance, cost)
        out = Outcome(Status.INFEASIBLE)
        try:
            if min(small_detours) < cost - 1:
                check_model(instance, cost - 1, method, detours=small_detours)
                small = TimeExpandedNetwork.build(instance, cost - 1, detours=small_detours)
                if not small.infeasible:
                    out = backend(small, "makespan", remaining, None, seed)
                    net = small
            if out.status is Status.INFEASIBLE:
                check_model(instance, cost - 1, method)
        except ModelTooLarge as exc:
            return done(Status.TIME_LIMIT, cost=cost, lower_bound=lb, proof=method, reason=str(exc))
        if out.status is Status.INFEASIBLE:
            net = TimeExpandedNetwork.build(instance, cost - 1)
            if net.infeasible:
                return done(
                    Status.OPTIMAL, cost=cost, optimum=cost, lower_bound=cost, proof="pruning"
                )
            remaining = None if time_limit is None else deadline.remaining()
            out = backend(net, "makespan", remaining, None, seed)
        stats = {**net.stats("makespan"), **out.stats}
        if out.status is Status.INFEASIBLE:
            return done(
                Status.OPTIMAL, cost=cost, optimum=cost, lower_bound=cost, proof=method, stats=stats
            )
        if out.values is None:
            return done(Status.TIME_LIMIT, cost=cost, lower_bound=lb, proof=method, stats=stats)
        better = net.plan(out.values)
        # A cheaper plan exists; find the optimum with what is left of the budget.
        res = _solve_rest(backend, instance, objective, deadline, time_limit, seed)
        if res is not None and res.status == Status.OPTIMAL and res.plan is not None:
            assert res.cost is not None  # an OPTIMAL result has a cost
            better = res.plan
            return done(
                Status.FEASIBLE,
                cost=cost,
                optimum=int(res.cost),
                lower_bound=int(res.cost),
                better_plan=better,
                proof=method,
                stats=stats,
            )
        low = lb if res is None or res.lower_bound is None else int(res.lower_bound)
        return done(
            Status.FEASIBLE,
            cost=cost,
            lower_bound=low,
            better_plan=better,
            proof=method,
            stats=stats,
        )

    res = solve_with(
        backend,
        instance,
        objective="soc",
        time_limit=remaining,
        seed=seed,
        upper_bound_plan=plan,
    )
    stats = dict(res.stats)
    if res.status == Status.OPTIMAL:
        assert res.cost is not None
        if res.cost >= cost:
            return done(
                Status.OPTIMAL, cost=cost, optimum=cost, lower_bound=cost, proof=method, stats=stats
            )
        return done(
            Status.FEASIBLE,
            cost=cost,
            optimum=int(res.cost),
            lower_bound=int(res.cost),
            better_plan=res.plan,
            proof=method,
            stats=stats,
        )
    low = lb if res.lower_bound is None else int(res.lower_bound)
    if res.plan is not None and res.plan.sum_of_costs < cost:
        return done(
            Status.FEASIBLE,
            cost=cost,
            lower_bound=low,
            better_plan=res.plan,
            proof=method,
            stats=stats,
        )
    reason = str(stats.get("reason", "")) if stats.get("stopped_by") == "memory_limit" else ""
    return done(
        Status.TIME_LIMIT, cost=cost, lower_bound=low, proof=method, stats=stats, reason=reason
    )


def _solve_rest(
    backend: Backend,
    instance: Instance,
    objective: str,
    deadline: Deadline,
    time_limit: float | None,
    seed: int,
) -> Result | None:

    if time_limit is not None and deadline.expired():
        return None
    return solve_with(
        backend,
        instance,
        objective=objective,
        time_limit=None if time_limit is None else deadline.remaining(),
        seed=seed,
    )
