"""``hierplan solve``: solve an instance with a registered solver and write the plan."""

from __future__ import annotations

import argparse
import sys
import time
from typing import Any

from hierplan_opt import registry
from hierplan_opt.api import DEFAULT_TIME_LIMIT, solve
from hierplan_opt.cli.common import (
    INFEASIBLE,
    INTERNAL,
    LIMIT,
    OK,
    PLAN_SUFFIXES,
    RESULT_FACTS,
    add_cost_argument,
    add_instance_arguments,
    add_memory_argument,
    add_progress_arguments,
    check_outputs,
    cost_of,
    load_instance_from_args,
    positive_float,
    progress_of,
)
from hierplan_opt.core.errors import InputError, UnknownSolverError
from hierplan_opt.core.options import parse_pairs
from hierplan_opt.core.progress import note
from hierplan_opt.core.result import Status
from hierplan_opt.search.libmrp import disappear_at_goals, from_disappeared

HELP = "solve a MAPF/TAPF instance and write the plan (libMultiRobotPlanning layout)"


def add_arguments(p: argparse.ArgumentParser) -> None:
    add_instance_arguments(p)
    add_memory_argument(p)
    add_progress_arguments(p)
    chosen = ["cbs"]  # the solver whose options --help lists

    class SolverName(argparse.Action):
        def __call__(
            self,
            parser: argparse.ArgumentParser,
            namespace: argparse.Namespace,
            values: Any,
            option_string: str | None = None,
        ) -> None:
            chosen[0] = str(values)
            setattr(namespace, self.dest, values)

    p.add_argument(
        "--solver",
        default=None,
        metavar="NAME",
        action=SolverName,
        help="solver name (default: cbs for MAPF; for TAPF flow with one team, cbm with "
        "more; the choice is printed); `--solver NAME --help` lists its options",
    )
    add_cost_argument(p, "what the plan minimises")
    p.add_argument("--w", type=positive_float, metavar="W", help="suboptimality bound (option w)")
    p.add_argument(
        "--highways",
        metavar="FILE|NAME",
        help="prefer directed edges: a highway file (.yaml, .map.highway grid, .hwy edge list) "
        "or crisscross, corridors, learned, flow, instance (solvers cbs, ecbs, eecbs)",
    )
    p.add_argument(
        "--w-hwy", type=positive_float, metavar="W", help="highway factor (option w_hwy, default 2)"
    )
    p.add_argument(
        "--time-limit",
        type=positive_float,
        default=DEFAULT_TIME_LIMIT,
        metavar="SECONDS",
        help=f"wall-clock limit (default: {DEFAULT_TIME_LIMIT:g})",
    )
    p.add_argument("--seed", type=int, default=0, metavar="N", help="random seed (default: 0)")
    p.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="a solver option (repeatable); booleans are true/false, yes/no or on/off",
    )
    p.add_argument(
        "--disappear-at-goal",
        action="store_true",
        help="agents leave the map when they reach their goals (libMultiRobotPlanning's "
        "--disappear-at-goal; cost counts up to each arrival); the plan's paths end there",
    )
    p.add_argument(
        "--out",
        metavar="PLAN",
        help="write the plan here (.yaml, or .json); only written when a plan is found",
    )
    p.add_argument(
        "--plot",
        metavar="FILE",
        help="also draw the plan (.png/.pdf/.svg); over 40 robots: faint paths, 5 highlighted",
    )
    base_help = p.format_help

    def format_help() -> str:
        return base_help() + "\n" + "\n".join(solver_help(chosen[0])) + "\n"

    p.format_help = format_help  # type: ignore[method-assign]


def solver_help(name: str) -> list[str]:
    """The ``--help`` lines describing solver ``name`` and listing its options.

    Example
    -------
    >>> solver_help("ecbs")[2]
    '  w: number >= 1 and < 1e+09 (default 1.2) -- suboptimality bound: cost <= w * optimum'
    """

    try:
        spec = registry.get(name).load().options
    except UnknownSolverError as exc:
        return [str(exc)]
    head = f"options of solver {name!r} (--set KEY=VALUE; other solvers: --solver NAME --help):"
    what = f"solver {name!r}: {registry.get(name).description}"
    return [what, head] + [f"  {o.describe()}" for o in spec] + ([] if len(spec) else ["  none"])


