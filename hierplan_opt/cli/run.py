"""``hierplan run``: the whole hierarchy: plan -> MAPF-POST -> execution under disturbances."""

from __future__ import annotations

import argparse

from hierplan_opt import registry
from hierplan_opt.cli.common import (
    INFEASIBLE,
    LIMIT,
    add_cost_argument,
    add_instance_arguments,
    cost_of,
    load_instance_from_args,
    positive_float,
    result_facts,
)
from hierplan_opt.cli.simulate import (
    add_execution_arguments,
    check_execution_outputs,
    check_monte_carlo,
    disturbances_of,
    report_execution,
)
from hierplan_opt.core.errors import InputError
from hierplan_opt.core.options import parse_pairs

HELP = "plan, post-process and execute an instance (the whole hierarchy) with a report"


def add_arguments(p: argparse.ArgumentParser) -> None:
    add_instance_arguments(p)
    p.add_argument("--solver", default="cbs", metavar="NAME", help="planner (default: cbs)")
    add_cost_argument(p, "what the plan minimises")
    p.add_argument(
        "--time-limit",
        type=positive_float,
        default=60.0,
        metavar="SECONDS",
        help="planning time limit (default 60)",
    )
    p.add_argument(
        "--post-objective",
        choices=("makespan", "safety", "flowtime"),
        default="makespan",
        help="MAPF-POST objective (default makespan; safety/flowtime use the LP)",
    )
    p.add_argument(
        "--margin",
        type=float,
        default=None,
        help="extra clearance in metres (default: MAPF-POST's, 0.1 x the shortest edge "
        "for point robots, else 0)",
    )
    p.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="a planner option (repeatable), as in `hierplan solve --set`",
    )
    p.add_argument(
        "--refine",
        action="store_true",
        help="refine the schedule into smooth trajectories (CasADi) and follow them",
    )
    p.add_argument(
        "--a-max",
        type=positive_float,
        metavar="A",
        help="with --refine: acceleration limit (m/s^2) for robots without one (as in "
        "`hierplan refine --a-max`)",
    )
    add_execution_arguments(p)
    p.add_argument("--out", metavar="REPORT", help="report YAML (statistics, events, schedule)")


def run(args: argparse.Namespace) -> int:
    from hierplan_opt.execution.pipeline import run

    check_execution_outputs(args)
    check_monte_carlo(args)
    if args.a_max is not None and not args.refine:
        raise InputError("--a-max applies to the refinement: give it with --refine")
    options = registry.get(args.solver).load().options.parse(parse_pairs(args.set), args.solver)
    instance = load_instance_from_args(args)
    dist = disturbances_of(args, instance)
    infeasible: type[Exception] = _Never
    if args.refine:
        from hierplan_opt.trajectory import InfeasibleWindowsError  # heavy module (CasADi)

        infeasible = InfeasibleWindowsError
    try:
        out = run(
            instance,
            args.solver,
            post=args.post_objective,
            disturbances=dist,
            policy=args.policy,
            mode=args.mode,
            time_limit=args.time_limit,
            cost=cost_of(args),
            margin=args.margin,
            refine=args.refine,
            a_max=args.a_max,
            seed=args.seed,
            replan_solver=args.replan_solver or "auto",
            solver_options=options,
        )
    except infeasible as exc:
        print(f"refinement: infeasible: {exc}")
        return INFEASIBLE
    except InputError as exc:
        # A stop at a way-point the planned schedule does not have: name the file.
        if args.disturbances and str(exc).startswith("disturbance "):
            raise InputError(f"{args.disturbances}: {exc}") from None
        raise
    res = out.result
    facts = result_facts(res.stats)  # stopped_by, plan_from, bound_met (as on solve's line)
    if res.plan is None:
        why = f"{res.status.value}{', ' + facts if facts else ''}"
        print(f"planning: {res.solver} found no plan ({why}) in {res.runtime:.3g} s")
        return INFEASIBLE if res.status.value == "INFEASIBLE" else LIMIT
    schedule = out.schedule
    if schedule is None or out.execution is None:
        # as `hierplan post` refuses the plan (e.g. robots rotating through a cycle
        # under a margin > 0, with its advice): bad input, exit 2; not "infeasible"
        raise InputError(out.why)
    clear = ", ".join(
        f"{a}/{b} {c.required:.3g} m" for c in schedule.clearance for a, b in [c.types]
    )
    title = (
        f"plan: {res.solver} {res.status.value} {res.objective} {res.cost} "
        f"{facts + ' ' if facts else ''}({res.runtime:.3g} s), {instance.num_agents} robots\n"
        f"MAPF-POST ({args.post_objective}): makespan {schedule.makespan:.4g} s, clearance "
        f"{clear or 'none'}, {schedule.stats['tpg_nodes']} TPG nodes"
    )
    traj = out.trajectories
    if traj is not None:
        title += (
            f"\nrefined ({traj.mode} mode): makespan {traj.makespan:.4g} s, stretch "
            f"{traj.stretch:.4g}, guaranteed distance {traj.safety_distance:.3g} m, "
            f"{traj.stats.get('total_time', 0.0):.2f} s"
        )
    return report_execution(
        args, instance, schedule, out.execution, title, dist, traj, plan_solver=args.solver
    )


class _Never(Exception):
    """Never raised (stands in for the refinement's error when there is no refinement)."""
