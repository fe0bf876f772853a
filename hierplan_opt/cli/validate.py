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
    add_tracker_y_arguments,
    load_instance_from_args,
    tracker_y_note,
)
from hierplan_opt.core.validate import validate
from hierplan_opt.search.libmrp import annotated_violations, checked_form

if TYPE_CHECKING:
    from hierplan_opt.core.validate import Violation

HELP = (
    "check a plan or schedule file against an instance (prints 'valid' with costs, or the "
    "violations)"
)


def add_arguments(p: argparse.ArgumentParser) -> None:
    add_instance_arguments(p)
    p.add_argument(
        "plan",
        metavar="PLAN",
        help="plan file: libMultiRobotPlanning layout (YAML/JSON), EECBS / CBSH2-RTC paths, "
        "LaCAM result or MAPF Tracker submission; or a schedule file of 'hierplan post' (its "
        "plan, its times against every bound, and its continuous-time replay)",
    )
    add_tracker_y_arguments(p)
    p.add_argument(
        "--all",
        action="store_true",
        help="list every violation, one a line (default: the first and how many more)",
    )
    p.add_argument(
        "--disappear-at-goal",
        action="store_true",
        help="agents leave the map at their goals (as `solve --disappear-at-goal` plans)",
    )


def _schedule(args: argparse.Namespace, instance) -> int:
    """A schedule file: its plan (validated by the reader), bounds and replay. An
    invalid plan or times that break a bound: one line, exit 1; a file that cannot be
    read or belongs to another instance: bad input (exit 2)."""
    from hierplan_opt.schedule import load_schedule, replay
    from hierplan_opt.schedule.files import InvalidScheduleError

    try:
        schedule = load_schedule(args.plan, instance)
    except InvalidScheduleError as exc:
        print(exc)
        return PLAN_INVALID
    plan = schedule.plan
    assert plan is not None
    rep = replay(schedule, instance)
    line = (
        f"soc={plan.sum_of_costs} makespan={plan.makespan} agents={plan.num_agents}; "
        f"schedule makespan {schedule.makespan:.6g} s, replay min distance "
        f"{rep.min_distance_text()}, margin {schedule.margin:.4g} m"
    )
    if not rep.ok:
        a, b = rep.worst_pair or ("?", "?")
        print(
            f"{args.plan}: {line}: {rep.violations} pairs too close or on one point "
            f"(worst {a} and {b}, {rep.worst_gap:+.4g} m vs required)"
        )
        return PLAN_INVALID
    print(f"valid schedule: {line}")
    return OK


def run(args: argparse.Namespace) -> int:
    from hierplan_opt.io import read_plan
    from hierplan_opt.schedule.files import is_schedule_file

    instance = load_instance_from_args(args)
    if is_schedule_file(args.plan):
        return _schedule(args, instance)
    plan, stats = read_plan(args.plan, instance, tracker_y=args.tracker_y)
    # libMRP's variants (task-free robots, agents that leave, annotated conflicts)

    checked, as_plan = checked_form(instance, plan, disappear=args.disappear_at_goal)
    violations: list[Violation | str] = [
        *validate(checked, as_plan),
        *annotated_violations(checked, plan),
    ]
    if violations:
        for line in [str(v) for v in violations] if args.all else [problems_line(violations)]:
            print(f"{args.plan}: {line}")
        return PLAN_INVALID
    print(
        f"valid: soc={plan.sum_of_costs} makespan={plan.makespan} "
        f"agents={plan.num_agents} (lower bounds: soc>={instance.soc_lower_bound()}, "
        f"makespan>={instance.makespan_lower_bound()})" + tracker_y_note(stats)
    )
    return OK


def problems_line(violations: Sequence[Violation | str]) -> str:
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
    kinds = ", ".join(
        f"{n} {k}"
        for k, n in Counter(getattr(v, "kind", "annotated_conflict") for v in rest).most_common()
    )
    word = "problem" if len(rest) == 1 else "problems"
    return f"{first} (and {len(rest)} further {word}: {kinds})"
