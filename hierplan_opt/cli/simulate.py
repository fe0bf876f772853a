"""``hierplan simulate``: execute a plan's schedule under disturbances."""

from __future__ import annotations

import argparse
import math
from typing import Any

from hierplan_opt.cli.common import (
    NOT_ARRIVED,
    OK,
    PLAN_INVALID,
    add_instance_arguments,
    check_outputs,
    fraction,
    load_instance_from_args,
    non_negative_int,
    positive_float,
    positive_int,
)
from hierplan_opt.core.errors import InputError, OptionError

HELP = "execute a plan or schedule under disturbances (slack, STN re-solve, re-plan)"

POLICY_HELP = (
    "slack (absorb by slack), stn (+ incremental STN re-solve), replan (default: "
    "slack -> stn -> MAPF re-plan), reorder (+ switch passing orders first), adg (no "
    "schedule), naive (ignore the TPG)"
)


def add_execution_arguments(p: argparse.ArgumentParser) -> None:
    """Options shared by ``simulate`` and ``run``."""
    from hierplan_opt.execution.simulate import POLICIES

    p.add_argument("--disturbances", metavar="FILE", help="disturbances YAML file")
    p.add_argument("--policy", choices=POLICIES, default="replan", help=POLICY_HELP)
    p.add_argument(
        "--mode",
        choices=("agent", "robot", "replay", "physics"),
        default="agent",
        help="agent: constant velocity; robot: closed loop over kinematic robots (bounded "
        "acceleration, turning in place; their delays feed back into the layers); replay: "
        "the same dynamics open loop on the agent run's event times; physics: the same "
        "closed loop over robots in MuJoCo (docs/physics.md)",
    )
    p.add_argument(
        "--seed", type=non_negative_int, default=0, metavar="S", help="random seed >= 0 (default 0)"
    )
    p.add_argument("--runs", type=positive_int, metavar="N", help="Monte Carlo: N seeded runs")
    p.add_argument("--workers", type=positive_int, metavar="W", help="Monte Carlo processes")
    p.add_argument(
        "--replan-below",
        type=fraction,
        metavar="P",
        help="Monte Carlo: re-plan (delay-aware) when a location is on time with less than P",
    )
    p.add_argument(
        "--replan-solver",
        metavar="NAME",
        help="MAPF solver of re-plans (default auto: ECBS up to 100 robots, else LaCAM; "
        "of --replan-below: the plan's solver in 'run', else ecbs, cbm for teams)",
    )
    p.add_argument("--plot", metavar="PNG", help="distance over time vs the guaranteed distance")
    p.add_argument("--animate", metavar="GIF|MP4", help="animation of the run")
    add_animation_arguments(p)


def add_animation_arguments(p: argparse.ArgumentParser) -> None:
    """``--fps``, ``--animate-size WxH``, ``--animate-speed`` of ``--animate``."""

    p.add_argument("--fps", type=positive_float, default=10.0, help="animation frame rate (10)")
    p.add_argument(
        "--animate-size", metavar="WxH", type=_size, help="animation size in pixels (auto)"
    )
    p.add_argument(
        "--animate-speed",
        type=positive_float,
        default=None,
        metavar="X",
        help="seconds of plan per second of animation (1; plans over 60 s: videos of 60 s)",
    )


def _size(text: str) -> tuple[int, int]:
    w, sep, h = text.lower().partition("x")
    if not (sep and w.isdigit() and h.isdigit()):
        raise argparse.ArgumentTypeError(f"expected WIDTHxHEIGHT in pixels, got {text!r}")
    if not (64 <= int(w) <= 7680 and 64 <= int(h) <= 4320):
        raise argparse.ArgumentTypeError(f"{text}: sizes go from 64x64 to 7680x4320 pixels")
    return int(w), int(h)


