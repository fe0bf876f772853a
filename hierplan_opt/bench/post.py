"""``hierplan bench post``: MAPF-POST sizes and times, graph method vs LP.

Plans: ECBS (``solve(inst, "ecbs", w=...)``) when that solver is
available, else prioritized planning with a space-time A* written here (every plan is
checked with :func:`hierplan_opt.validate`). For each number of robots the table
gives the TPG/STN sizes and the median over repeats of: building TPG+STN, the earliest
schedule (graph method), the LP for minimum makespan with the direct HiGHS back end
on the exactly projected STN (``lp``) and, side by side, on the STN with chains merged
only (``chains``, the earlier reduction), the same LP (up to ``--pyomo-max`` robots)
with Pyomo + appsi_highs, and (up to ``--safety-max`` robots) the max-safety LP.
"""

from __future__ import annotations

import logging
import statistics
import time
from collections.abc import Callable
from pathlib import Path
from typing import TypeVar

from hierplan_opt.api import solve
from hierplan_opt.bench import BenchParser, time_limit
from hierplan_opt.core.errors import InputError
from hierplan_opt.core.instance import Instance
from hierplan_opt.core.plan import Plan
from hierplan_opt.core.validate import validate

log = logging.getLogger(__name__)

T = TypeVar("T")

DEFAULT_MAP = "instances/movingai/warehouse-10-20-10-2-1.map"
DEFAULT_SCEN = "instances/movingai/warehouse-10-20-10-2-1-even-1.scen"


# ---------------------------------------------------------------------- plans
def prioritized_plan(
    instance: Instance, *, max_time: int | None = None, max_expansions: int = 300_000
) -> Plan | None:
    """A valid plan by prioritized planning (agents in index order), or None.

    Each robot takes a shortest path that avoids every conflict with the robots planned
    before it (their cells, swaps and parked goals; it parks at its goal only if no
    earlier robot passes there later): the space-time search of
    :func:`~hierplan_opt.search.focal.focal_path` with ``avoid=True``. Gives up (None)
    when a robot needs more than ``max_expansions`` expansions.

    Example
    -------
    >>> from hierplan_opt.core.graph import Graph
    >>> g = Graph.grid(3, 3)
    >>> inst = Instance.mapf(g, [(0, 0), (2, 0)], [(2, 0), (0, 0)])
    >>> from hierplan_opt.core.validate import validate
    >>> validate(inst, prioritized_plan(inst))
    []
    """
    from hierplan_opt.search.constraints import AgentConstraints
    from hierplan_opt.search.focal import focal_path
    from hierplan_opt.search.reservations import Reservations

    g = instance.graph
    goals = instance.goals
    g.precompute_distances(goals)
    if max_time is None:
        max_time = 2 * max(g.dist(s, x) for s, x in zip(instance.starts, goals, strict=True)) + 200
    res = Reservations(g.n)
    free = AgentConstraints()
    paths: list[tuple[int, ...]] = []
    for i, (s, goal) in enumerate(zip(instance.starts, goals, strict=True)):
        if res.park_t[s] <= 0 or res.vt.get(s):  # an earlier robot sits on this start
            return None
        out = focal_path(
            g.adj,
            s,
            goal,
            g.dist_list(goal),
            free,
            res,
            max_t=max_time,
            budget=-1,
            avoid=True,
            limit=max_expansions,
        )
        if out is None:
            return None
        res.add(i, out[0])
        paths.append(out[0])
    plan = Plan.from_paths(paths)
    bad = validate(instance, plan)  # as every solve is checked (api.solve)
    if bad:
        raise RuntimeError(f"prioritized planning made an invalid plan: {bad[0]}")
    return plan


