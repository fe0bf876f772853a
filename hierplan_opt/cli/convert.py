"""``hierplan convert``: write an instance, a plan or a schedule in another tool's format.

::

    hierplan convert INSTANCE [--scen F --agents K] --to hierplan|lmrp|movingai --out FILE
    hierplan convert INSTANCE [--scen F --agents K] --plan PLAN
                     --to yaml|json|eecbs|lacam|tracker --out FILE
    hierplan convert INSTANCE [--scen F --agents K] --schedule SCHEDULE --to lmrp --out FILE

PLAN may be in any format :func:`hierplan_opt.io.read_plan` reads. ``--to`` defaults
from the extension of ``--out`` where it can (``.map`` MovingAI, ``.csv`` tracker,
``.json`` JSON, ``.yaml`` the hierplan instance / plan layout). The plan is checked with
the validator and the summary line says whether it is valid; it is converted either way.
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path
from typing import Any

from hierplan_opt.cli.common import (
    OK,
    PLAN_SUFFIXES,
    add_instance_arguments,
    add_tracker_y_arguments,
    check_outputs,
    load_instance_from_args,
    tracker_y_note,
)
from hierplan_opt.core.errors import InputError
from hierplan_opt.core.validate import validate

HELP = (
    "write an instance, a plan or a schedule in another tool's format (libMultiRobotPlanning, "
    "MovingAI, EECBS, LaCAM, MAPF Tracker)"
)

INSTANCE_TARGETS = ("hierplan", "lmrp", "movingai")
PLAN_TARGETS = ("yaml", "json", "eecbs", "lacam", "tracker")
SCHEDULE_TARGETS = ("lmrp",)
TRACKER_SUFFIXES = (".csv", ".json", ".yaml", ".yml")


def add_arguments(p: argparse.ArgumentParser) -> None:
    add_instance_arguments(p)
    p.add_argument(
        "--plan",
        metavar="FILE",
        help="a plan file in any readable format (without --plan or --schedule: the instance)",
    )
    p.add_argument(
        "--schedule",
        metavar="FILE",
        help="a MAPF-POST schedule (from `hierplan post`) to convert instead of a plan",
    )
    p.add_argument(
        "--to",
        choices=sorted(set(INSTANCE_TARGETS + PLAN_TARGETS)),
        help="target format: hierplan, lmrp, movingai (instances); yaml, json, eecbs, "
        "lacam, tracker (plans); lmrp (schedules, for libMultiRobotPlanning's visualize.py)",
    )
    p.add_argument("--out", required=True, metavar="FILE", help="file to write")
    add_tracker_y_arguments(p)


def _target(args: argparse.Namespace, kind: str) -> str:
    allowed = {"instance": INSTANCE_TARGETS, "plan": PLAN_TARGETS, "schedule": SCHEDULE_TARGETS}
    ext = Path(args.out).suffix.lower()
    to = args.to
    if to is None:
        guess = {
            "instance": {".map": "movingai", ".scen": "movingai", ".yaml": "hierplan"},
            "plan": {".yaml": "yaml", ".yml": "yaml", ".json": "json", ".csv": "tracker"},
            "schedule": {".yaml": "lmrp", ".yml": "lmrp"},
        }[kind]
        to = guess.get(ext)
        if to is None:
            raise InputError(
                f"--out {args.out}: give --to ({', '.join(allowed[kind])}) for {_a(kind)}"
            )
    if to not in allowed[kind]:
        raise InputError(f"--to {to} does not apply to {_a(kind)} (use {', '.join(allowed[kind])})")
    return to


def _a(kind: str) -> str:
    return f"an {kind}" if kind[0] in "aeiou" else f"a {kind}"


def run(args: argparse.Namespace) -> int:
    if args.plan is not None and args.schedule is not None:
        raise InputError("give --plan FILE or --schedule FILE, not both")
    kind = "plan" if args.plan is not None else "schedule" if args.schedule else "instance"
    to = _target(args, kind)
    out = Path(args.out)
    # -------------------------------------------------------- outputs, before any work
    if kind == "instance" and to == "movingai":
        check_outputs(
            ("--out", out.with_suffix(".map"), None), ("--out", out.with_suffix(".scen"), None)
        )
    elif kind == "instance" or kind == "schedule":
        check_outputs(("--out", out, (".yaml", ".yml")))
    elif to in ("yaml", "json"):
        check_outputs(("--out", out, PLAN_SUFFIXES))
    elif to == "tracker":
        check_outputs(("--out", out, TRACKER_SUFFIXES))
    else:
        check_outputs(("--out", out, None))

    instance = load_instance_from_args(args)
    if kind == "instance":
        from hierplan_opt.io import save_instance

        if to in ("lmrp", "movingai"):  # write what the format carries; say what it cannot
            from hierplan_opt.io.lmrp_yaml import without_extras

            instance, lost = without_extras(instance)
            fmt = "libMultiRobotPlanning" if to == "lmrp" else "MovingAI"
            for what in lost:
                print(
                    f"hierplan convert: warning: the {fmt} format cannot hold {what}; left "
                    f"out of {out}",
                    file=sys.stderr,
                )
        save_instance(out, instance, format=to)
        written = f"{out.with_suffix('.map')} and {out.with_suffix('.scen')}"
        print(
            f"instance {instance.name} ({instance.num_agents} agents) as {to} -> "
            + (written if to == "movingai" else str(out))
        )
        return OK
    if kind == "schedule":
        from hierplan_opt.io.lmrp_yaml import save_schedule
        from hierplan_opt.schedule import read_schedule

        data = read_schedule(str(args.schedule))
        names = {a.name for a in instance.agents}
        unknown = [str(n) for n in data["schedule"] if str(n) not in names]
        if unknown:
            raise InputError(
                f"{args.schedule}: schedule names agent {unknown[0]!r}, which the instance "
                "does not have"
            )
        save_schedule(out, data)
        print(f"schedule ({len(data['schedule'])} robots) as lmrp (x, y, t) -> {out}")
        return OK
    from hierplan_opt.io import read_plan, save_plan
    from hierplan_opt.io.files import read_text
    from hierplan_opt.io.plans import plan_format
    from hierplan_opt.io.tracker import submission

    plan_path = str(args.plan)
    text = read_text(plan_path)
    src = plan_format(text)
    plan, stats = read_plan(plan_path, instance, text=text, tracker_y=args.tracker_y)
    violations = validate(instance, plan)
    lower = _soc_lower_bound(stats)
    written = ""
    if to == "tracker":
        from hierplan_opt.io import tracker

        tracker.save(out, submission(instance, plan, lower_cost=lower))
        written = f" (moves y-{tracker.WRITE_Y}: d = y+1, the tracker's current convention)"
    elif to == "lacam":
        from hierplan_opt.io import lacam

        lacam.save(out, instance, plan, stats={} if lower is None else {"soc_lb": lower})
    else:
        save_plan(out, instance, plan, format=to)
    state = "valid" if not violations else f"INVALID ({len(violations)} violations)"
    print(
        f"plan ({src}{tracker_y_note(stats)}, {plan.num_agents} agents, "
        f"soc={plan.sum_of_costs}, makespan={plan.makespan}, {state}) as {to}{written} -> {out}"
    )
    return OK


def _soc_lower_bound(stats: dict[str, Any]) -> int | None:
    """A proven sum-of-costs lower bound from a plan file's statistics, if it has one."""
    for key in ("lower_bound", "lower_cost", "soc_lb"):
        value = stats.get(key)
        if key == "lower_bound" and stats.get("objective", "soc") != "soc":
            continue
        if isinstance(value, bool) or value in (None, ""):
            continue
        try:
            return int(math.ceil(float(value) - 1e-9))
        except (TypeError, ValueError, OverflowError):
            continue
    return None
