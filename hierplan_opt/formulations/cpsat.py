"""Time-expanded CP-SAT model with OR-Tools (``solver="cpsat"``).

Mathematics: ``formulations/cpsat.md``. One Boolean per arc of the pruned
:class:`~hierplan_opt.formulations.time_expanded.TimeExpandedNetwork`; per agent and
time exactly one arc (per team: as many arcs as robots); at most one robot entering a
vertex at a time; flow conservation (successor and predecessor clauses); at most one
of two opposite moves over an edge (swap). The model is a reduction: :func:`build` gives
``(model, index)``, :func:`extract` the plan of a solution's arc values.

CP-SAT runs ``workers`` parallel search workers (2 suit this project's 2-core machines),
``seed`` fixes its random seed, and a known plan (from an earlier horizon, or from the
``hint`` solver, e.g. ``"ecbs"``) becomes a solution hint.

Example
-------
>>> from hierplan_opt.core.graph import Graph
>>> from hierplan_opt.core.instance import Instance
>>> pocket = Graph.grid(4, 2, obstacles=[(0, 1), (2, 1), (3, 1)])  # one side pocket
>>> r = solve(Instance.mapf(pocket, [(0, 0), (3, 0)], [(3, 0), (0, 0)]), time_limit=30)
>>> r.status.value, r.cost == r.lower_bound
('OPTIMAL', True)
"""

from __future__ import annotations

import logging
import time
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from hierplan_opt import registry
from hierplan_opt.core.instance import Instance
from hierplan_opt.core.options import Option
from hierplan_opt.core.plan import Plan
from hierplan_opt.core.progress import active
from hierplan_opt.core.result import Result, Status
from hierplan_opt.core.validate import validate
from hierplan_opt.formulations.horizon import Outcome, fold_seed, solve_with
from hierplan_opt.formulations.memory import memory_budget
from hierplan_opt.formulations.time_expanded import TimeExpandedNetwork
from hierplan_opt.registry import solver

log = logging.getLogger(__name__)


@dataclass
class CpSatIndex:
    """Where the model's variables live: the network and the Boolean of each arc and y."""

    network: TimeExpandedNetwork
    x: list[Any]  # one cp_model Boolean per arc id
    y: list[Any]  # goal-reached indicators (sum of costs only)


def build(
    instance: Instance,
    horizon: int,
    objective: str = "makespan",
    *,
    deadlines: Sequence[int] | None = None,
    prune: bool = True,
) -> tuple[Any, CpSatIndex]:
    """The CP-SAT model of ``instance`` at ``horizon`` and its :class:`CpSatIndex`.

    Example
    -------
    >>> from hierplan_opt.core.graph import Graph
    >>> inst = Instance.mapf(Graph.grid(3, 1), [(0, 0)], [(2, 0)])
    >>> model, index = build(inst, 2)
    >>> len(index.x) == index.network.num_arcs
    True
    """
    net = TimeExpandedNetwork.build(instance, horizon, deadlines=deadlines, prune=prune)
    return model_of(net, objective)


