"""``hierplan verify INSTANCE [--scen FILE --agents K] PLAN``: certify a plan's optimality."""

from __future__ import annotations

import argparse

from hierplan_opt.cli.common import (
    LIMIT,
    OK,
    PLAN_INVALID,
    add_cost_argument,
    add_instance_arguments,
    add_memory_argument,
    add_progress_arguments,
    cost_of,
    load_instance_from_args,
    positive_float,
    progress_of,
)
from hierplan_opt.core.progress import note
from hierplan_opt.core.result import Status

#: Exit code of each verdict: proven optimal, not optimal, invalid plan, undecided.
EXIT_CODES = {
    Status.OPTIMAL: OK,
    Status.FEASIBLE: PLAN_INVALID,
    Status.INFEASIBLE: PLAN_INVALID,
    Status.TIME_LIMIT: LIMIT,
}

HELP = "certify that a plan is optimal with an exact formulation (CP-SAT or MIP), or report the gap"


def add_arguments(p: argparse.ArgumentParser) -> None:
    add_instance_arguments(p)
    add_memory_argument(p)
    add_progress_arguments(p)
    p.add_argument("plan", metavar="PLAN", help="plan file (as written by `hierplan solve`)")
    add_cost_argument(p, "the plan's cost to certify")
    p.add_argument(
        "--method",
        choices=("cpsat", "mip"),
        default="cpsat",
        help="exact formulation that decides (default: cpsat)",
    )
    p.add_argument(
        "--time-limit",
        metavar="S",
        type=positive_float,
        help="wall-clock budget in seconds (default: none)",
    )
    p.epilog = (
        "exit codes: 0 proven optimal, 1 plan invalid or not optimal, "
        "2 bad input, 4 time or memory limit reached before a proof"
    )


def run(args: argparse.Namespace) -> int:
    from hierplan_opt.formulations.verify import verify
    from hierplan_opt.io import load_plan

    instance = load_instance_from_args(args)
    plan = load_plan(args.plan, instance)
    with progress_of(args, f"verify {args.method}"):
        res = verify(
            instance,
            plan,
            objective=cost_of(args),
            method=args.method,
            time_limit=args.time_limit,
        )
        note(verdict=str(res.outcome))
    print(res.message())  # one line: the first violation and the count of the others
    return EXIT_CODES[res.outcome]
