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
    load_instance_from_args,
    positive_float,
    positive_int,
    progress_of,
)
from hierplan_opt.core.errors import InputError

HELP = "refine a MAPF-POST schedule into velocity- and acceleration-limited trajectories"
PLOT_FORMATS = (".png", ".pdf", ".svg")


def _stretch(text: str) -> float | str | None:
    if text == "auto":
        return text
    if text == "none":
        return None
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"expected 'auto', 'none' or a number >= 1, got {text!r}"
        ) from None
    if not math.isfinite(value) or value < 1:
        raise argparse.ArgumentTypeError(f"expected 'auto', 'none' or a number >= 1, got {text!r}")
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
        help="auto (default): by size, IPOPT up to 32 robots (and in corridor mode), "
        "profile+qp beyond (the summary line names it); ipopt/fatrop: the NLP; "
        "profile: path mode without an NLP (fast); profile+qp: the profile smoothed by a QP",
    )
    p.add_argument(
        "--stretch",
        type=_stretch,
        default="auto",
        help="auto (default): slow the schedule down by a factor that makes every robot "
        "feasible (1 when it already is; the summary line gives it); a number: by that "
        "factor; none: do not stretch, report an infeasible robot and the factor (exit 3)",
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
        "exit codes: 0 refined and verified (and written), 1 verification failed (nothing "
        "written), 2 bad input, 3 the robots' limits cannot meet the windows with "
        "--stretch none or a number (the message gives the factor that works)"
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
    st = traj.stats
    solvers = sorted({r.stats.get("solver") or "-" for r in traj.robots} - {"-"})
    used = "/".join(solvers) or "no solver"
    if st.get("solver_asked") == "auto":
        picked = st.get("solver", used)
        used = f"solver auto: {picked} for {traj.num_agents} robots" + (
            "" if used == picked else f", ran {used}"
        )
    line = (
        f"refined {traj.num_agents} robots ({traj.mode} mode, {used}): "
        f"makespan {traj.makespan:.6g} s, stretch {traj.stretch:.4g}, clearance "
        f"{_clearance(traj)}, {st['total_time']:.2f} s"
    )
    if not args.no_verify:
        # Verified before anything is written: a result that fails its own check is not
        # written (issue 34); --no-verify writes without the check, and says so.
        from hierplan_opt.trajectory.verify import verify

        rep = verify(traj, instance, dt=args.verify_dt)
        if not rep.ok:
            print(f"{line}, not written; {rep.message()}")
            return PLAN_INVALID
    write_trajectories(traj, args.out, dt=args.dt)
    if args.plot:
        from hierplan_opt.trajectory.plot import plot_trajectories

        plot_trajectories(traj, args.plot)
    tail = "not verified (--no-verify)" if args.no_verify else rep.message()
    print(f"{line} -> {args.out}; {tail}")
    return OK
