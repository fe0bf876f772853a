"""``hierplan run``: the whole hierarchy: plan -> MAPF-POST -> execution under disturbances."""

from __future__ import annotations

import argparse

from hierplan_opt.cli.common import INFEASIBLE, LIMIT, add_instance_arguments, positive_float
from hierplan_opt.cli.simulate import add_execution_arguments, check_execution_outputs, execute

HELP = "plan, post-process and execute an instance (the whole hierarchy) with a report"


def add_arguments(p: argparse.ArgumentParser) -> None:
    add_instance_arguments(p)
    p.add_argument("--solver", default="cbs", metavar="NAME", help="planner (default: cbs)")
    p.add_argument(
        "--objective",
        choices=("soc", "makespan"),
        help="planning objective (default: soc for MAPF, makespan for TAPF)",
    )
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
    p.add_argument("--margin", type=float, default=0.0, help="extra clearance in metres")
    p.add_argument(
        "--refine",
        action="store_true",
        help="refine the schedule into smooth trajectories (CasADi) and follow them",
    )
    add_execution_arguments(p)
    p.add_argument("--out", metavar="REPORT", help="report YAML (statistics, events, schedule)")


def run(args: argparse.Namespace) -> int:
    import hierplan_opt as hp
    from hierplan_opt.cli.common import load_instance_from_args
    from hierplan_opt.schedule import postprocess

    check_execution_outputs(args)
    instance = load_instance_from_args(args)
    res = hp.solve(instance, args.solver, time_limit=args.time_limit, objective=args.objective)
    if res.plan is None:
        print(f"planning: {res.solver} found no plan ({res.status}) in {res.runtime:.3g} s")
        return INFEASIBLE if res.status.value == "INFEASIBLE" else LIMIT
    method = "graph" if args.post_objective == "makespan" else "lp"
    schedule = postprocess(
        instance,
        res.plan,
        args.post_objective,
        margin=args.margin,
        method=method,
        check_plan=False,
    )
    clear = ", ".join(
        f"{a}/{b} {c.required:.3g} m" for c in schedule.clearance for a, b in [c.types]
    )
    title = (
        f"plan: {res.solver} {res.status.value} {res.objective} {res.cost} "
        f"({res.runtime:.3g} s), {instance.num_agents} robots\n"
        f"MAPF-POST ({args.post_objective}): makespan {schedule.makespan:.4g} s, clearance "
        f"{clear or 'none'}, {schedule.stats['tpg_nodes']} TPG nodes"
    )
    traj = None
    if args.refine:
        from hierplan_opt.trajectory import InfeasibleWindowsError, refine

        try:
            traj = refine(instance, schedule, stretch="auto")
        except InfeasibleWindowsError as exc:
            print(f"refinement: infeasible: {exc}")
            return INFEASIBLE
        title += (
            f"\nrefined ({traj.mode} mode): makespan {traj.makespan:.4g} s, stretch "
            f"{traj.stretch:.4g}, guaranteed distance {traj.safety_distance:.3g} m, "
            f"{traj.stats.get('total_time', 0.0):.2f} s"
        )
    return execute(args, instance, schedule, title, traj, plan_solver=args.solver)