def make_plan(instance: Instance, *, w: float = 1.5, time_limit: float = 120.0) -> tuple[Plan, str]:
    """An ECBS plan if the ECBS solver is available and succeeds, else prioritized."""

    try:
        res = solve(instance, "ecbs", time_limit=time_limit, w=w)
        if res.plan is not None and not validate(instance, res.plan):
            return res.plan, f"ecbs(w={w})"
        log.info("ECBS gave no plan (%s); using prioritized planning", res.status)
    except Exception as exc:  # the ECBS solver may not exist yet
        log.info("ECBS unavailable (%s); using prioritized planning", exc)
    plan = prioritized_plan(instance)
    if plan is None:
        raise RuntimeError("prioritized planning failed")
    bad = validate(instance, plan)
    if bad:
        raise RuntimeError(f"prioritized plan invalid: {bad[0]}")
    return plan, "prioritized"


# ---------------------------------------------------------------------- bench
def _median_time(fn: Callable[[], T], repeats: int) -> tuple[float, T]:
    times: list[float] = []
    outs: list[T] = []
    for _ in range(max(1, repeats)):
        t0 = time.perf_counter()
        outs.append(fn())
        times.append(time.perf_counter() - t0)
    return statistics.median(times), outs[-1]


def main(argv: list[str] | None = None) -> int:
    from hierplan_opt.bench.fleet import fleet_row
    from hierplan_opt.io.movingai import load_map, load_scen
    from hierplan_opt.schedule import build_stn, build_tpg, solve_graph, solve_lp

    ap = BenchParser(
        "post",
        (__doc__ or "").split("\n\n")[0],
        instance="a bundled MovingAI scenario (default warehouse-10-20-10-2-1-even-1)",
        quick="50 and 100 robots, one repeat",
        time_limit="seconds per ECBS plan (default 120)",
    )
    ap.add_argument("--map", default=DEFAULT_MAP, help="map file (with --scen)")
    ap.add_argument("--scen", default=DEFAULT_SCEN, help="scenario file (with --map)")
    ap.add_argument(
        "--agents",
        help="comma-separated robot counts (default 50,100,200,300,450; the warehouse "
        "scenario has 450)",
    )
    ap.add_argument("--repeats", type=int, help="repeats per timing (default 3, --quick 1)")
    ap.add_argument("--w", type=float, default=1.5, help="ECBS suboptimality bound")
    ap.add_argument("--pyomo-max", type=int, default=100, help="largest K for the Pyomo LP")
    ap.add_argument(
        "--safety-max", type=int, default=300, help="largest K for the max-safety LP (1 run)"
    )
    ap.add_argument("--planner", choices=("auto", "prioritized"), default="auto")
    ap.add_argument("--cache", metavar="DIR", help="keep plans in DIR and reuse them")
    ap.add_argument(
        "--fleet", type=int, help="robots of the fleet row (0: none; default 1000, --quick 0)"
    )
    args = ap.parse_args(argv)
    args.time_limit = time_limit(args.time_limit, False, full=120.0)
    args.repeats = args.repeats or (1 if args.quick else 3)
    agents = args.agents or ("50,100" if args.quick else "50,100,200,300,450")

    from hierplan_opt.experiments.data import instances_dir, movingai_files  # shipped

    def shipped(name: str) -> Path:  # DEFAULT_MAP / DEFAULT_SCEN start with "instances/"
        return Path(name) if Path(name).exists() else instances_dir() / name.split("/", 1)[-1]

    map_path, scen_path = shipped(args.map), shipped(args.scen)
    if args.instance:
        if len(args.instance) != 1:
            ap.error("--instance takes one scenario")
        map_path, scen_path = movingai_files(args.instance[0].removesuffix(".scen"))
    graph = load_map(str(map_path))
    try:
        counts = [int(x) for x in agents.split(",") if x]
    except ValueError:
        raise InputError(f"--agents expects comma-separated numbers, got {agents!r}") from None
    header = (
        f"{'K':>4} {'planner':>12} {'SOC':>7} {'nodes':>7} {'arcs':>7} {'type2':>6} "
        f"{'build':>7} {'graph':>7} {'lp':>7} {'lp/gr':>6} {'chains':>7} {'ch/gr':>6} "
        f"{'pyomo':>7} {'safety':>7} "
        f"{'makespan':>9} {'lp_mk':>9} {'R*':>6}"
    )
    title = f"MAPF-POST on {map_path.name} + {scen_path.name}: medians of {args.repeats} runs, s"
    print(title)
    print(header)
    for k in counts:
        try:
            inst = load_scen(str(scen_path), graph, agents=k)
        except InputError as exc:
            print(f"{k:>4} skipped: {exc}")
            continue
        t0 = time.perf_counter()
        cached = None
        if args.cache:
            Path(args.cache).mkdir(parents=True, exist_ok=True)
            cached = Path(args.cache) / f"{scen_path.stem}-{k}-{args.planner}-w{args.w}.yaml"
        if cached is not None and cached.exists():
            from hierplan_opt.io import load_plan

            plan = load_plan(cached, inst)
            planner = "cached"
        elif args.planner == "prioritized":
            plan = prioritized_plan(inst)
            planner = "prioritized"
            if plan is None:
                print(f"{k:>4} prioritized planning failed")
                continue
        else:
            plan, planner = make_plan(inst, w=args.w, time_limit=args.time_limit)
        if cached is not None and not cached.exists():
            from hierplan_opt.io import save_plan

            save_plan(cached, inst, plan)
        log.info("plan for %d robots by %s in %.1f s", k, planner, time.perf_counter() - t0)

        def build(inst=inst, plan=plan):
            tpg = build_tpg(inst, plan)  # MovingAI agents: point robots
            return build_stn(inst, tpg)

        t_build, stn = _median_time(build, args.repeats)
        t_graph, gsol = _median_time(lambda stn=stn: solve_graph(stn), args.repeats)
        t_lp, lp = _median_time(
            lambda stn=stn: solve_lp(stn, "makespan", backend="highs"), args.repeats
        )
        t_ch, lp_ch = _median_time(
            lambda stn=stn: solve_lp(stn, "makespan", backend="highs", reduction="chains"),
            args.repeats,
        )
        assert abs(lp.makespan - gsol.makespan) < 1e-6 * max(1, gsol.makespan)
        assert abs(lp_ch.makespan - gsol.makespan) < 1e-6 * max(1, gsol.makespan)
        if k <= args.pyomo_max:
            t_py, lp_py = _median_time(
                lambda stn=stn: solve_lp(stn, "makespan", backend="pyomo"), 1
            )
            assert abs(lp_py.makespan - gsol.makespan) < 1e-6 * max(1, gsol.makespan)
            py = f"{t_py:7.3f}"
        else:
            py = f"{'-':>7}"
        if k <= args.safety_max:
            t_safe, safe = _median_time(lambda stn=stn: solve_lp(stn, "safety", backend="highs"), 1)
            sf, rs = f"{t_safe:7.3f}", f"{safe.R:6.3f}"
        else:
            sf, rs = f"{'-':>7}", f"{'-':>6}"
        graph_total = t_build + t_graph
        print(
            f"{k:>4} {planner:>12} {plan.sum_of_costs:>7} {stn.num_nodes:>7} {stn.num_arcs:>7} "
            f"{stn.tpg.num_type2:>6} {t_build:7.3f} {t_graph:7.3f} {t_lp:7.3f} "
            f"{(t_build + t_lp) / graph_total:6.1f} {t_ch:7.3f} "
            f"{(t_build + t_ch) / graph_total:6.1f} {py} {sf} "
            f"{gsol.makespan:9.3f} {lp.makespan:9.3f} {rs}"
        )
    fleet = args.fleet if args.fleet is not None else (0 if args.quick else 1000)
    if fleet:
        print(fleet_row(graph, fleet, args.repeats))
    print(
        "build = TPG + STN; graph = earliest schedule + latest times + critical path; "
        "lp = makespan LP via HiGHS direct on the projected STN; lp/gr = (build+lp)/(build+graph); "
        "chains = same LP with chains merged only (the earlier reduction); "
        "pyomo = same LP via Pyomo+appsi_highs (1 run); safety = max-safety LP via HiGHS "
        "direct (2 stages, 1 run); R* = 1 / slowest piece speed"
    )
    return 0
