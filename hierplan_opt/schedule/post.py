"""The front door of MAPF-POST: ``postprocess(instance, plan, ...) -> Schedule``.

The steps, each a function below: check the arguments and the plan, build the temporal
plan graph with markers from the robots' radii (:func:`build_tpg`), its simple temporal
network (:func:`build_stn`), the node times (earliest times by graph passes, or an LP),
their windows and critical path, and the :class:`Schedule`, built once. The schedule is
not checked here: :func:`hierplan_opt.schedule.replay` is the independent check the tests
and ``hierplan post --check`` run.
"""

from __future__ import annotations

import logging
import time
import warnings
from collections.abc import Mapping
from typing import Any

import numpy as np

from hierplan_opt.core.errors import InputError, OptionError
from hierplan_opt.core.instance import Instance
from hierplan_opt.core.plan import Plan
from hierplan_opt.core.progress import tick
from hierplan_opt.core.validate import validate
from hierplan_opt.schedule.clearance import default_margin, finite_nonnegative
from hierplan_opt.schedule.output import Schedule, build_schedule, plan_tree
from hierplan_opt.schedule.solve_graph import critical_path, earliest_times, windows
from hierplan_opt.schedule.solve_lp import BACKENDS, solve_lp
from hierplan_opt.schedule.stn import STN, build_stn
from hierplan_opt.schedule.tpg import TPG, build_tpg

log = logging.getLogger(__name__)

OBJECTIVES = ("makespan", "safety", "flowtime")
METHODS = ("graph", "lp")


def postprocess(
    instance: Instance,
    plan: Plan,
    objective: str = "makespan",
    *,
    margin: float | None = None,
    clearance: bool = True,
    method: str = "graph",
    epsilon: float = 0.0,
    acceleration: bool = True,
    deadlines: Mapping[str | int, float] | None = None,
    lp_backend: str = "auto",
    time_limit: float | None = None,
    check_plan: bool = True,
    delta: float | None = None,
) -> Schedule:
    """Turn a valid discrete plan into an execution schedule (MAPF-POST).

    The schedule keeps the centres of robots ``i`` and ``j`` at least
    ``r_i + r_j + margin`` apart at every moment, in any motion that passes the
    way-points in the order of the temporal plan graph (radii from the robots'
    kinematics). A plan whose geometry cannot give that distance is refused with a
    :class:`~hierplan_opt.schedule.clearance.ClearanceError` naming the robots, their
    types and the cell size.

    Parameters
    ----------
    instance, plan
        The plan must pass :func:`hierplan_opt.validate` (else :class:`InputError`
        naming the first violation).
    objective : {"makespan", "safety", "flowtime"}
        ``makespan`` works with both methods; ``safety`` (maximise the slowest speed,
        then minimise makespan) and ``flowtime`` (sum of arrival times) need
        ``method="lp"``.
    margin : float, optional
        Extra clearance in metres on top of the two radii. Default
        (:func:`~hierplan_opt.schedule.clearance.default_margin`): 0.1 x the shortest
        edge when at least two robots are points (radius 0), else 0; pass 0 for
        point robots that may come arbitrarily close (but never onto one point).
    clearance : bool
        False: order of the plan only (plain temporal plan graph), no distance
        guarantee; :attr:`Schedule.clearance` then says which robot types lose it.
    method : {"graph", "lp"}
        ``graph``: earliest schedule by longest paths. ``lp``: the LP for
        ``objective`` (Pyomo or direct HiGHS, see ``lp_backend``).
    epsilon : float
        Lower bound of Type-2 arcs (seconds).
    acceleration : bool
        Use the acceleration-aware bounds for robots whose kinematics give ``a_max``.
    deadlines : mapping, optional
        Agent name (or index) -> latest arrival time at its final vertex.
    lp_backend : {"auto", "pyomo", "highs"}
    time_limit : float, optional
        Passed to HiGHS (LP method).
    check_plan : bool
        Run the validator first (default). Pass False only for a plan that was
        just validated (e.g. from :func:`hierplan_opt.solve`).
    delta : float, optional
        Deprecated name of ``margin``.

    Example
    -------
    >>> from hierplan_opt import Graph
    >>> inst = Instance.mapf(Graph.grid(4, 1), [(1, 0), (0, 0)], [(3, 0), (2, 0)])
    >>> plan = Plan.from_paths([[1, 2, 3], [0, 1, 2]])  # agent1 follows agent0
    >>> s = postprocess(inst, plan, margin=0.5)  # point robots kept 0.5 m apart
    >>> s.arrival_times("agent1").round(6).tolist(), s.safety_distance
    ([0.0, 0.75, 1.5, 1.75, 2.5], 0.5)
    """
    t_start = time.perf_counter()
    margin = _check_arguments(instance, plan, objective, method, lp_backend, margin, delta)
    if margin is None:
        margin = default_margin(instance)
    _check_plan(instance, plan, check_plan)
    t0 = time.perf_counter()
    tpg = build_tpg(instance, plan, margin, clearance=clearance)
    t1 = time.perf_counter()
    tick("steps", 1, 3, step="STN", tpg_nodes=tpg.num_nodes)
    stn = build_stn(instance, tpg, epsilon=epsilon, acceleration=acceleration, deadlines=deadlines)
    t2 = time.perf_counter()
    tick("steps", 2, 3, step=f"{method} {objective}", stn_arcs=stn.num_arcs)
    earliest = earliest_times(stn)  # also the consistency check (InconsistentSTNError)
    times, lp_stats = _times(stn, earliest, objective, method, lp_backend, time_limit)
    t3 = time.perf_counter()
    tick("steps", 3, 3, step="done", lp_time=lp_stats.get("lp_time"))
    early, late = windows(stn, times, earliest=earliest)
    crit = critical_path(stn, times)
    t4 = time.perf_counter()
    stats = _stats(tpg, stn, earliest, lp_stats)
    stats.update(
        {
            "tpg_time": t1 - t0,
            "stn_time": t2 - t1,
            "solve_time": t3 - t2,
            "window_time": t4 - t3,
            "total_time": time.perf_counter() - t_start,
        }
    )
    g = instance.graph
    req = tpg.requirement
    settings: dict[str, Any] = {
        "objective": objective,
        "method": method,
        "margin": req.margin,
        "clearance": bool(clearance),
        "acceleration": bool(acceleration),
        "epsilon": float(epsilon),
        "radii": {a.name: float(a.kinematics.radius) for a in instance.agents},
    }
    if deadlines:
        settings["deadlines"] = {
            (instance.agents[k].name if isinstance(k, int) else str(k)): float(v)
            for k, v in deadlines.items()
        }
    if method == "lp":
        settings["lp_backend"] = lp_stats.get("lp_backend", lp_backend)
    return build_schedule(
        stn,
        times,
        early,
        late,
        crit,
        objective=objective,
        method=method,
        scale=g.scale,
        safety_distance=req.guaranteed_distance(),
        margin=req.margin,
        clearance=req.report(),
        stats=stats,
        plan=plan,
        settings=settings,
        plan_rows=plan_tree(instance, plan),
    )


