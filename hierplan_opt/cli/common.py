"""Pieces shared by the subcommands: exit codes, instance arguments, output checks.

Every command that writes files checks all its outputs before any work with
:func:`check_outputs` (missing folder, parent that is a file, a device such as
``/dev/full``, an unsupported extension, an empty name, two options naming one file)
and writes them with the atomic writers of :mod:`hierplan_opt.io.files`.
"""

from __future__ import annotations

import argparse
import contextlib
import logging
import math
import sys
from collections.abc import Iterable, Iterator, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, NoReturn

from hierplan_opt.core.errors import InputError
from hierplan_opt.core.resources import data_size

if TYPE_CHECKING:
    from hierplan_opt.core.instance import Instance

#: Extensions of plan files in the libMultiRobotPlanning layout.
PLAN_SUFFIXES = (".yaml", ".yml", ".json")

OK = 0
PLAN_INVALID = 1
BAD_INPUT = 2
INFEASIBLE = 3
LIMIT = 4
#: An execution (``simulate``/``run``) left a working robot away from its goal.
NOT_ARRIVED = 5
INTERNAL = 70  # EX_SOFTWARE: a bug in hierplan, never a user error


#: Loggers whose INFO lines narrate a solve (periodic node counts, a first plan, each
#: horizon): ``--progress`` shows the same as one status line, so without ``-v`` the
#: command line shows only their warnings (issue 34: INFO lines on every ecbs solve,
#: progress lines twice).
SOLVER_LOGGERS = ("hierplan_opt.search", "hierplan_opt.formulations", "hierplan_opt.registry")


#: A result's stats that say why its solver stopped (``stopped_by``: the limit's name,
#: e.g. ``time_limit``, ``node_limit``, ``memory_limit``, ``max_horizon``), where its
#: plan comes from (``plan_from``: ``lacam`` for ECBS/EECBS's fallback) and whether it
#: is within the bound asked (``bound_met``): every summary line shows them.
RESULT_FACTS = ("stopped_by", "plan_from", "bound_met")


def result_facts(stats: dict) -> str:
    """``key=value`` for each of :data:`RESULT_FACTS` in ``stats`` (booleans in lower
    case), separated by spaces; "" when there is none.

    Example
    -------
    >>> result_facts({"stopped_by": "time_limit", "bound_met": False, "runtime": 2.0})
    'stopped_by=time_limit bound_met=false'
    >>> result_facts({})
    ''
    """
    parts = []
    for key in RESULT_FACTS:
        if key in stats:
            value = stats[key]
            parts.append(f"{key}={str(value).lower() if isinstance(value, bool) else value}")
    return " ".join(parts)


def configure_logging(*, verbose: bool = False, quiet: bool = False) -> None:
    """The command line's logging: INFO (``-v``: DEBUG, ``-q``: WARNING) on stderr, the
    solvers' narration (:data:`SOLVER_LOGGERS`) at WARNING unless ``-v``.

    Example
    -------
    >>> "hierplan_opt.search" in SOLVER_LOGGERS  # lacam's "first plan after ..." is INFO
    True
    """
    level = logging.DEBUG if verbose else logging.WARNING if quiet else logging.INFO
    logging.basicConfig(level=level, format="%(levelname)s %(name)s: %(message)s", force=True)
    logging.getLogger("hierplan_opt").setLevel(logging.NOTSET)  # a level left by a bench
    for name in SOLVER_LOGGERS:
        logging.getLogger(name).setLevel(logging.NOTSET if verbose else logging.WARNING)