def model_of(net: TimeExpandedNetwork, objective: str) -> tuple[Any, CpSatIndex]:
    """The CP-SAT model and index of an already built network."""
    from ortools.sat.python import cp_model  # heavy module: OR-Tools

    m = cp_model.CpModel()
    k, u, v, t = (a.tolist() for a in (net.arc_k, net.arc_u, net.arc_v, net.arc_t))
    x = [m.new_bool_var(f"x[{k[i]},{u[i]},{v[i]},{t[i]}]") for i in range(net.num_arcs)]

    def arcs(ids: np.ndarray) -> list:
        return [x[i] for i in ids.tolist()]

    # ---- one arc per agent and time (a team: one per robot)
    for kk, c in enumerate(net.commodities):
        for layer in net.layers[kk]:
            if c.units == 1:
                m.add_exactly_one(arcs(layer))
            else:
                m.add(sum(arcs(layer)) == c.units)
    # ---- sources, sinks, and flow conservation (successor/predecessor clauses)
    for outs in net.source_out:
        m.add_exactly_one(arcs(outs))
    for ins in net.sink_in:
        m.add_exactly_one(arcs(ins))
    for ins, outs in net.conservation:
        a_in, a_out = arcs(ins), arcs(outs)
        if not a_out:
            for a in a_in:
                m.add(a == 0)
        elif not a_in:
            for a in a_out:
                m.add(a == 0)
        else:
            m.add(sum(a_in) == sum(a_out))
            for a in a_in:  # entering (v, t) implies leaving it
                m.add_bool_or([*a_out, a.Not()])
            for a in a_out:  # leaving (v, t) implies having entered it
                m.add_bool_or([*a_in, a.Not()])
    # ---- collisions
    for group in net.vertex_groups:
        m.add_at_most_one(arcs(group))
    for group in net.swap_groups:
        m.add_at_most_one(arcs(group))
    for a in net.forbidden.tolist():  # annotated conflicts with a parked robot
        m.add(x[a] == 0)
    # ---- objective
    y: list = []
    if objective == "soc":
        for kk, w in enumerate(net.wait):
            for j, row in enumerate(w):
                nxt = None
                for tt in range(len(row) - 1, -1, -1):
                    if row[tt] < 0:
                        break
                    yv = m.new_bool_var(f"y[{kk},{net.commodities[kk].sinks[j]},{tt}]")
                    m.add_implication(yv, x[int(row[tt])])
                    if nxt is not None:
                        m.add_implication(yv, nxt)
                    y.append(yv)
                    nxt = yv
        m.minimize(net.soc_constant() - sum(y))
    return m, CpSatIndex(net, x, y)


def extract(values: Sequence[float] | np.ndarray, index: CpSatIndex) -> Plan:
    """The plan of arc ``values`` (in arc order) in the model's index."""
    return index.network.plan(values)


def add_hint(model: Any, index: CpSatIndex, plan: Plan) -> bool:
    """Hint every arc (and y) with ``plan``; False if the plan does not fit the network."""
    vals = index.network.arcs_of_plan(plan)
    if vals is None:
        return False
    for var, val in zip(index.x, vals.tolist(), strict=True):
        model.add_hint(var, val)
    if index.y:
        # y[k, g, t] is 1 iff the wait arc at t and all later ones are used.
        net = index.network
        it = iter(index.y)
        for w in net.wait:
            for row in w:
                on = True
                flags = []
                for tt in range(len(row) - 1, -1, -1):
                    if row[tt] < 0:
                        break
                    on = on and bool(vals[int(row[tt])])
                    flags.append(on)
                for f in flags:
                    model.add_hint(next(it), int(f))
    return True


class CpSatBackend:
    """Solves one network with CP-SAT."""

    name = "cpsat"

    def __init__(self, workers: int = 2) -> None:
        self.workers = workers

    def __call__(
        self,
        net: TimeExpandedNetwork,
        objective: str,
        time_limit: float | None,
        hint: Plan | None,
        seed: int,
    ) -> Outcome:
        from ortools.sat.python import cp_model  # heavy module: OR-Tools

        t0 = time.perf_counter()
        model, index = model_of(net, objective)
        stats: dict = {"model_time": time.perf_counter() - t0}
        if time_limit is not None and stats["model_time"] >= time_limit:
            return Outcome(Status.TIME_LIMIT, stats=stats)  # the model took the budget
        if hint is not None:
            stats["hinted"] = add_hint(model, index, hint)
        cp = cp_model.CpSolver()
        p = cp.parameters
        p.num_workers = self.workers
        p.random_seed = fold_seed(seed, -(2**31), 2**31 - 1)  # an int32 in CP-SAT
        p.log_search_progress = False
        # Measured on random-32-32-20 (10 agents): probing in presolve costs far more than
        # it saves on these models (SOC network at slack 4: 31 s at probing level 1, 2 s
        # at level 0), and on the large makespan feasibility networks presolve as a whole
        # does (112 s vs 20-25 s without it), overrunning the time limit (formulations/
        # cpsat.md).
        p.cp_model_probing_level = 0
        # CP-SAT's own memory guard (it stops the search when the process passes it):
        # the budget that the model estimate was checked against (formulations/memory.py)
        p.max_memory_in_mb = max(64, memory_budget() >> 20)
        if objective != "soc":
            p.cp_model_presolve = False
        if time_limit is not None:
            p.max_time_in_seconds = max(0.01, time_limit - (time.perf_counter() - t0))
        code = cp.solve(model, _reporter(cp_model, objective))
        stats["cpsat_status"] = cp.status_name(code)
        stats["conflicts"] = cp.num_conflicts
        status = _status(code)
        if status is Status.ERROR:
            stats["error"] = f"CP-SAT model invalid: {model.validate()}"
        if status in (Status.INFEASIBLE, Status.ERROR):
            return Outcome(status, stats=stats)
        bound = cp.best_objective_bound if objective == "soc" else None
        if status is Status.TIME_LIMIT:
            return Outcome(status, None, None, bound, stats)
        if objective != "soc":
            status = Status.OPTIMAL  # a feasibility model: any solution decides it
        values = np.array([cp.value(var) for var in index.x], dtype=float)
        obj = cp.objective_value if objective == "soc" else 0.0
        return Outcome(status, values, obj, bound, stats)