def add_arguments(p: argparse.ArgumentParser) -> None:
    add_instance_arguments(p)
    p.add_argument(
        "plan",
        metavar="PLAN|SCHEDULE",
        help="a plan file (post-processed here) or a schedule file from 'hierplan post'",
    )
    p.add_argument("--margin", type=float, default=None, help="extra clearance (m) for a plan")
    p.add_argument(
        "--trajectories",
        metavar="NPZ",
        help="follow refined trajectories of this schedule (the .npz of 'hierplan refine')",
    )
    add_execution_arguments(p)
    p.add_argument("--out", required=True, metavar="REPORT", help="report YAML")


def load_plan_or_schedule(args: argparse.Namespace, instance: Any) -> tuple[Any, str]:
    """The schedule to execute: MAPF-POST of a plan file, or a schedule file read by the
    one reader (its own plan, settings and times; ``--margin`` re-posts its plan)."""
    from hierplan_opt.io import load_plan
    from hierplan_opt.schedule import load_schedule, postprocess
    from hierplan_opt.schedule.files import is_schedule_file

    if is_schedule_file(args.plan):
        schedule = load_schedule(args.plan, instance)
        if args.margin is not None and args.margin != schedule.margin:
            assert schedule.plan is not None
            st = schedule.settings
            schedule = postprocess(
                instance,
                schedule.plan,
                str(st.get("objective", "makespan")),
                margin=args.margin,
                method=str(st.get("method", "graph")),
                check_plan=False,
            )
        return schedule, "schedule"
    plan = load_plan(args.plan, instance)
    return postprocess(instance, plan, margin=args.margin), "plan"


def execute(
    args: argparse.Namespace,
    instance: Any,
    schedule: Any,
    title: str,
    trajectories: Any = None,
    plan_solver: str | None = None,
) -> int:
    """Simulate (or Monte Carlo), print the readable report, write REPORT and pictures.

    ``plan_solver`` makes the delay-aware re-plan of ``--replan-below`` (default: the
    re-plan solver)."""
    from hierplan_opt.execution import simulate

    check_monte_carlo(args)
    dist = disturbances_of(args, instance, schedule)
    ex = simulate(
        instance,
        schedule,
        disturbances=dist,
        policy=args.policy,
        mode=args.mode,
        seed=args.seed,
        solver=args.replan_solver or "auto",
        trajectories=trajectories,
    )
    return report_execution(args, instance, schedule, ex, title, dist, trajectories, plan_solver)


def check_monte_carlo(args: argparse.Namespace) -> None:

    if args.replan_below is not None and not args.runs:
        raise OptionError("--replan-below needs a Monte Carlo batch (--runs N)")
    if args.mode == "physics" and args.runs:
        raise OptionError("--runs (Monte Carlo) has no physics mode: use agent, robot or replay")


def disturbances_of(args: argparse.Namespace, instance: Any, schedule: Any = None) -> list[Any]:
    """The ``--disturbances`` file's disturbances, checked against the robots' names and
    the map (and the way-points of ``schedule``): one that can never happen is refused
    with one line naming the file and the disturbance, before any simulation."""
    from hierplan_opt.execution import load_disturbances
    from hierplan_opt.execution.disturbances import check_disturbances

    if not args.disturbances:
        return []
    dist = load_disturbances(args.disturbances, tuple(a.name for a in instance.agents))
    try:
        check_disturbances(dist, instance, schedule)
    except InputError as exc:
        raise InputError(f"{args.disturbances}: {exc}") from None
    return dist


