"""``hierplan post``: MAPF-POST, from a discrete plan to an execution schedule."""

from __future__ import annotations

import argparse
import dataclasses
import math

from hierplan_opt.cli.common import (
    OK,
    PLAN_INVALID,
    add_instance_arguments,
    add_progress_arguments,
    check_outputs,
    load_instance_from_args,
    progress_of,
)
from hierplan_opt.core.errors import InputError

HELP = "turn a plan into an execution schedule (MAPF-POST: TPG, STN, graph or LP)"


def _metres(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number >= 0, got {text!r}") from None
    if not math.isfinite(value) or value < 0:
        raise argparse.ArgumentTypeError(f"expected a number >= 0, got {text!r}")
    return value


def add_arguments(p: argparse.ArgumentParser) -> None:
    add_instance_arguments(p)
    add_progress_arguments(p)
    p.add_argument(
        "plan", metavar="PLAN", help="plan file (YAML/JSON, libMultiRobotPlanning layout)"
    )
    p.add_argument(
        "--objective",
        choices=("makespan", "safety", "flowtime"),
        default="makespan",
        help="makespan (default), safety (max slowest speed, then makespan) or flowtime",
    )
    p.add_argument(
        "--method",
        choices=("graph", "lp"),
        default=None,
        help="graph: earliest schedule by longest paths (makespan only; default for it); "
        "lp: Pyomo/HiGHS LP (default for safety and flowtime)",
    )
    p.add_argument(
        "--lp-backend",
        choices=("auto", "pyomo", "highs"),
        default="auto",
        help="LP back end: Pyomo+appsi_highs, direct highspy, or auto (Pyomo for small STNs)",
    )
    p.add_argument(
        "--margin",
        type=_metres,
        default=None,
        help="extra clearance in metres: robots i, j keep r_i + r_j + margin apart "
        "(default: 0.1 x the shortest edge when two or more robots are points of radius 0, "
        "else 0)",
    )
    p.add_argument("--delta", type=_metres, default=None, help=argparse.SUPPRESS)  # old name
    p.add_argument(
        "--no-clearance",
        action="store_true",
        help="keep only the plan's order (plain TPG): no distance guarantee for robot sizes",
    )
    p.add_argument(
        "--no-acceleration", action="store_true", help="ignore a_max (no acceleration bound)"
    )
    p.add_argument("--out", required=True, metavar="SCHEDULE", help="output .yaml/.json/.csv")
    p.add_argument("--dot", metavar="FILE", help="also write the STN as Graphviz DOT")
    p.add_argument("--gantt", metavar="FILE", help="also write a Gantt chart (PNG)")
    p.add_argument(
        "--gantt-rows",
        type=int,
        default=60,
        metavar="N",
        help="Gantt rows (60): more robots share rows, and the chart says so",
    )
    p.add_argument(
        "--gantt-agents",
        metavar="FIRST:STOP",
        help="Gantt chart of robots FIRST..STOP-1 only (the chart says which)",
    )
    p.add_argument(
        "--check",
        action="store_true",
        help="replay the schedule and check the minimum distance and every STN bound",
    )


def _clearance(schedule) -> str:
    """``youbot/youbot 0.7 m, pioneer/youbot 0.65 m guaranteed`` (or not)."""
    parts = [f"{a}/{b} {c.required:.4g} m" for c in schedule.clearance for a, b in [c.types]]
    held = all(c.guaranteed for c in schedule.clearance)
    return (", ".join(parts) or "none") + (" guaranteed" if held else " NOT guaranteed")


def run(args: argparse.Namespace) -> int:
    from hierplan_opt.io import read_plan
    from hierplan_opt.schedule import postprocess, replay, to_dot, write_schedule
    from hierplan_opt.schedule.output import FORMATS
    from hierplan_opt.schedule.replay import check_bounds
    from hierplan_opt.viz.gantt import FIGURE_SUFFIXES

    check_outputs(
        ("--out", args.out, FORMATS),
        ("--dot", args.dot, (".dot", ".gv")),
        ("--gantt", args.gantt, FIGURE_SUFFIXES),
    )
    rng = None
    if args.gantt_agents:
        a, sep, b = args.gantt_agents.partition(":")
        if not (sep and a.isdigit() and b.isdigit() and int(a) < int(b)):
            raise InputError(f"--gantt-agents expects FIRST:STOP, got {args.gantt_agents!r}")
        rng = (int(a), int(b))
    if args.gantt_rows < 1:
        raise InputError(f"--gantt-rows must be at least 1, got {args.gantt_rows}")
    instance = load_instance_from_args(args)
    if rng is not None and rng[1] > instance.num_agents:
        raise InputError(
            f"--gantt-agents {args.gantt_agents}: there are {instance.num_agents} robots"
        )
    plan, plan_stats = read_plan(args.plan, instance)
    method = args.method or ("graph" if args.objective == "makespan" else "lp")
    if args.margin is not None and args.delta is not None:
        raise InputError("give --margin or its old name --delta, not both")
    margin = args.margin if args.margin is not None else args.delta  # None: default
    with progress_of(args, f"post {method}"):
        schedule = postprocess(
            instance,
            plan,
            args.objective,
            margin=margin,
            clearance=not args.no_clearance,
            method=method,
            acceleration=not args.no_acceleration,
            lp_backend=args.lp_backend,
        )
    solver = plan_stats.get("solver") or plan_stats.get("algorithm")
    if isinstance(solver, str) and solver:
        schedule = dataclasses.replace(schedule, settings={**schedule.settings, "solver": solver})
    write_schedule(schedule, args.out)
    if args.dot:
        assert schedule.stn is not None
        with open(args.dot, "w") as f:
            f.write(to_dot(schedule.stn, schedule))
    if args.gantt:
        from hierplan_opt.viz.gantt import plot_gantt

        plot_gantt(schedule, args.gantt, rows=args.gantt_rows, agents=rng)
    st = schedule.stats
    line = (
        f"{schedule.objective} schedule ({method}): makespan {schedule.makespan:.6g} s, "
        f"flowtime {schedule.flowtime:.6g} s, clearance {_clearance(schedule)}, "
        f"{st['tpg_nodes']} nodes, {st['stn_arcs']} arcs ({st['type2_arcs']} type-2), "
        f"{st['total_time']:.3f} s -> {args.out}"
    )
    code = OK
    if args.check:
        rep = replay(schedule, instance)
        assert schedule.stn is not None
        bad = check_bounds(schedule.stn, schedule.times)
        ok = rep.ok and not bad
        gap = f"{rep.worst_gap:+.4g} m" if math.isfinite(rep.worst_gap) else "none close"
        line += (
            f"; replay min distance {rep.min_distance_text()}, worst pair vs required {gap} "
            f"(margin {schedule.margin:.4g} m), {rep.violations} pairs too close or on one "
            f"point ({'ok' if ok else 'FAILED'})"
        )
        if bad:
            line += f"; bound violated: {bad[0]}"
        code = OK if ok else PLAN_INVALID
    print(line)
    return code