def _reporter(cp_model: Any, objective: str) -> Any:
    """With ``--progress``: a callback that shows each solution's objective and CP-SAT's
    bound during a long solve (it runs in CP-SAT's thread, so it holds the progress)."""
    progress = active()
    if progress is None or objective != "soc":
        return None

    class Report(cp_model.CpSolverSolutionCallback):
        def on_solution_callback(self) -> None:
            progress.update(objective=self.objective_value, bound=self.best_objective_bound)

    return Report()


def _status(code: Any) -> Status:
    """CP-SAT's solve status in the project's vocabulary (UNKNOWN: stopped undecided)."""
    from ortools.sat.python import cp_model  # heavy module: OR-Tools

    table = {
        cp_model.OPTIMAL: Status.OPTIMAL,
        cp_model.FEASIBLE: Status.FEASIBLE,
        cp_model.INFEASIBLE: Status.INFEASIBLE,
        cp_model.MODEL_INVALID: Status.ERROR,
    }
    return table.get(code, Status.TIME_LIMIT)


@solver(
    "cpsat",
    Option("workers", "int", "CP-SAT's parallel search workers", low=1),
    Option("hint", "solver", "solver whose plan seeds the search (none: no hint)", optional=True),
    Option("max_horizon", "int", "largest horizon tried (none: a safe cap)", low=1, optional=True),
)
def solve(
    instance: Instance,
    *,
    time_limit: float | None = None,
    seed: int = 0,
    objective: str = "soc",
    workers: int = 2,
    hint: str | None = None,
    max_horizon: int | None = None,
) -> Result:
    """Optimal MAPF/TAPF plan from the time-expanded CP-SAT model.

    ``workers`` is CP-SAT's number of parallel workers. ``hint`` names a registered
    solver (e.g. ``"ecbs"``) whose plan seeds the sum-of-costs search: its cost gives the
    slack of the first network and its arcs the solution hint (ignored if that solver is
    not available or fails). ``max_horizon`` caps the horizon search; reaching it returns
    TIME_LIMIT. INFEASIBLE comes from the quick checks or the horizon bound
    ``makespan_upper_bound`` (see ``formulations/mip.md``).

    Example
    -------
    >>> from hierplan_opt.core.graph import Graph
    >>> inst = Instance.tapf(Graph.grid(3, 3), [([(0, 0), (2, 2)], [(0, 2), (2, 0)])])
    >>> r = solve(inst, cost="makespan")
    >>> r.status.value, r.cost
    ('OPTIMAL', 2)
    """
    t0 = time.perf_counter()
    start_plan = _hint_plan(instance, hint, time_limit, seed) if objective == "soc" else None
    used = time.perf_counter() - t0
    return solve_with(
        CpSatBackend(workers),
        instance,
        objective=objective,
        time_limit=None if time_limit is None else max(0.01, time_limit - used),
        seed=seed,
        max_horizon=max_horizon,
        upper_bound_plan=start_plan,
    )


def _hint_plan(
    instance: Instance, hint: str | None, time_limit: float | None, seed: int
) -> Plan | None:
    """A plan from the ``hint`` solver within a quarter of the budget, or None."""
    if hint is None:
        return None
    try:
        res = registry.run(
            hint, instance, time_limit=None if time_limit is None else time_limit / 4, seed=seed
        )
    except Exception as exc:  # a missing or failing hint solver only costs the hint
        log.warning("hint solver %r unavailable: %s", hint, exc)
        return None
    if res.plan is None or not res.solved or validate(instance, res.plan):
        return None
    return res.plan
