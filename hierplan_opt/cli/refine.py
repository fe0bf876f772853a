"""``hierplan refine``: a schedule into smooth, limited trajectories (CasADi), verified."""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

from hierplan_opt.cli.common import (
    INFEASIBLE,
    OK,
    PLAN_INVALID,
    add_instance_arguments,
    add_progress_arguments,
    fraction,
    positive_float,
    positive_int,
    progress_of,
)
from hierplan_opt.core.errors import InputError

HELP = "refine a MAPF-POST schedule into velocity- and acceleration-limited trajectories"
PLOT_FORMATS = (".png", ".pdf", ".svg")


def _stretch(text: str) -> float | str:
    if text == "auto":
        return text
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"expected 'auto' or a number >= 1, got {text!r}"
        ) from None
    if not math.isfinite(value) or value < 1:
        raise argparse.ArgumentTypeError(f"expected 'auto' or a number >= 1, got {text!r}")
    return value


def add_arguments(p: argparse.ArgumentParser) -> None:
    add_instance_arguments(p)
    add_progress_arguments(p)
    p.add_argument("schedule", metavar="SCHEDULE", help="schedule file written by `hierplan post`")
    p.add_argument("--out", required=True, metavar="FILE", help="output trajectories .csv or .npz")
    p.add_argument(
        "--plot", metavar="FILE", help="also plot position/speed/acceleration (.png/.pdf/.svg)"
    )
    p.add_argument(
        "--model",
        choices=("auto", "double_integrator", "unicycle"),
        default="auto",
        help="robot model (auto: unicycle for differential drive, else double integrator)",
    )
    p.add_argument(
        "--mode",
        choices=("path", "corridor"),
        default="path",
        help="path: stay on the planned polyline (default); "
        "corridor: cut corners within --corridor",
    )
    p.add_argument(
        "--corridor", type=positive_float, default=0.1, help="corridor half-width in metres (0.1)"
    )
    p.add_argument(
        "--solver",
        choices=("auto", "ipopt", "fatrop", "profile", "profile+qp"),
        default="auto",
        help="NLP solver (auto: IPOPT), or profile: path mode without an NLP (fast), "
        "profile+qp: the profile smoothed by a QP",
    )
    p.add_argument(
        "--stretch",
        type=_stretch,
        default=None,
        help="slow the schedule down by this factor, or 'auto' for the smallest that works "
        "(default: report an infeasible robot and that factor)",
    )
    p.add_argument("--a-max", type=positive_float, help="acceleration limit for robots without one")
    p.add_argument("--alpha-max", type=positive_float, help="turn acceleration limit of unicycles")
    p.add_argument(
        "--split", type=fraction, default=0.5, help="slack share of the earlier event (0.5)"
    )
    p.add_argument("--workers", type=positive_int, default=1, help="solve in N processes (1)")
    p.add_argument(
        "--dt", type=positive_float, default=0.1, help="sampling step of the file (0.1 s)"
    )
    p.add_argument(
        "--verify-dt", type=positive_float, default=0.02, help="verification step (0.02 s)"
    )
    p.add_argument("--no-verify", action="store_true", help="skip the independent verification")
    p.epilog = (
        "exit codes: 0 refined and verified, 1 verification failed, 2 bad input, "
        "3 the robots' limits cannot meet the windows (the message gives the stretch factor)"
    )


def _check_plot(path: str) -> None:
    p = Path(path)
    if p.suffix.lower() not in PLOT_FORMATS:
        raise InputError(f"{path}: the plot must end in {', '.join(PLOT_FORMATS)}")
    parent = p.parent if str(p.parent) else Path(".")
    if not parent.is_dir():
        raise InputError(f"{path}: directory {parent} does not exist")


def _clearance(traj) -> str:
    """``r_i + r_j + 0.1 (smallest pair 0.6 m)``: what the trajectories keep."""
    if not traj.enforced:
        return "none guaranteed (schedule without clearance)"
    less = traj.margin - 2 * traj.corridor
    sign = "+" if less >= 0 else "-"
    return f"r_i + r_j {sign} {abs(less):.4g} m (smallest pair {traj.safety_distance:.4g} m)"


def run(args: argparse.Namespace) -> int:
    from hierplan_opt.cli.common import load_instance_from_args
    from hierplan_opt.trajectory import InfeasibleWindowsError, from_file, refine
    from hierplan_opt.trajectory.result import check_output_path, write_trajectories

    check_output_path(args.out)
    if args.plot:
        _check_plot(args.plot)
    instance = load_instance_from_args(args)
    network = from_file(instance, args.schedule)
    try:
        with progress_of(args, "refine"):
            traj = refine(
                instance,
                network,
                model=args.model,
                mode=args.mode,
                corridor=args.corridor,
                solver=args.solver,
                split=args.split,
                stretch=args.stretch,
                a_max=args.a_max,
                alpha_max=args.alpha_max,
                workers=args.workers,
            )
    except InfeasibleWindowsError as exc:
        print(f"hierplan refine: infeasible: {exc}", file=sys.stderr)
        return INFEASIBLE
    write_trajectories(traj, args.out, dt=args.dt)
    if args.plot:
        from hierplan_opt.trajectory.plot import plot_trajectories

        plot_trajectories(traj, args.plot)
    st = traj.stats
    solvers = sorted({r.stats.get("solver") or "-" for r in traj.robots} - {"-"})
    line = (
        f"refined {traj.num_agents} robots ({traj.mode} mode, {'/'.join(solvers) or 'no solver'}): "
        f"makespan {traj.makespan:.6g} s, stretch {traj.stretch:.4g}, clearance "
        f"{_clearance(traj)}, {st['total_time']:.2f} s -> {args.out}"
    )
    code = OK
    if not args.no_verify:
        from hierplan_opt.trajectory.verify import verify

        rep = verify(traj, instance, dt=args.verify_dt)
        line += f"; {rep.message()}"
        code = OK if rep.ok else PLAN_INVALID
    print(line)
    return code