def summary(result: Any, instance: Any) -> str:
    """The one-line summary ``solve`` prints.

    Example
    -------
    >>> from hierplan_opt import Graph, Instance, Result, Status
    >>> inst = Instance.mapf(Graph.grid(2, 1), [(0, 0)], [(1, 0)])
    >>> summary(Result(Status.TIME_LIMIT, None, lower_bound=7, solver="cbs"), inst)
    'TIME_LIMIT lb=7 gap=- runtime=0.000s solver=cbs objective=soc agents=1'
    """
    parts = [str(result.status)]
    if result.plan is not None:
        parts.append(f"cost={_fmt(result.cost)}")
    parts.append(f"lb={_fmt(result.lower_bound)}")
    gap = result.gap
    parts.append(f"gap={gap:.4f}" if gap is not None else "gap=-")
    if result.plan is not None:
        parts.append(f"soc={result.plan.sum_of_costs} makespan={result.plan.makespan}")
    parts.append(f"runtime={result.runtime:.3f}s")
    parts.append(f"solver={result.solver} objective={result.objective}")
    parts.append(f"agents={instance.num_agents}")
    for k in _ALWAYS:  # why the search stopped and what the plan does not meet: never cut
        if k in result.stats:
            parts.append(f"{k}={_fmt(result.stats[k])}")
    shown = 0
    for k, v in result.stats.items():
        if k == "error" or k in _ALWAYS or shown >= 6:
            continue
        if isinstance(v, (bool, int, float, str)):
            text = _fmt(v) if not isinstance(v, str) else v
            if isinstance(v, str) and (len(v) > 30 or " " in v):
                continue
            parts.append(f"{k}={text}")
            shown += 1
    return " ".join(parts)


#: Stats the summary line always shows when present, before the solver's others.
_ALWAYS = (*RESULT_FACTS, "feasibility", "disappear_at_goal", "free_agents")


def _fmt(x: Any) -> str:
    if x is None:
        return "-"
    if isinstance(x, bool):
        return str(x).lower()
    if isinstance(x, float):
        return str(int(x)) if x.is_integer() else f"{x:.4g}"
    return str(x)


def highway_options(args: argparse.Namespace, instance: Any, options: dict[str, Any]) -> Any:
    """Put ``--highways``/``--w-hwy`` into ``options``; a highway file goes into the instance."""
    from dataclasses import replace

    from hierplan_opt.core.highways import GENERATORS

    if args.highways is None:
        if args.w_hwy is not None:
            raise InputError("--w-hwy needs --highways")
        return instance
    if "highways" not in registry.get(args.solver).load().options.names():
        raise InputError(f"solver {args.solver!r} does not take highways (use cbs, ecbs or eecbs)")
    for key, flag in (("highways", "--highways"), ("w_hwy", "--w-hwy")):
        if key in options and (key == "highways" or args.w_hwy is not None):
            raise InputError(f"give {key} either with {flag} or with --set {key}=..., not both")
    if args.w_hwy is not None:
        options["w_hwy"] = args.w_hwy
    if args.highways in GENERATORS:
        options["highways"] = args.highways
        return instance
    from hierplan_opt.io.highways import load_highways

    hw = load_highways(args.highways, instance.graph)
    options["highways"] = "instance"
    return replace(instance, highways=hw)


