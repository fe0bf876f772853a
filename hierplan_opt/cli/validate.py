"""``hierplan validate``: check a plan file against an instance with the one validator."""

from __future__ import annotations

import argparse

from hierplan_opt.cli.common import (
    OK,
    PLAN_INVALID,
    add_instance_arguments,
    add_tracker_y_arguments,
    load_instance_from_args,
    tracker_y_note,
)

HELP = "check a plan file against an instance (prints 'valid' with costs, or the violations)"


def add_arguments(p: argparse.ArgumentParser) -> None:
    add_instance_arguments(p)
    p.add_argument(
        "plan",
        metavar="PLAN",
        help="plan file: libMultiRobotPlanning layout (YAML/JSON), EECBS / CBSH2-RTC paths, "
        "LaCAM result or MAPF Tracker submission",
    )
    add_tracker_y_arguments(p)
    p.add_argument(
        "--disappear-at-goal",
        action="store_true",
        help="agents leave the map at their goals (as `solve --disappear-at-goal` plans)",
    )


def run(args: argparse.Namespace) -> int:
    from hierplan_opt.core.validate import validate
    from hierplan_opt.io import read_plan

    instance = load_instance_from_args(args)
    plan, stats = read_plan(args.plan, instance, tracker_y=args.tracker_y)
    # libMRP's variants (task-free robots, agents that leave, annotated conflicts)
    from hierplan_opt.search.libmrp import annotated_violations, checked_form

    checked, as_plan = checked_form(instance, plan, disappear=args.disappear_at_goal)
    violations: list[object] = [*validate(checked, as_plan), *annotated_violations(checked, plan)]
    if violations:
        for v in violations:
            print(f"{args.plan}: {v}")
        return PLAN_INVALID
    print(
        f"valid: soc={plan.sum_of_costs} makespan={plan.makespan} "
        f"agents={plan.num_agents} (lower bounds: soc>={instance.soc_lower_bound()}, "
        f"makespan>={instance.makespan_lower_bound()})" + tracker_y_note(stats)
    )
    return OK
