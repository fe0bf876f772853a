"""The front door of MAPF-POST: ``postprocess(instance, plan, ...) -> Schedule``."""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Mapping

import numpy as np

from hierplan_opt.core.errors import InputError, OptionError
from hierplan_opt.core.instance import Instance
from hierplan_opt.core.plan import Plan
from hierplan_opt.core.validate import validate
from hierplan_opt.schedule.output import Schedule, build_schedule
from hierplan_opt.schedule.replay import guaranteed_distance, plan_geometry, speed_range
from hierplan_opt.schedule.solve_graph import solve_graph
from hierplan_opt.schedule.solve_lp import BACKENDS, solve_lp
from hierplan_opt.schedule.stn import build_stn
from hierplan_opt.schedule.tpg import build_tpg

log = logging.getLogger(__name__)

OBJECTIVES = ("makespan", "safety", "flowtime")
METHODS = ("graph", "lp")
#: Default marker distance as a fraction of the shortest move of the plan.
DEFAULT_DELTA_FRACTION = 0.25


def _moves(instance: Instance, plan: Plan) -> tuple[np.ndarray, np.ndarray]:
    """Every move (u != v) of the plan as two arrays of vertex ids."""
    us, vs = [], []
    for p in plan.paths:
        a = np.asarray(p, dtype=np.int64)
        mv = a[1:] != a[:-1]
        us.append(a[:-1][mv])
        vs.append(a[1:][mv])
    if not us:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    return np.concatenate(us), np.concatenate(vs)


def _shortest_move(instance: Instance, plan: Plan) -> tuple[float, int, int]:
    g = instance.graph
    us, vs = _moves(instance, plan)
    if not len(us):
        return math.inf, -1, -1
    scale = g.cell_size if g.kind == "grid" else 1.0
    geo = np.linalg.norm((g.coords[vs] - g.coords[us]) * scale, axis=1)
    k = int(np.argmin(geo))
    return float(geo[k]), int(us[k]), int(vs[k])


def default_delta(instance: Instance, plan: Plan) -> float:
    """A quarter of the shortest move of the plan (metres); 0 if no robot moves.

    Example
    -------
    >>> from hierplan_opt.core.graph import Graph
    >>> g = Graph.grid(3, 1, cell_size=2.0)
    >>> default_delta(Instance.mapf(g, [(0, 0)], [(2, 0)]), Plan.from_paths([[0, 1, 2]]))
    0.5
    """
    shortest, _, _ = _shortest_move(instance, plan)
    return 0.0 if not math.isfinite(shortest) else DEFAULT_DELTA_FRACTION * shortest