def default_solver(instance: Any) -> tuple[str, str]:
    """The solver ``solve`` uses when none is given, and why: cbs for MAPF (and for TAPF
    with one robot per team, which is MAPF); for TAPF, flow (optimal makespan for one
    team, i.e. anonymous MAPF) or cbm (teams); cpsat for annotated roadmaps whose
    conflicts go beyond vertex and swap conflicts.

    Example
    -------
    >>> from hierplan_opt import Graph, Instance
    >>> g = Graph.grid(3, 3)
    >>> teams = [([(0, 0), (1, 0)], [(2, 2), (2, 1)]), ([(2, 0)], [(0, 2)])]
    >>> default_solver(Instance.tapf(g, teams))
    ('cbm', 'TAPF with 2 teams')
    >>> default_solver(Instance.tapf(g, [([(0, 0)], [(2, 2)]), ([(2, 0)], [(0, 2)])]))
    ('cbs', 'one robot per team: MAPF')
    >>> default_solver(Instance.mapf(g, [(0, 0)], [(2, 2)]))[0]
    'cbs'
    """
    if instance.meta.get("edge_conflicts"):
        return "cpsat", "an annotated roadmap with conflicts beyond vertex and swap"
    if not instance.is_tapf:
        return "cbs", "MAPF"
    if len(instance.teams) > 1 and all(len(t.agents) == 1 for t in instance.teams):
        if instance.meta.get("free_agents"):
            return "cbs", "one robot per team, task-free robots' ends chosen: MAPF"
        return "cbs", "one robot per team: MAPF"
    if len(instance.teams) == 1:
        return "flow", "TAPF with one team"
    return "cbm", f"TAPF with {len(instance.teams)} teams"


def run(args: argparse.Namespace) -> int:
    from hierplan_opt.io import save_plan
    from hierplan_opt.viz.gantt import FIGURE_SUFFIXES

    check_outputs(("--out", args.out, PLAN_SUFFIXES), ("--plot", args.plot, FIGURE_SUFFIXES))
    texts = parse_pairs(args.set)
    if args.solver is None:  # the instance decides: read it first
        instance = load_instance_from_args(args)
        args.solver, why = default_solver(instance)
        chosen = f"hierplan solve: no --solver given; using {args.solver} ({why})"
        if args.solver == "cbs" and instance.is_tapf and not instance.meta.get("free_agents"):
            instance = instance.with_goals([t.targets[0] for t in instance.teams])
    else:
        instance = None
        chosen = None
    options = registry.get(args.solver).load().options.parse(texts, args.solver)
    if args.w is not None:
        if "w" in options:
            raise InputError("give w either with --w or with --set w=..., not both")
        options["w"] = args.w
    if instance is None:
        instance = load_instance_from_args(args)
    instance = highway_options(args, instance, options)
    solved = instance
    if args.disappear_at_goal:
        solved = disappear_at_goals(instance)
    with progress_of(args, f"solve {args.solver}"):
        cpu0 = time.process_time()
        result = solve(
            solved,
            args.solver,
            time_limit=args.time_limit,
            seed=args.seed,
            cost=cost_of(args),
            **options,
        )
        cpu = time.process_time() - cpu0  # the solve's CPU seconds (runtime is wall-clock)
        if args.disappear_at_goal:
            result = from_disappeared(instance, result)
        note(status=str(result.status), lb=result.lower_bound, best=result.cost)
    if chosen is not None and "MAPF)" not in chosen:  # MAPF: cbs, the documented default
        print(chosen, file=sys.stderr)
    line = f"{summary(result, instance)} cpu={cpu:.3f}s"
    if result.plan is not None and args.out:
        save_plan(args.out, instance, result)
        line += f" -> {args.out}"
    if result.plan is not None and args.plot:
        from hierplan_opt.viz.plots import save_plan_figure

        save_plan_figure(instance, result.plan, args.plot)
        line += f", plot -> {args.plot}"
    print(line)
    if result.status is Status.ERROR:
        err = result.stats.get("error", "no details")
        print(f"hierplan solve: solver error: {err}", file=sys.stderr)
        return INTERNAL
    if result.plan is not None:
        return OK
    if result.status is Status.INFEASIBLE:
        reason = result.stats.get("reason") or result.stats.get("infeasible")
        if isinstance(reason, str):
            print(f"hierplan solve: infeasible: {reason}", file=sys.stderr)
        return INFEASIBLE
    if result.status is Status.TIME_LIMIT:
        if result.stats.get("stopped_by") == "memory_limit":
            print(f"hierplan solve: {result.stats.get('reason', 'memory limit')}", file=sys.stderr)
        return LIMIT
    print(f"hierplan solve: solver returned {result.status} without a plan", file=sys.stderr)
    return INTERNAL
