"""Time-expanded network MIP in Pyomo, solved with HiGHS (``solver="mip"``).

Mathematics: ``formulations/mip.md``. The model is a reduction:
:func:`build` turns an instance and a horizon into ``(model, index)`` where ``index`` is
the :class:`~hierplan_opt.formulations.time_expanded.TimeExpandedNetwork` (plain data);
:func:`extract` turns arc values back into a :class:`~hierplan_opt.core.plan.Plan`.
HiGHS is called through Pyomo's APPSI interface (the ``appsi_highs`` solver), with the
wall-clock budget as HiGHS' ``time_limit``.

Example
-------
>>> from hierplan_opt.core.graph import Graph
>>> from hierplan_opt.core.instance import Instance
>>> g = Graph.grid(5, 2, obstacles=[(0, 1), (1, 1), (3, 1), (4, 1)])
>>> inst = Instance.mapf(g, [(0, 0), (1, 0)], [(4, 0), (3, 0)])
>>> r = solve(inst, cost="soc", time_limit=30)
>>> r.status.value, r.cost, r.lower_bound
('OPTIMAL', 8, 8)
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Sequence
from functools import partial
from typing import Any, cast

import numpy as np

from hierplan_opt.core.instance import Instance
from hierplan_opt.core.options import Option
from hierplan_opt.core.plan import Plan
from hierplan_opt.core.progress import watching_highs
from hierplan_opt.core.result import Result, Status
from hierplan_opt.formulations.horizon import Outcome, fold_seed, solve_with
from hierplan_opt.formulations.time_expanded import TimeExpandedNetwork
from hierplan_opt.registry import solver

log = logging.getLogger(__name__)


def build(
    instance: Instance,
    horizon: int,
    objective: str = "makespan",
    *,
    deadlines: Sequence[int] | None = None,
    prune: bool = True,
) -> tuple[Any, TimeExpandedNetwork]:
    """The Pyomo model of ``instance`` at ``horizon`` and its index (the network).

    ``objective="makespan"`` gives a feasibility model (is there a plan of makespan at
    most ``horizon``?); ``"soc"`` minimises the sum of costs among plans in the network.

    Example
    -------
    >>> from hierplan_opt.core.graph import Graph
    >>> inst = Instance.mapf(Graph.grid(3, 1), [(0, 0)], [(2, 0)])
    >>> model, index = build(inst, 2)
    >>> len(model.x) == index.num_arcs
    True
    """
    net = TimeExpandedNetwork.build(instance, horizon, deadlines=deadlines, prune=prune)
    return model_of(net, objective), net


def model_of(net: TimeExpandedNetwork, objective: str) -> Any:
    """The Pyomo model of an already built network."""
    import pyomo.environ as pyo  # heavy module: Pyomo
    from pyomo.core.expr.numeric_expr import LinearExpression  # heavy module: Pyomo

    m: Any = pyo.ConcreteModel(name=f"mapf_te_T{net.horizon}")  # components as attributes
    # x[i] = 1 iff arc i (commodity arc_k[i], arc_u[i] -> arc_v[i] at arc_t[i]) is used.
    m.x = cast(Any, pyo.Var(range(net.num_arcs), domain=pyo.Binary))
    x = m.x
    xs = list(m.x.values())

    def total(ids: np.ndarray, minus: np.ndarray | None = None):
        terms = [xs[i] for i in ids.tolist()]
        if minus is not None:
            terms += [-1 * xs[i] for i in minus.tolist()]
        return LinearExpression(terms)

    # ---- flow conservation, sources and sinks
    m.flow = cast(Any, pyo.ConstraintList())
    for ins, outs in net.conservation:
        m.flow.add(total(ins, outs) == 0)
    m.source = cast(Any, pyo.ConstraintList())
    for outs in net.source_out:
        m.source.add(total(outs) == 1)
    m.sink = cast(Any, pyo.ConstraintList())
    for ins in net.sink_in:
        m.sink.add(total(ins) == 1)

    # ---- collisions: one robot per vertex and time, no swaps
    m.vertex = cast(Any, pyo.ConstraintList())
    for arcs in net.vertex_groups:
        m.vertex.add(total(arcs) <= 1)
    m.swap = cast(Any, pyo.ConstraintList())
    for arcs in net.swap_groups:
        m.swap.add(total(arcs) <= 1)
    for a in net.forbidden.tolist():  # annotated conflicts with a parked robot
        m.swap.add(xs[a] == 0)

    # ---- objective
    if objective == "soc":
        # y = 1: the robot waits at that sink from t to the deadline (parked for good).
        pairs: list[tuple[int, int | None]] = []  # (wait arc, index of the y at t + 1)
        for w in net.wait:
            for row in w:
                nxt: int | None = None
                for t in range(len(row) - 1, -1, -1):
                    if row[t] < 0:
                        break
                    pairs.append((int(row[t]), nxt))
                    nxt = len(pairs) - 1
        m.y = cast(Any, pyo.Var(range(len(pairs)), bounds=(0, 1)))
        m.goal = cast(Any, pyo.ConstraintList())
        for j, (arc, nxt) in enumerate(pairs):
            m.goal.add(m.y[j] <= x[arc])
            if nxt is not None:
                m.goal.add(m.y[j] <= m.y[nxt])
        m.cost = pyo.Objective(
            expr=net.soc_constant() - pyo.quicksum(m.y.values()), sense=pyo.minimize
        )
    else:
        m.cost = pyo.Objective(expr=0, sense=pyo.minimize)
    return m


def extract(values: Sequence[float] | np.ndarray, index: TimeExpandedNetwork) -> Plan:
    """The plan of arc ``values`` (model.x in arc order) in network ``index``."""
    return index.plan(values)


def _highs(seed: int) -> Any:
    from pyomo.contrib.appsi.solvers import Highs  # heavy module: Pyomo

    # only_child_vars: hand all variables to HiGHS in one batch (much faster set-up).
    opt = Highs(only_child_vars=True)
    opt.config.load_solution = False
    opt.config.stream_solver = False
    opt.config.log_level = logging.DEBUG  # HiGHS' banner and log go to DEBUG, not INFO
    opt.highs_options = {
        # HiGHS ignores (with a log line) a seed outside 0 .. 2**31 - 1
        "random_seed": fold_seed(seed, 0, 2**31 - 1),
        "mip_rel_gap": 0.0,
        # Objectives are integers: a gap below 1 already proves the incumbent optimal.
        "mip_abs_gap": 1.0 - 1e-6,
        "threads": 1,
        "output_flag": False,
    }
    return opt


def _set_domain(m: Any, relaxed: bool) -> None:
    import pyomo.environ as pyo  # heavy module: Pyomo

    dom = pyo.UnitInterval if relaxed else pyo.Binary
    for v in m.x.values():
        v.domain = dom


class MipBackend:
    """Solves one network with HiGHS; first its LP relaxation when ``lp_check``."""

    name = "mip"

    def __init__(self, lp_check: bool = True) -> None:
        self.lp_check = lp_check

    def __call__(
        self,
        net: TimeExpandedNetwork,
        objective: str,
        time_limit: float | None,
        hint: Plan | None,
        seed: int,
    ) -> Outcome:
        t0 = time.perf_counter()
        m = model_of(net, objective)
        opt = _highs(seed)
        opt.set_instance(m)  # builds the highspy model now, for the progress callbacks
        stats: dict = {"model_time": time.perf_counter() - t0}  # Pyomo's and HiGHS' model
        if time_limit is not None and time.perf_counter() - t0 >= time_limit:
            return Outcome(Status.TIME_LIMIT, stats=stats)  # the model took the budget
        watch = partial(watching_highs, opt._solver_model)  # Pyomo keeps it private

        def budget() -> None:
            if time_limit is not None:
                opt.config.time_limit = max(0.01, time_limit - (time.perf_counter() - t0))

        if self.lp_check:
            # The LP relaxation first: if it is infeasible, so is the MIP.
            _set_domain(m, relaxed=True)
            budget()
            with watch():
                res = opt.solve(m)
            stats["lp_time"] = time.perf_counter() - t0 - stats["model_time"]
            stats["lp_status"] = res.termination_condition.name
            if _status(res.termination_condition) is Status.INFEASIBLE:
                stats["lp_rejected"] = 1
                return Outcome(Status.INFEASIBLE, stats=stats)
            # Persistent interface: only the domains change, not the model.
            _set_domain(m, relaxed=False)
            for flag in (
                "check_for_new_or_removed_constraints",
                "check_for_new_or_removed_vars",
                "check_for_new_or_removed_params",
                "update_constraints",
                "update_params",
                "update_named_expressions",
                "check_for_new_objective",
                "update_objective",
                "update_vars",
            ):
                setattr(opt.update_config, flag, False)
            opt.update_variables(list(m.x.values()))
            if time_limit is not None and time.perf_counter() - t0 >= time_limit:
                return Outcome(Status.TIME_LIMIT, stats=stats)  # the LP took the budget
        budget()
        with watch():
            res = opt.solve(m)
        tc = res.termination_condition
        stats["highs_status"] = tc.name
        bound = res.best_objective_bound
        bound = None if bound is None or not math.isfinite(bound) else float(bound)
        status = _status(tc)
        if status is Status.ERROR:
            stats["error"] = "HiGHS reported an error"
        if status in (Status.INFEASIBLE, Status.ERROR):
            return Outcome(status, stats=stats)
        incumbent = res.best_feasible_objective
        if incumbent is None or not math.isfinite(incumbent):
            return Outcome(Status.TIME_LIMIT, None, None, bound, stats)
        prim = res.solution_loader.get_primals(list(m.x.values()))
        values = np.array([prim[v] for v in m.x.values()], dtype=float)
        if status is not Status.OPTIMAL:
            status = Status.FEASIBLE  # stopped with an incumbent
        return Outcome(status, values, float(incumbent), bound, stats)


def _status(tc: Any) -> Status:
    """HiGHS' termination condition (Pyomo APPSI) in the project's vocabulary.

    Conditions not in the table stopped the solve without a decision (time limit,
    interrupt, ...): TIME_LIMIT, or FEASIBLE when there is an incumbent.
    """
    from pyomo.contrib.appsi.base import TerminationCondition as TC  # heavy module: Pyomo

    table = {
        TC.optimal: Status.OPTIMAL,
        TC.infeasible: Status.INFEASIBLE,
        TC.infeasibleOrUnbounded: Status.INFEASIBLE,
        TC.error: Status.ERROR,
    }
    return table.get(tc, Status.TIME_LIMIT)


@solver(
    "mip",
    Option("lp_check", "bool", "reject a horizon when its LP relaxation is infeasible"),
    Option("max_horizon", "int", "largest horizon tried (none: a safe cap)", low=1, optional=True),
)
def solve(
    instance: Instance,
    *,
    time_limit: float | None = None,
    seed: int = 0,
    objective: str = "soc",
    lp_check: bool = True,
    max_horizon: int | None = None,
) -> Result:
    """Optimal MAPF/TAPF plan from the time-expanded MIP (Pyomo + HiGHS).

    ``lp_check`` solves each horizon's LP relaxation first and skips the horizon when it
    is infeasible. ``max_horizon`` caps the horizon search (default: makespan lower
    bound + free vertices + agents); reaching it returns TIME_LIMIT. INFEASIBLE comes
    from the quick checks or the horizon bound ``makespan_upper_bound`` (see
    ``formulations/mip.md``).

    Example
    -------
    >>> from hierplan_opt.core.graph import Graph
    >>> inst = Instance.tapf(Graph.grid(3, 3), [([(0, 0), (2, 2)], [(0, 2), (2, 0)])])
    >>> r = solve(inst, cost="makespan")
    >>> r.status.value, r.cost
    ('OPTIMAL', 2)
    """
    return solve_with(
        MipBackend(lp_check),
        instance,
        objective=objective,
        time_limit=time_limit,
        seed=seed,
        max_horizon=max_horizon,
    )
