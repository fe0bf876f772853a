"""Pieces shared by the subcommands: exit codes and instance arguments."""

from __future__ import annotations

import argparse
import math
from typing import TYPE_CHECKING, NoReturn

if TYPE_CHECKING:
    from hierplan_opt.core.instance import Instance

OK = 0
PLAN_INVALID = 1
BAD_INPUT = 2
INFEASIBLE = 3
LIMIT = 4
INTERNAL = 70  # EX_SOFTWARE: a bug in hierplan, never a user error


def add_instance_arguments(p: argparse.ArgumentParser) -> None:
    """``INSTANCE [--scen FILE --agents K]``: a YAML instance, or a .map with a .scen."""
    p.add_argument(
        "instance",
        metavar="INSTANCE",
        help="instance file: a YAML instance (own or libMultiRobotPlanning format) or a "
        "MovingAI .map (then --scen is required)",
    )
    p.add_argument("--scen", metavar="FILE", help="MovingAI .scen file for a .map instance")
    p.add_argument(
        "--agents",
        metavar="K",
        type=positive_int,
        help="use the first K agents of the scenario (default: all)",
    )


def load_instance_from_args(args: argparse.Namespace) -> Instance:
    """Read the instance named by :func:`add_instance_arguments`."""
    from hierplan_opt.io import load_instance

    return load_instance(args.instance, scen=args.scen, agents=args.agents)


def positive_int(text: str) -> int:
    """argparse type: an integer >= 1."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a positive integer, got {text!r}") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"expected a positive integer, got {text!r}")
    return value


def positive_float(text: str) -> float:
    """argparse type: a finite number > 0."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a positive number, got {text!r}") from None
    if not math.isfinite(value) or value <= 0:
        raise argparse.ArgumentTypeError(f"expected a positive number, got {text!r}")
    return value


def one_line_errors(p: argparse.ArgumentParser, command: str) -> None:
    """Make usage errors of a subcommand one line on stderr (exit code 2, no usage dump).

    Example
    -------
    >>> p = argparse.ArgumentParser()
    >>> one_line_errors(p, "hierplan demo")
    >>> p.add_argument("--k", type=int) and None
    >>> try:
    ...     p.parse_args(["--k", "x"])
    ... except SystemExit as exc:
    ...     print(exc.code)
    2
    """

    def error(message: str) -> NoReturn:
        p.exit(2, f"{command}: error: {message} (see '{command} --help')\n")

    p.error = error  # type: ignore[method-assign]
