"""Horizon search shared by the MIP and CP-SAT formulations.

A *backend* solves one :class:`~hierplan_opt.formulations.time_expanded.TimeExpandedNetwork`
(feasibility for makespan, minimum sum of costs for ``"soc"``); this module decides which
networks to solve and turns the outcomes into one :class:`~hierplan_opt.core.result.Result`.

* Makespan: horizons ``T = LB, LB + 1, ...``; the first feasible one is optimal because
  every smaller one was proven infeasible (the MIP rejects many by its LP relaxation).
  At each ``T`` a small network that keeps only vertices within a detour ``s`` of each
  commodity's shortest paths is tried first (a plan in it has makespan ``<= T``); only
  when it has no plan is the full network solved, which alone can prove ``T``
  infeasible.
* Sum of costs: per-commodity deadlines ``d_k + Δ`` for ``Δ = 0, 1, ...`` (``d_k`` the
  distance lower bound of the commodity's agents). If the network at ``Δ`` is infeasible,
  every plan costs at least ``LB + Δ + 1``. If its optimum ``C`` satisfies
  ``C - LB <= Δ`` then ``C`` is optimal: in an optimal plan each agent's excess over its
  distance is at most ``C* - LB <= Δ``, so that plan fits the network. Otherwise one more
  solve at ``Δ = C - LB`` is optimal by the same argument. A known plan of cost ``U``
  (``upper_bound_plan``) starts the search at ``Δ = U - LB``.

INFEASIBLE comes from the front door's checks (:func:`hierplan_opt.registry.run`; exact
on undirected graphs) or from the horizon bound ``B =`` :func:`makespan_upper_bound`:
every solvable instance has a plan of makespan at most ``B``, so a network that holds
every plan of makespan ``<= B`` (the makespan search at horizon ``B``; for the sum of
costs, deadlines that all reach ``B``) and has no flow proves that no plan exists.
Otherwise the search stops at ``max_horizon`` (default :func:`default_max_horizon`) with
TIME_LIMIT and ``stats["stopped_by"] == "max_horizon"``, or before a model whose
estimated size exceeds the memory budget (:mod:`hierplan_opt.formulations.memory`; it
is never built) with ``stats["stopped_by"] == "memory_limit"`` and the one-line reason
in ``stats["reason"]``.

Backends report one :class:`Outcome` per network in the project's one status vocabulary
(:class:`~hierplan_opt.core.result.Status`), each mapping its native codes by a table.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np

from hierplan_opt.core.feasibility import makespan_upper_bound
from hierplan_opt.core.instance import Instance
from hierplan_opt.core.plan import Plan
from hierplan_opt.core.progress import tick
from hierplan_opt.core.result import Result, Status
from hierplan_opt.core.timer import Deadline
from hierplan_opt.formulations.memory import ModelTooLarge, check_model
from hierplan_opt.formulations.time_expanded import TimeExpandedNetwork, commodity_min_deadline

log = logging.getLogger(__name__)

#: Backend statistics added up over the solves of one search (others keep the last value).
_SUMMED = {"model_time", "lp_time", "lp_rejected", "conflicts"}


@dataclass
class Outcome:
    """What a backend reports for one network.

    ``status`` is OPTIMAL, FEASIBLE (stopped with an incumbent), INFEASIBLE, TIME_LIMIT
    (stopped without a decision) or ERROR (``stats["error"]`` says why). ``objective``
    includes the constant of the sum-of-costs objective; ``bound`` is the backend's
    proven bound on it.
    """

    status: Status
    values: np.ndarray | None = None
    objective: float | None = None
    bound: float | None = None
    stats: dict = field(default_factory=dict)


class Backend(Protocol):
    """Solves one network for ``objective`` within ``time_limit`` seconds."""

    name: str

    def __call__(
        self,
        net: TimeExpandedNetwork,
        objective: str,
        time_limit: float | None,
        hint: Plan | None,
        seed: int,
    ) -> Outcome: ...


def fold_seed(seed: int, low: int, high: int) -> int:
    """``seed`` folded into the range ``[low, high]`` of a C library's seed (CP-SAT:
    a signed 32-bit integer; HiGHS: 0 .. 2**31 - 1), so every integer seed works.

    Seeds in the range are kept; the others are taken modulo the range's size, which
    is deterministic (one seed, one run) and keeps the seeds ``S, S+1, ...`` of a
    batch distinct.

    Example
    -------
    >>> fold_seed(7, 0, 2**31 - 1), fold_seed(2**31, 0, 2**31 - 1), fold_seed(-1, 0, 2**31 - 1)
    (7, 0, 2147483647)
    >>> fold_seed(-5, -(2**31), 2**31 - 1), fold_seed(2**31, -(2**31), 2**31 - 1)
    (-5, -2147483648)
    """
    return low + (int(seed) - low) % (high - low + 1)


def detours(instance: Instance, horizon: int) -> list[int]:
    """Per commodity, the detour budget of the small first network at ``horizon``.

    Each commodity may spend ``2 + horizon // 10`` steps more than its distance lower
    bound: small enough to solve fast, large enough to hold a plan most of the time.

    Example
    -------
    >>> from hierplan_opt.core.graph import Graph
    >>> detours(Instance.mapf(Graph.grid(3, 1), [(0, 0)], [(2, 0)]), 20)
    [6]
    """
    slack = 2 + horizon // 10
    return [b + slack for b in commodity_min_deadline(instance)]


def default_max_horizon(instance: Instance) -> int:
    """A horizon cap used when none is given: LB + free vertices + agents.

    The search's own cap is :func:`search_cap`: it reaches the horizon bound when that
    bound is within a small factor of this cap (small roadmaps, where a proof is cheap).
    """
    return instance.makespan_lower_bound() + instance.graph.num_vertices + instance.num_agents


#: The default cap stretches up to the horizon bound when the bound is at most this many
#: times :func:`default_max_horizon` (e.g. a full one-way 4-cycle: bound 23, cap 11).
BOUND_REACH = 8


def search_cap(instance: Instance, max_horizon: int | None, bound: int) -> int:
    """The largest horizon the search tries without a plan: ``max_horizon`` when given;
    otherwise :func:`default_max_horizon`, or the horizon bound ``bound`` (which decides
    feasibility) when it is at most :data:`BOUND_REACH` times that.

    Example
    -------
    >>> from hierplan_opt.core.graph import Graph
    >>> ring = [("A", "B"), ("B", "C"), ("C", "D"), ("D", "A")]
    >>> g = Graph.roadmap({"A": (0, 0), "B": (1, 0), "C": (1, 1), "D": (0, 1)}, ring, directed=True)
    >>> inst = Instance.mapf(g, ["A", "B", "C", "D"], ["B", "A", "C", "D"])
    >>> default_max_horizon(inst), search_cap(inst, None, 23), search_cap(inst, 5, 23)
    (11, 23, 5)
    """
    if max_horizon is not None:
        return max_horizon
    cap = default_max_horizon(instance)
    return max(cap, bound) if bound <= BOUND_REACH * cap else cap


class _BackendError(Exception):
    pass


class _Stopped(Exception):
    """Ends the search with ``result`` (a model over the memory budget)."""

    def __init__(self, result: Result) -> None:
        self.result = result


#: The next network and model take about this many times the last one's set-up (each
#: horizon or slack step adds arcs; measured 1.2-2x on random-32-32-20, 60 agents).
SETUP_GROWTH = 1.5


def solve_with(
    backend: Backend,
    instance: Instance,
    **kwargs: Any,
) -> Result:
    """Run the horizon search with ``backend`` (see the module docstring).

    Keyword arguments: ``objective``, ``time_limit``, ``seed``, ``max_horizon``,
    ``upper_bound_plan`` (a known plan: the sum-of-costs search starts at its slack),
    ``build`` (the network builder).
    """
    try:
        return _search(backend, instance, **kwargs)
    except _BackendError as exc:
        return Result(Status.ERROR, None, stats={"error": str(exc)})
    except _Stopped as stop:
        return stop.result


def _search(
    backend: Backend,
    instance: Instance,
    *,
    objective: str,
    time_limit: float | None,
    seed: int = 0,
    max_horizon: int | None = None,
    upper_bound_plan: Plan | None = None,
    build: Callable[..., TimeExpandedNetwork] = TimeExpandedNetwork.build,
) -> Result:
    deadline = Deadline(time_limit)
    bound = makespan_upper_bound(instance)  # every solvable instance has a plan within it
    cap = search_cap(instance, max_horizon, bound)
    stats: dict = {"solves": 0, "build_time": 0.0, "solve_time": 0.0, "horizons": []}
    # seconds the last network took to build and turn into a model: a next one is not
    # started when less time is left (it could not be stopped half way)
    setup = [0.0, 0.0]

    def run(net: TimeExpandedNetwork, hint: Plan | None) -> Outcome:
        if net.num_arcs == 0:  # everyone is at a goal at t = 0: nothing to decide
            return Outcome(Status.OPTIMAL, np.zeros(0), float(net.soc_constant()), 0.0)
        if deadline.expired():  # building the network took the rest of the budget
            return Outcome(Status.TIME_LIMIT)
        stats["solves"] += 1
        t0 = time.perf_counter()
        remaining = deadline.remaining() if time_limit is not None else None
        out = backend(net, objective, remaining, hint, seed)
        stats["solve_time"] += time.perf_counter() - t0
        setup[1] = setup[0] + float(out.stats.get("model_time", 0.0))
        stats.update(net.stats(objective))
        stats["horizons"].append((net.horizon, str(out.status)))
        for key, value in out.stats.items():
            if key in _SUMMED and key in stats:
                stats[key] += value  # totals over all solves
            else:
                stats[key] = value  # the last solve's value
        log.info("%s: horizon %d, %d arcs: %s", backend.name, net.horizon, net.num_arcs, out.status)
        tick(
            "solves", stats["solves"], horizon=net.horizon, status=str(out.status), bound=out.bound
        )
        if out.status is Status.ERROR:
            raise _BackendError(out.stats.get("error", "solver error"))
        return out

    def make(horizon: int, proven: float, **kwargs) -> TimeExpandedNetwork:
        try:
            check_model(instance, horizon, backend.name, **kwargs)
        except ModelTooLarge as exc:
            stats["reason"] = str(exc)
            raise _Stopped(limit(proven, "memory_limit")) from None
        t0 = time.perf_counter()
        net = build(instance, horizon, **kwargs)
        setup[0] = time.perf_counter() - t0
        stats["build_time"] += setup[0]
        return net

    def out_of_time() -> bool:
        """The budget is spent, or too little is left to build the next model."""
        return deadline.expired() or deadline.remaining() < SETUP_GROWTH * setup[1]

    best: list[Plan] = []  # the cheapest plan found so far (sum of costs): never dropped

    def limit(lower_bound: float, why: str) -> Result:
        stats["stopped_by"] = why
        if best:  # stopped with a plan in hand: FEASIBLE, not TIME_LIMIT
            cost = best[0].sum_of_costs
            return Result(Status.FEASIBLE, best[0], cost, min(lower_bound, cost), stats=stats)
        return Result(Status.TIME_LIMIT, None, lower_bound=lower_bound, stats=stats)

    def no_plan() -> Result:
        stats["reason"] = (
            f"no plan has makespan <= {bound}, the bound every solvable instance of this "
            "size meets (makespan_upper_bound)"
        )
        return Result(Status.INFEASIBLE, None, stats=stats)

    if objective == "makespan":
        horizon = instance.makespan_lower_bound()
        while True:
            if horizon > bound:
                return no_plan()  # every horizon up to the bound was proven infeasible
            if horizon > cap:
                return limit(horizon, "max_horizon")
            if out_of_time():
                return limit(horizon, "time_limit")
            # First a network where each commodity may detour little from its shortest
            # paths (small, fast); any plan in it has makespan <= horizon. Only if it has
            # none does the full network decide the horizon.
            small = detours(instance, horizon)
            tries: list[dict] = [{"detours": small}] if min(small) < horizon else []
            for kwargs in [*tries, {}]:
                net = make(horizon, horizon, **kwargs)
                out = Outcome(Status.INFEASIBLE) if net.infeasible else run(net, None)
                if out.status is not Status.INFEASIBLE:
                    break
            if out.status is Status.INFEASIBLE:
                horizon += 1
                continue
            if out.values is None:
                return limit(horizon, "time_limit")
            plan = net.plan(out.values)
            return Result(Status.OPTIMAL, plan, plan.makespan, plan.makespan, stats=stats)

    if objective != "soc":
        raise ValueError(f"unknown objective {objective!r}")
    lb = instance.soc_lower_bound()
    base = commodity_min_deadline(instance)
    hint = upper_bound_plan
    delta = 0 if hint is None else max(0, hint.sum_of_costs - lb)
    proven = lb  # every plan costs at least this
    # The network at slack bound - min(base) holds every plan of makespan <= bound; the
    # search may go that far to prove infeasibility even past ``cap``.
    reach = max(cap, bound - min(base) + max(base)) if bound <= cap else cap
    while True:
        # With a plan in hand the network that proves it optimal (slack cost - LB) is
        # solved even past the default cap; a cap the user gave still stops the search.
        if max(base) + delta > reach and (max_horizon is not None or not best):
            return limit(proven, "max_horizon")
        if out_of_time():
            return limit(proven, "time_limit")
        net = make(max(base) + delta, proven, deadlines=[b + delta for b in base])
        out = Outcome(Status.INFEASIBLE) if net.infeasible else run(net, hint)
        stats["slack"] = delta
        if out.status is Status.INFEASIBLE:
            if min(base) + delta >= bound:
                return no_plan()
            proven = max(proven, lb + delta + 1)
            delta += 1 + delta // 4
            if min(base) + delta > bound:
                delta = max(bound - min(base), 0)  # land on the proof's network
            continue
        if out.values is None:
            if out.bound is not None:
                proven = max(proven, min(int(np.ceil(out.bound - 1e-6)), lb + delta + 1))
            return limit(proven, "time_limit")
        plan = net.plan(out.values)
        cost = plan.sum_of_costs
        if not best or cost < best[0].sum_of_costs:
            best[:] = [plan]
        if out.status is Status.OPTIMAL:
            if cost - lb <= delta:
                return Result(Status.OPTIMAL, plan, cost, cost, stats=stats)
            proven = max(proven, min(cost, lb + delta + 1))  # plans outside the network
            delta = cost - lb
            hint = plan
            continue
        # Stopped with an incumbent: the network's bound, or any plan outside it.
        net_bound = lb if out.bound is None else int(np.ceil(out.bound - 1e-6))
        proven = max(proven, min(net_bound, lb + delta + 1))
        return limit(proven, "time_limit")
