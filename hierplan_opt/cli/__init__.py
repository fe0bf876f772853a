"""The ``hierplan`` command line.

Each subcommand lives in its own module of this package with ``HELP``,
``add_arguments(parser)`` and ``run(args) -> int``; :data:`COMMANDS` lists them in the
order ``--help`` shows. Heavy imports happen inside ``run``.

Exit codes: 0 success, 1 plan invalid, 2 bad input or usage (also an output that
cannot be written), 3 proven infeasible, 4 limit reached without a plan; 70 only for an
internal bug.
"""

from __future__ import annotations

import argparse
import importlib
import sys
from collections.abc import Sequence

from hierplan_opt.cli.common import (
    BAD_INPUT,
    INTERNAL,
    LIMIT,
    apply_limits,
    configure_logging,
    memory_guard,
    one_line_errors,
    refuse_overwriting_inputs,
)
from hierplan_opt.core.errors import HierplanError
from hierplan_opt.core.version import __version__

COMMANDS = (
    "solve",
    "validate",
    "info",
    "verify",
    "post",
    "refine",
    "convert",
    "simulate",
    "run",
    "bench",
    "sweep",
    "view",
    "lifelong",
)


def build_parser(command: str | None = None) -> argparse.ArgumentParser:
    """The argument parser with every available subcommand.

    With ``command``, only that subcommand gets its arguments (the others are listed
    with their help line): filling in another's choices may import heavy modules
    (``simulate``'s policies import the execution layer, ~0.1 s).
    """
    parser = argparse.ArgumentParser(
        prog="hierplan",
        description="Plan generation (MAPF/TAPF), MAPF-POST scheduling and execution "
        "for robot teams.",
        epilog="exit codes: 0 success, 1 plan invalid, 2 bad input or usage, "
        "3 proven infeasible, 4 limit reached without a plan",
    )
    parser.add_argument("-q", "--quiet", action="store_true", help="only warnings and errors")
    parser.add_argument("-v", "--verbose", action="store_true", help="debug logging")
    parser.add_argument("--debug", action="store_true", help="show tracebacks of internal errors")
    parser.add_argument("--version", action="version", version=f"hierplan {__version__}")
    one_line_errors(parser, "hierplan")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True
    for name in COMMANDS:
        mod = importlib.import_module(f"hierplan_opt.cli.{name}")
        p = sub.add_parser(name, help=mod.HELP, description=mod.HELP)
        one_line_errors(p, f"hierplan {name}")
        if command is None or name == command:
            mod.add_arguments(p)
        p.set_defaults(_run=mod.run)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``hierplan`` console script; returns the exit code."""
    argv = sys.argv[1:] if argv is None else list(argv)
    # The global options take no value, so the first other word names the subcommand.
    word = next((a for a in argv if not a.startswith("-")), None)
    parser = build_parser(word if word in COMMANDS else None)
    args = parser.parse_args(argv)
    configure_logging(verbose=args.verbose, quiet=args.quiet)
    from hierplan_opt.io.files import limits, set_limits

    try:
        before = limits()  # HIERPLAN_MAX_* from the environment
    except HierplanError as exc:
        print(f"hierplan {args.command}: error: {exc}", file=sys.stderr)
        return BAD_INPUT
    try:
        refuse_overwriting_inputs(args, argv)
        apply_limits(args)
        with memory_guard(args):
            return int(args._run(args))
    except HierplanError as exc:
        print(f"hierplan {args.command}: error: {exc}", file=sys.stderr)
        return BAD_INPUT
    except OSError as exc:
        # a file the command reads or writes (every reader and writer of the package
        # turns these into one-line errors already; this catches the rest)
        where = f"{exc.filename}: " if exc.filename else ""
        print(f"hierplan {args.command}: error: {where}{exc.strerror or exc}", file=sys.stderr)
        return BAD_INPUT
    except MemoryError:
        print(
            f"hierplan {args.command}: error: out of memory (over the memory budget; "
            "certify fewer agents or raise --memory-limit)",
            file=sys.stderr,
        )
        return LIMIT
    except KeyboardInterrupt:
        print(f"hierplan {args.command}: interrupted", file=sys.stderr)
        return 130
    except Exception as exc:  # an internal bug, not a user error
        if args.debug:
            raise
        if type(exc).__module__ == "sqlite3":  # a damaged store is bad input
            print(
                f"hierplan {args.command}: error: the SQLite database cannot be used: {exc} "
                "(a damaged file, or not one that hierplan sweep wrote)",
                file=sys.stderr,
            )
            return BAD_INPUT
        print(
            f"hierplan {args.command}: internal error: {type(exc).__name__}: {exc} "
            "(run with --debug for the traceback)",
            file=sys.stderr,
        )
        return INTERNAL
    finally:
        set_limits(before)