def report_execution(
    args: argparse.Namespace,
    instance: Any,
    schedule: Any,
    ex: Any,
    title: str,
    dist: list[Any],
    trajectories: Any = None,
    plan_solver: str | None = None,
) -> int:
    """Print the readable report of execution ``ex`` (and a Monte Carlo batch with
    ``--runs``), write REPORT and pictures; the exit code over the base run and every
    Monte Carlo run: 1 (a collision or the distance not kept in any), else 5 (a working
    robot not at its goal in any), else 0."""
    from hierplan_opt.execution.report import text_report, write_report
    from hierplan_opt.execution.statistics import unsafe

    report: dict[str, Any] = ex.report()
    print(text_report(ex, title))
    st = ex.statistics
    failed = unsafe(st)
    stranded = bool(st["stranded"])
    if args.runs:
        from hierplan_opt.execution.montecarlo import monte_carlo

        mc = monte_carlo(
            instance,
            schedule,
            dist,
            runs=args.runs,
            workers=args.workers,
            seed=args.seed,
            policy=args.policy,
            replan_below=args.replan_below,
            replan_solver=plan_solver or args.replan_solver or "auto",
            mode=args.mode,
            trajectories=trajectories,
        )
        s = mc.summary()
        report = {"statistics": report["statistics"], "monte_carlo": s, **report}
        p5, p50, p95 = s["makespan_p5_p50_p95"]
        makespan = (
            f"makespan p5/p50/p95 {p5:.4g}/{p50:.4g}/{p95:.4g} s"
            if math.isfinite(p50)
            else "makespan not reached in any run"
        )
        print(
            f"monte carlo: {mc.runs} runs ({s['runs_per_second']:.3g}/s), {mc.collisions} "
            f"collisions, {makespan}, on time (min over locations) {s['on_time_min']:.2f}"
        )
        if mc.failed_runs:
            print(
                f"monte carlo: FAILED: {mc.failed_runs}/{mc.runs} runs ({mc.unsafe_runs} with a "
                f"collision or the guaranteed distance not kept, {mc.stranded_runs} with a "
                "working robot not at its goal)"
            )
        failed = failed or mc.unsafe_runs > 0
        stranded = stranded or mc.stranded_runs > 0
        if mc.below:
            print(f"{len(mc.below)} location(s) on time with less than {args.replan_below:g}")
        if mc.replanned is not None:
            new = mc.replanned
            r = new.summary()
            report["replanned_schedule"] = new.schedule.to_dict()["schedule"]
            print(
                f"delay-aware re-plan ({new.solver}, {new.rounds} buffering round(s), "
                f"quantile {new.quantile:g}): on time (min) {s['on_time_min']:.2f} -> "
                f"{r['on_time_min']:.2f}, planned makespan {mc.planned_makespan:.4g} -> "
                f"{new.schedule.makespan:.4g} s, {new.result.collisions} collisions"
            )
    if args.out:
        write_report(args.out, report)
        print(f"report -> {args.out}")
    if args.plot:
        from hierplan_opt.viz.animation import plot_distance

        plot_distance(ex, instance, args.plot)
    if args.animate:
        from hierplan_opt.viz.animation import animate

        animate(
            ex,
            instance,
            args.animate,
            fps=args.fps,
            size=args.animate_size,
            speed=args.animate_speed,
            progress=None if not args.quiet else False,
        )
    # The base run and every Monte Carlo run: a safety failure wins over a robot away
    # from its goal. Broken robots are listed apart and do not change the exit code.
    if failed:
        return PLAN_INVALID
    return NOT_ARRIVED if stranded else OK


def check_execution_outputs(args: argparse.Namespace) -> None:
    """Every output of ``simulate`` / ``run`` checked before any work (one line, exit 2)."""
    from hierplan_opt.viz.gantt import FIGURE_SUFFIXES

    check_outputs(
        ("--out", args.out, (".yaml", ".yml")),
        ("--plot", args.plot, FIGURE_SUFFIXES),
        ("--animate", args.animate, (".gif", ".mp4")),
    )


def run(args: argparse.Namespace) -> int:

    check_execution_outputs(args)
    instance = load_instance_from_args(args)
    schedule, kind = load_plan_or_schedule(args, instance)
    traj = None
    if args.trajectories:
        from hierplan_opt.execution.follow import check_trajectories
        from hierplan_opt.trajectory.result import read_trajectories

        traj = read_trajectories(args.trajectories)
        try:
            check_trajectories(schedule, traj, args.mode)
        except InputError as exc:
            raise InputError(f"{args.trajectories}: {exc}") from None
    title = f"{args.plan} ({kind}), {instance.num_agents} robots"
    if traj is not None:
        title += f", following refined trajectories {args.trajectories}"
    return execute(args, instance, schedule, title, traj)