# ---------------------------------------------------------------------- steps
def _check_arguments(
    instance: Instance,
    plan: Plan,
    objective: str,
    method: str,
    lp_backend: str,
    margin: float | None,
    delta: float | None,
) -> float | None:
    """Validate the arguments; returns the margin (``delta`` is its old name; None:
    the default)."""
    if not isinstance(instance, Instance):
        raise InputError(f"postprocess needs an Instance, got {type(instance).__name__}")
    if not isinstance(plan, Plan):
        raise InputError(f"postprocess needs a Plan, got {type(plan).__name__}")
    if objective not in OBJECTIVES:
        raise OptionError(f"unknown objective {objective!r} (use {', '.join(OBJECTIVES)})")
    if method not in METHODS:
        raise OptionError(f"unknown method {method!r} (use {', '.join(METHODS)})")
    if method == "graph" and objective != "makespan":
        raise OptionError(
            f"objective {objective!r} needs method='lp' (the graph method computes the "
            "earliest schedule, which minimises makespan)"
        )
    if lp_backend not in BACKENDS:
        raise OptionError(f"unknown lp_backend {lp_backend!r} (use {', '.join(BACKENDS)})")
    if delta is not None:
        warnings.warn(
            "postprocess(delta=...) is deprecated: markers now follow the robots' radii; "
            "use margin= for extra clearance",
            DeprecationWarning,
            stacklevel=3,
        )
        if margin:
            raise OptionError("give margin or its old name delta, not both")
        margin = delta
    if margin is None:
        return None
    return finite_nonnegative(
        margin, f"margin must be a finite number >= 0 (metres), got {margin!r}"
    )


def _check_plan(instance: Instance, plan: Plan, check: bool) -> None:
    violations = validate(instance, plan) if check else []
    if violations:
        more = f" (and {len(violations) - 1} more)" if len(violations) > 1 else ""
        raise InputError(f"the plan is invalid: {violations[0]}{more}")


def _times(
    stn: STN,
    earliest: np.ndarray,
    objective: str,
    method: str,
    lp_backend: str,
    time_limit: float | None,
) -> tuple[np.ndarray, dict[str, Any]]:
    """Node times: the earliest schedule, or the LP's."""
    if method == "graph":
        return earliest, {}
    lp = solve_lp(stn, objective, backend=lp_backend, time_limit=time_limit)
    out: dict[str, Any] = {"lp_backend": lp.backend, "lp_objective": lp.objective_value}
    out.update(lp.stats)
    if lp.R is not None:
        out["R"] = lp.R
        if lp.R > 0:
            out["min_speed_bound"] = 1.0 / lp.R
    # The LP's times meet every bound within HiGHS's tolerance, which can put a robot's
    # last arrival a few 1e-9 s before the earliest possible one (the safety LP on a 3D
    # grid did); the windows then see a horizon nobody can meet. The pointwise maximum of
    # two solutions of difference constraints is a solution, so lifting the LP's times
    # to the earliest ones keeps every STN bound and only moves round-off.
    return np.maximum(lp.times, earliest), out


def _stats(tpg: TPG, stn: STN, earliest: np.ndarray, extra: dict[str, Any]) -> dict[str, Any]:
    stats: dict[str, Any] = {
        "tpg_nodes": tpg.num_nodes,
        "tpg_arcs": tpg.num_arcs,
        "type2_arcs": tpg.num_type2,
        "stn_arcs": stn.num_arcs,
        "regime": tpg.regime,
        "earliest_makespan": float(earliest[tpg.final_nodes()].max()),
    }
    stats.update(extra)
    return stats
