"""``hierplan solve``: solve an instance with a registered solver and write the plan."""

from __future__ import annotations

import argparse
import sys
import time
from typing import Any

from hierplan_opt.api import DEFAULT_TIME_LIMIT
from hierplan_opt.cli.common import (
    INFEASIBLE,
    INTERNAL,
    LIMIT,
    OK,
    PLAN_SUFFIXES,
    add_instance_arguments,
    add_memory_argument,
    add_progress_arguments,
    check_outputs,
    load_instance_from_args,
    positive_float,
    progress_of,
)
from hierplan_opt.core.errors import InputError, UnknownSolverError
from hierplan_opt.core.options import parse_pairs
from hierplan_opt.core.progress import note

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
        default="cbs",
        metavar="NAME",
        action=SolverName,
        help="solver name (default: cbs); `--solver NAME --help` lists its options",
    )
    p.add_argument(
        "--objective",
        choices=("soc", "makespan"),
        help="objective (default: soc for MAPF, makespan for TAPF)",
    )
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
        "--out",
        metavar="PLAN",
        help="write the plan here (.yaml, or .json); only written when a plan is found",
    )
    base_help = p.format_help

    def format_help() -> str:
        return base_help() + "\n" + "\n".join(solver_help(chosen[0])) + "\n"

    p.format_help = format_help  # type: ignore[method-assign]


def solver_help(name: str) -> list[str]:
    """The ``--help`` lines listing solver ``name``'s options.

    Example
    -------
    >>> solver_help("ecbs")[1]
    '  w: number >= 1 and < 1e+09 (default 1.2) -- suboptimality bound: cost <= w * optimum'
    """
    from hierplan_opt import registry

    try:
        spec = registry.get(name).load().options
    except UnknownSolverError as exc:
        return [str(exc)]
    head = f"options of solver {name!r} (--set KEY=VALUE; other solvers: --solver NAME --help):"
    return [head] + [f"  {o.describe()}" for o in spec] + ([] if len(spec) else ["  none"])


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
    shown = 0
    for k, v in result.stats.items():
        if k == "error" or shown >= 6:
            continue
        if isinstance(v, (bool, int, float, str)):
            text = _fmt(v) if not isinstance(v, str) else v
            if isinstance(v, str) and (len(v) > 30 or " " in v):
                continue
            parts.append(f"{k}={text}")
            shown += 1
    return " ".join(parts)


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

    from hierplan_opt import registry
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


def run(args: argparse.Namespace) -> int:
    import hierplan_opt
    from hierplan_opt import registry
    from hierplan_opt.core.result import Status
    from hierplan_opt.io import save_plan

    check_outputs(("--out", args.out, PLAN_SUFFIXES))
    texts = parse_pairs(args.set)
    options = registry.get(args.solver).load().options.parse(texts, args.solver)
    if args.w is not None:
        if "w" in options:
            raise InputError("give w either with --w or with --set w=..., not both")
        options["w"] = args.w
    instance = load_instance_from_args(args)
    instance = highway_options(args, instance, options)
    with progress_of(args, f"solve {args.solver}"):
        cpu0 = time.process_time()
        result = hierplan_opt.solve(
            instance,
            args.solver,
            time_limit=args.time_limit,
            seed=args.seed,
            objective=args.objective,
            **options,
        )
        cpu = time.process_time() - cpu0  # the solve's CPU seconds (runtime is wall-clock)
        note(status=str(result.status), lb=result.lower_bound, best=result.cost)
    line = f"{summary(result, instance)} cpu={cpu:.3f}s"
    if result.plan is not None and args.out:
        save_plan(args.out, instance, result)
        line += f" -> {args.out}"
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
