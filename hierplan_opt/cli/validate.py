"""``hierplan validate``: check a plan file against an instance with the one validator."""

from __future__ import annotations

import argparse
from collections import Counter
from collections.abc import Sequence
from typing import TYPE_CHECKING

from hierplan_opt.cli.common import (
    OK,
    PLAN_INVALID,
    add_instance_arguments,
    load_instance_from_args,
)

if TYPE_CHECKING:
    from hierplan_opt.core.validate import Violation

HELP = "check a plan file against an instance (prints 'valid' with costs, or the violations)"


def add_arguments(p: argparse.ArgumentParser) -> None:
    add_instance_arguments(p)
    p.add_argument(
        "plan",
        metavar="PLAN",
        help="plan file: libMultiRobotPlanning layout (YAML/JSON), EECBS / CBSH2-RTC paths, "
        "LaCAM result or MAPF Tracker submission",
    )
    p.add_argument(
        "--all",
        action="store_true",
        help="list every violation, one a line (default: the first and how many more)",
    )


def run(args: argparse.Namespace) -> int:
    from hierplan_opt.core.validate import validate
    from hierplan_opt.io import load_plan

    instance = load_instance_from_args(args)
    plan = load_plan(args.plan, instance)
    violations = validate(instance, plan)
    if violations:
        for line in [str(v) for v in violations] if args.all else [problems_line(violations)]:
            print(f"{args.plan}: {line}")
        return PLAN_INVALID
    print(
        f"valid: soc={plan.sum_of_costs} makespan={plan.makespan} "
        f"agents={plan.num_agents} (lower bounds: soc>={instance.soc_lower_bound()}, "
        f"makespan>={instance.makespan_lower_bound()})"
    )
    return OK


def problems_line(violations: Sequence[Violation]) -> str:
    """The first violation and how many further ones there are, by kind: one line
    however many (a plan of another instance has one or two per agent).

    Example
    -------
    >>> from hierplan_opt.core.validate import Violation
    >>> v = [Violation(k, (i,), None, None, f"agent{i} ...") for i, k in
    ...      enumerate(["wrong_start", "wrong_start", "wrong_goal", "wrong_start"])]
    >>> problems_line(v)
    'wrong_start: agent0 ... (and 3 further problems: 2 wrong_start, 1 wrong_goal)'
    >>> problems_line(v[:1])
    'wrong_start: agent0 ...'
    """
    first, rest = violations[0], violations[1:]
    if not rest:
        return str(first)
    kinds = ", ".join(f"{n} {k}" for k, n in Counter(v.kind for v in rest).most_common())
    word = "problem" if len(rest) == 1 else "problems"
    return f"{first} (and {len(rest)} further {word}: {kinds})"