def add_instance_arguments(p: argparse.ArgumentParser, *, optional: bool = False) -> None:
    """``INSTANCE [--scen FILE --agents K]``: a YAML instance, or a .map with a .scen.

    Also ``--ignore-scen-map`` and the input limits. ``optional`` makes INSTANCE
    optional (``hierplan info --solvers``).
    """
    p.add_argument(
        "instance",
        metavar="INSTANCE",
        nargs="?" if optional else None,
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
    p.add_argument(
        "--ignore-scen-map",
        action="store_true",
        help="accept a scenario whose map field names another map file",
    )
    add_limit_arguments(p)


def add_cost_argument(p: argparse.ArgumentParser, what: str) -> None:
    """``--cost soc|makespan``: what a plan minimises, in steps (``what`` says for what);
    ``--objective`` is its old name, kept (deprecated) for scripts. Objectives are a
    schedule's (``hierplan post --objective``, seconds)."""
    p.add_argument(
        "--cost",
        choices=("soc", "makespan"),
        help=f"{what} (default: soc for MAPF, makespan for TAPF)",
    )
    p.add_argument(
        "--objective",
        dest="deprecated_objective",
        choices=("soc", "makespan"),
        help="deprecated name of --cost",
    )


def cost_of(args: argparse.Namespace) -> str | None:
    """The ``--cost`` of a command made by :func:`add_cost_argument` (``--objective``
    with a warning on stderr)."""
    old = getattr(args, "deprecated_objective", None)
    if old is None:
        return args.cost
    print(
        "hierplan: --objective is deprecated for a plan's cost, use --cost "
        "(objectives are a schedule's: hierplan post --objective)",
        file=sys.stderr,
    )
    if args.cost is not None and args.cost != old:
        raise InputError(f"--cost {args.cost} and the deprecated --objective {old} differ")
    return old


def add_limit_arguments(p: argparse.ArgumentParser) -> None:
    """``--max-input-mb`` and ``--max-grid-cells``: limits of :mod:`hierplan_opt.io.files`."""
    g = p.add_argument_group("input limits")
    g.add_argument(
        "--max-input-mb",
        metavar="MB",
        type=positive_float,
        help="largest input file read, in MiB (default 64, or HIERPLAN_MAX_INPUT_MB)",
    )
    g.add_argument(
        "--max-grid-cells",
        metavar="N",
        type=positive_int,
        help="largest grid, in cells (default 16777216, or HIERPLAN_MAX_GRID_CELLS)",
    )


def apply_limits(args: argparse.Namespace) -> None:
    """Put the ``--max-*`` options of :func:`add_limit_arguments` in force."""
    from dataclasses import replace

    from hierplan_opt.io.files import MB, limits, set_limits

    mb = getattr(args, "max_input_mb", None)
    cells = getattr(args, "max_grid_cells", None)
    if mb is None and cells is None:
        return
    new = limits()
    if mb is not None:
        new = replace(new, max_bytes=max(1, int(mb * MB)))
    if cells is not None:
        new = replace(new, max_cells=cells)
    set_limits(new)


def add_tracker_y_arguments(p: argparse.ArgumentParser) -> None:
    """``--tracker-y-down`` / ``--tracker-y-up``: the MAPF Tracker move convention of a
    plan file (``args.tracker_y``; None: detected from the scenario)."""
    g = p.add_mutually_exclusive_group()
    g.add_argument(
        "--tracker-y-down",
        dest="tracker_y",
        action="store_const",
        const="down",
        help="read MAPF Tracker moves with d = y+1 (the tracker's current documentation)",
    )
    g.add_argument(
        "--tracker-y-up",
        dest="tracker_y",
        action="store_const",
        const="up",
        help="read MAPF Tracker moves with u = y+1 (its older data); default: detect which "
        "convention fits the scenario and say so",
    )


def tracker_y_note(stats: dict) -> str:
    """`` moves=y-up (detected)`` for a tracker plan's statistics, else ``""``."""
    y = stats.get("tracker_y")
    return f" moves=y-{y} ({stats.get('tracker_y_from', 'detected')})" if y else ""


def add_memory_argument(p: argparse.ArgumentParser) -> None:
    """``--memory-limit GB``: the budget of :mod:`hierplan_opt.formulations.memory`."""
    p.add_argument(
        "--memory-limit",
        metavar="GB",
        type=positive_float,
        help="memory budget in GB: a time-expanded model (cpsat, mip, verify) estimated "
        "above it is not built, and the process may not grow by more than it (default: "
        "half the RAM, at most 80%% of the free memory; or HIERPLAN_MEMORY_LIMIT_GB)",
    )


@contextlib.contextmanager
def memory_guard(args: argparse.Namespace) -> Iterator[None]:
    """Put ``--memory-limit`` in force while a command runs, then restore everything.

    Two layers: the formulations refuse a model whose estimated size exceeds the budget
    (one line, before building it), and the process's data limit (``RLIMIT_DATA``) is
    set to its current size plus the budget plus :data:`DATA_HEADROOM`, so an estimate
    that was too low ends in a ``MemoryError`` (one line, exit 4) instead of the
    kernel's out-of-memory killer.
    Commands without the option run unchanged.
    """
    if not hasattr(args, "memory_limit"):
        yield
        return
    from hierplan_opt.core.options import AMOUNT_CAP
    from hierplan_opt.formulations.memory import GB, memory_budget, memory_limit

    if args.memory_limit is None:
        budget = memory_budget()
    else:  # a limit beyond any machine is none (and fits a C long)
        budget = int(min(args.memory_limit * GB, AMOUNT_CAP))
    with memory_limit(budget), _data_limit(budget):
        yield


def add_progress_arguments(p: argparse.ArgumentParser) -> None:
    """``--progress`` and ``--progress-interval SECONDS`` (see :func:`progress_of`)."""
    p.add_argument(
        "--progress",
        action="store_true",
        help="show how the long work goes: a bar on a terminal, else a status line "
        "(INFO, hidden by -q) every --progress-interval seconds and one at the end",
    )
    p.add_argument(
        "--progress-interval",
        type=positive_float,
        default=10.0,
        metavar="SECONDS",
        help="seconds between two status lines on a non-terminal (default: 10)",
    )


@contextlib.contextmanager
def progress_of(args: argparse.Namespace, description: str) -> Iterator[None]:
    """The command's work, with progress shown when ``--progress`` asks (not with -q):
    a status line at least every ``--progress-interval`` seconds, also through silent
    phases (a model being built).

    Example
    -------
    >>> args = argparse.Namespace(progress=False, quiet=False)
    >>> with progress_of(args, "solve cbs"):
    ...     pass
    """
    from hierplan_opt.core.progress import Progress, heartbeat, reporting

    show = getattr(args, "progress", False) and not getattr(args, "quiet", False)
    interval = getattr(args, "progress_interval", 10.0)
    progress = Progress(description, interval=interval) if show else None
    # the heartbeat: a status line every interval even while the work reports nothing
    with reporting(progress), heartbeat(progress):
        yield


#: Room beyond the model budget for everything else a command holds (instance, plan,
#: distance tables, Python objects), so the model estimate speaks first.
DATA_HEADROOM = 512 << 20


@contextlib.contextmanager
def _data_limit(budget: int) -> Iterator[None]:
    try:
        import resource
    except ImportError:  # pragma: no cover - not on POSIX: the estimate alone guards
        yield
        return
    from hierplan_opt.core.options import AMOUNT_CAP

    soft, hard = resource.getrlimit(resource.RLIMIT_DATA)
    want = data_size() + budget + DATA_HEADROOM
    if hard != resource.RLIM_INFINITY:
        want = min(want, hard)
    if soft != resource.RLIM_INFINITY:
        want = min(want, soft)
    if want >= AMOUNT_CAP:  # beyond any machine (and a C long): no limit to set
        yield
        return
    try:
        resource.setrlimit(resource.RLIMIT_DATA, (want, hard))
    except (ValueError, OSError, OverflowError):  # pragma: no cover - the estimate guards
        yield
        return
    try:
        yield
    finally:
        resource.setrlimit(resource.RLIMIT_DATA, (soft, hard))


def load_instance_from_args(args: argparse.Namespace) -> Instance:
    """Read the instance named by :func:`add_instance_arguments`."""
    from hierplan_opt.io import load_instance

    return load_instance(
        args.instance,
        scen=args.scen,
        agents=args.agents,
        check_scen_map=not getattr(args, "ignore_scen_map", False),
        shared_goals=bool(getattr(args, "disappear_at_goal", False)),
    )


def check_outputs(*outputs: tuple[str, str | Path | None, Iterable[str] | None]) -> None:
    """Check every output of a command before any work: ``(option, path, suffixes)``.

    ``path`` None means the option was not given; ``suffixes`` None allows any
    extension. Raises :class:`~hierplan_opt.core.errors.OutputError` (exit code 2).

    Example
    -------
    >>> check_outputs(("--out", "", None))
    Traceback (most recent call last):
    ...
    hierplan_opt.core.errors.OutputError: --out: the file name is empty
    """
    from hierplan_opt.io.files import check_outputs as _check

    _check(outputs)


#: Options whose value a command writes (checked against what it reads).
OUTPUT_DESTS = frozenset({"out", "dot", "gantt", "plot", "animate"})


def refuse_overwriting_inputs(args: argparse.Namespace, argv: Sequence[str]) -> None:
    """Refuse an output option that names a file the command reads (the instance, a
    plan, a problem, a delays log...): writing it would destroy the input. Checked
    before any work; only existing files can be both.

    Example
    -------
    >>> import tempfile, os
    >>> f = os.path.join(tempfile.mkdtemp(), "a.yaml"); _ = open(f, "w").write("x")
    >>> refuse_overwriting_inputs(argparse.Namespace(instance=f, out=f), [f, "--out", f])
    Traceback (most recent call last):
    ...
    hierplan_opt.core.errors.OutputError: --out ...a.yaml: the same file as the input INSTANCE; ...
    """
    import os

    from hierplan_opt.core.errors import OutputError

    def paths(value: object) -> list[str]:
        items = value if isinstance(value, (list, tuple)) else [value]
        return [str(v) for v in items if isinstance(v, (str, Path)) and str(v)]

    inputs = [
        (dest, p)
        for dest, value in vars(args).items()
        if dest not in OUTPUT_DESTS and not dest.startswith("_")
        for p in paths(value)
        if os.path.isfile(p)
    ]
    for dest in sorted(OUTPUT_DESTS):
        for out in paths(getattr(args, dest, None)):
            if not os.path.isfile(out):
                continue
            for name, p in inputs:
                with contextlib.suppress(OSError):
                    if os.path.samefile(out, p):
                        flag = f"--{name.replace('_', '-')}"
                        what = flag if flag in argv else name.upper()
                        raise OutputError(
                            f"--{dest} {out}: the same file as the input {what}; write the "
                            "output elsewhere"
                        )


def _int_at_least(text: str, low: int, what: str) -> int:
    """argparse type body: an integer >= ``low``, else the error naming ``what``."""
    try:
        value = int(text)
    except ValueError:
        value = low - 1
    if value < low:
        raise argparse.ArgumentTypeError(f"expected {what}, got {text!r}")
    return value


def positive_int(text: str) -> int:
    """argparse type: an integer >= 1."""
    return _int_at_least(text, 1, "a positive integer")


def non_negative_int(text: str) -> int:
    """argparse type: an integer >= 0 (the seeds of random delays: NumPy takes no
    negative seed)."""
    return _int_at_least(text, 0, "an integer >= 0")


def positive_float(text: str) -> float:
    """argparse type: a finite number > 0."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a positive number, got {text!r}") from None
    if not math.isfinite(value) or value <= 0:
        raise argparse.ArgumentTypeError(f"expected a positive number, got {text!r}")
    return value


def fraction(text: str) -> float:
    """argparse type: a number in [0, 1]."""
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not 0.0 <= value <= 1.0:
        raise argparse.ArgumentTypeError(f"expected a number in [0, 1], got {text!r}")
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