def postprocess(
    instance: Instance,
    plan: Plan,
    objective: str = "makespan",
    *,
    delta: float | None = None,
    method: str = "graph",
    epsilon: float = 0.0,
    acceleration: bool = True,
    deadlines: Mapping[str | int, float] | None = None,
    lp_backend: str = "auto",
    time_limit: float | None = None,
    check_plan: bool = True,
) -> Schedule:
    """Turn a valid discrete plan into an execution schedule (MAPF-POST).

    Parameters
    ----------
    instance, plan
        The plan must pass :func:`hierplan_opt.validate` (else :class:`InputError`
        naming the first violation).
    objective : {"makespan", "safety", "flowtime"}
        ``makespan`` works with both methods; ``safety`` (maximise the slowest speed,
        then minimise makespan) and ``flowtime`` (sum of arrival times) need
        ``method="lp"``.
    delta : float, optional
        Safety-marker distance in metres (grid cells times ``cell_size``); 0 builds the
        plain TPG without markers. Default: a quarter of the plan's shortest move.
        Must be below half of the shortest move, or the markers of that move cross.
    method : {"graph", "lp"}
        ``graph``: earliest schedule by longest paths (Bellman-Ford with deadlines).
        ``lp``: the LP for ``objective`` (Pyomo or direct HiGHS, see ``lp_backend``).
    epsilon : float
        Lower bound of Type-2 arcs (seconds).
    acceleration : bool
        Use the acceleration-aware bound for robots whose kinematics give ``a_max``.
    deadlines : mapping, optional
        Agent name (or index) -> latest arrival time at its final vertex.
    lp_backend : {"auto", "pyomo", "highs"}
    time_limit : float, optional
        Passed to HiGHS (LP method).
    check_plan : bool
        Run the validator first (default). Pass False only for a plan that was
        just validated (e.g. from :func:`hierplan_opt.solve`); it saves ~0.7 s at 300
        robots on the warehouse map.

    Example
    -------
    >>> from hierplan_opt.core.graph import Graph
    >>> g = Graph.grid(3, 3, obstacles=[(0, 0), (2, 0), (0, 2), (2, 2)])
    >>> inst = Instance.mapf(g, [(0, 1), (1, 0)], [(2, 1), (1, 2)])
    >>> v = g.vertex
    >>> plan = Plan.from_paths([[v((0, 1)), v((1, 1)), v((2, 1))],
    ...                         [v((1, 0)), v((1, 0)), v((1, 1)), v((1, 2))]])
    >>> s = postprocess(inst, plan, delta=0.25)
    >>> s.makespan, s.arrival_times("agent1").tolist()
    (2.5, [0.0, 1.25, 1.5, 2.5])
    """
    t_start = time.perf_counter()
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
    violations = validate(instance, plan) if check_plan else []
    if violations:
        more = f" (and {len(violations) - 1} more)" if len(violations) > 1 else ""
        raise InputError(f"the plan is invalid: {violations[0]}{more}")

    shortest, su, sv = _shortest_move(instance, plan)
    if delta is None:
        delta = 0.0 if not math.isfinite(shortest) else DEFAULT_DELTA_FRACTION * shortest
    if (
        isinstance(delta, bool)
        or not isinstance(delta, (int, float, np.floating))
        or not math.isfinite(delta)
        or delta < 0
    ):
        raise InputError(f"delta must be a finite number >= 0, got {delta!r}")
    delta = float(delta)
    if delta > 0 and delta >= shortest / 2:
        g = instance.graph
        raise InputError(
            f"delta = {delta:g} is too large: it must be below half the shortest move of "
            f"the plan ({_loc(g, su)} -> {_loc(g, sv)}, length {shortest:g}), or the "
            "safety markers on that move cross"
        )

    t0 = time.perf_counter()
    tpg = build_tpg(instance, plan, delta)
    t1 = time.perf_counter()
    stn = build_stn(instance, tpg, epsilon=epsilon, acceleration=acceleration, deadlines=deadlines)
    t2 = time.perf_counter()
    gsol = solve_graph(stn)
    t3 = time.perf_counter()
    stats: dict = {
        "tpg_nodes": tpg.num_nodes,
        "tpg_arcs": tpg.num_arcs,
        "type2_arcs": tpg.num_type2,
        "stn_arcs": stn.num_arcs,
        "tpg_time": t1 - t0,
        "stn_time": t2 - t1,
        "graph_time": t3 - t2,
        "graph_makespan": gsol.makespan,
    }
    R = None
    if method == "graph":
        times = gsol.earliest
    else:
        lp = solve_lp(stn, objective, backend=lp_backend, time_limit=time_limit)
        times = lp.times
        R = lp.R
        stats["lp_backend"] = lp.backend
        stats["lp_objective"] = lp.objective_value
        stats.update(lp.stats)
        if objective == "makespan" and abs(lp.makespan - gsol.makespan) > 1e-6 * max(
            1.0, gsol.makespan
        ):
            log.warning(
                "LP makespan %.9g differs from the graph makespan %.9g",
                lp.makespan,
                gsol.makespan,
            )
    if R is not None:
        stats["R"] = R
        stats["min_speed_bound"] = 1.0 / R if R > 0 else math.inf
    g = instance.graph
    scale = g.cell_size if g.kind == "grid" else 1.0
    schedule = build_schedule(
        stn,
        np.array(times, dtype=float),
        np.array(gsol.earliest, dtype=float),
        np.array(gsol.latest, dtype=float),
        gsol.critical_path,
        objective=objective,
        method=method,
        scale=scale,
        stats=stats,
    )
    geometry = plan_geometry(instance, tpg)
    v_slow, v_fast = speed_range(schedule)
    safety = guaranteed_distance(delta, geometry, v_slow, v_fast)
    stats.update(
        {
            "v_slow": v_slow if math.isfinite(v_slow) else None,
            "v_fast": v_fast,
            "clearance": geometry.clearance,
            "angle_factor": geometry.angle_factor,
            "total_time": time.perf_counter() - t_start,
        }
    )
    # Schedule is frozen: rebuild with the safety distance and the final stats.
    from dataclasses import replace

    return replace(schedule, safety_distance=safety, stats=stats)


def _loc(g, v: int) -> str:  # noqa: ANN001
    loc = g.location(v)
    return repr(loc) if isinstance(loc, str) else "(" + ", ".join(map(str, loc)) + ")"
