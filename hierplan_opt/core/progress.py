"""Progress of long work: a Rich bar on a terminal, a periodic status line elsewhere.

One small class for every long loop of the toolkit (sweeps, Monte Carlo runs, a CBS
search, a horizon ladder, an LP solve). The caller says how far it got and which
figures to show (``solved=12``, ``lb=431``, ``best=440``); :class:`Progress` decides how
to show them:

* on a terminal, a Rich progress bar (bar, ``done/total``, the figures, elapsed time,
  ETA), drawn on stderr;
* otherwise (a log file, CI), one ``INFO`` log line on the ``hierplan_opt.progress``
  logger every ``interval`` seconds and one at the end, so ``hierplan -q`` hides them;
* with ``enabled=False``, nothing at all (the figures are still kept).

Solvers do not take a progress object: the caller makes one the *active* progress with
:func:`reporting` (``hierplan solve --progress`` does), and a long loop calls
:func:`tick` with its count and figures (CBS and ECBS once per high-level expansion,
the formulations once per horizon, trajectory refinement once per robot). Without an
active progress :func:`tick` is one context-variable lookup.

Rich is imported only when a bar is drawn.
"""

from __future__ import annotations

import logging
import math
import sys
import threading
import time
from collections.abc import Generator
from contextlib import contextmanager
from contextvars import ContextVar
from types import TracebackType
from typing import Any, TextIO

log = logging.getLogger("hierplan_opt.progress")


def format_duration(seconds: float) -> str:
    """``H:MM:SS`` (or ``M:SS`` under an hour); ``-`` when unknown.

    Example
    -------
    >>> format_duration(75.4), format_duration(3725), format_duration(math.inf)
    ('1:15', '1:02:05', '-')
    """
    if not math.isfinite(seconds) or seconds < 0:
        return "-"
    s = int(round(seconds))
    h, rest = divmod(s, 3600)
    m, s = divmod(rest, 60)
    return f"{h}:{m:02d}:{s:02d}" if h else f"{m}:{s:02d}"


def _figure(value: Any) -> str:
    if isinstance(value, float):
        return f"{value:.4g}"
    return str(value)


class Progress:
    """How far a long piece of work is, shown as a bar or as periodic status lines.

    Parameters
    ----------
    description
        What is running (``"sweep cbs"``, ``"CBS"``); starts every status line.
    total
        Number of steps when known (runs of a sweep); ``None`` for open-ended work
        (a search), which then shows a count and the figures without a bar or ETA.
    unit
        Name of one step in the status line (``"runs"``, ``"nodes"``).
    enabled
        ``False`` shows nothing; ``None`` (default) shows a bar when ``stream`` is a
        terminal and status lines otherwise.
    interval
        Seconds between two status lines on a non-terminal.
    stream
        Where a bar is drawn (default ``sys.stderr``).

    Example
    -------
    >>> with Progress("demo", total=4, unit="runs", enabled=False) as p:
    ...     for solved in (True, False, True, True):
    ...         p.advance(solved=p.fields.get("solved", 0) + solved)
    >>> p.completed, p.fields["solved"]
    (4, 3)
    >>> p.status_line().split(",")[0]
    'demo: 4/4 runs'
    """

    def __init__(
        self,
        description: str,
        total: int | None = None,
        *,
        unit: str = "",
        enabled: bool | None = None,
        interval: float = 10.0,
        stream: TextIO | None = None,
    ) -> None:
        self.description = description
        self.total = total
        self.unit = unit
        self.interval = interval
        self.completed = 0
        self.fields: dict[str, Any] = {}
        self._stream = stream if stream is not None else sys.stderr
        if enabled is None:
            isatty = getattr(self._stream, "isatty", None)
            self.mode = "bar" if callable(isatty) and isatty() else "lines"
        else:
            self.mode = "lines" if enabled else "off"
        self._start = time.perf_counter()
        self._last_line = self._start
        self._bar: Any = None
        self._task: Any = None
        self._unshown = True  # an update (or the start) no status line has shown yet

    # ------------------------------------------------------------------ context
    def __enter__(self) -> Progress:
        self._start = self._last_line = time.perf_counter()
        if self.mode == "bar":
            self._start_bar()
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()

    def close(self) -> None:
        """Stop the bar, or write the final status line."""
        if self._bar is not None:
            self._refresh_bar()
            self._bar.stop()
            self._bar = None
        elif self.mode == "lines":
            if self._unshown:  # the last periodic line may already say it all
                log.info("%s", self.status_line())
            self.mode = "off"  # one final line only

    # ------------------------------------------------------------------ updates
    def advance(self, n: int = 1, **fields: Any) -> None:
        """``n`` more steps are done; ``fields`` replace the shown figures."""
        self.update(completed=self.completed + n, **fields)

    def update(
        self, *, completed: int | None = None, total: int | None = None, **fields: Any
    ) -> None:
        """Set the step count, the total or some figures (``lb=431``, ``best=440``)."""
        if completed is not None:
            self.completed = completed
        if total is not None:
            self.total = total
        self.fields.update(fields)
        self._unshown = True
        if self._bar is not None:
            self._refresh_bar()
        elif self.mode == "lines":
            now = time.perf_counter()
            if now - self._last_line >= self.interval:
                self._last_line = now
                self._unshown = False
                log.info("%s", self.status_line())

    def beat(self) -> None:
        """A status line when none was shown for ``interval`` seconds, whether or not
        anything changed: the heartbeat of silent work (a model being built), called
        from another thread (:func:`heartbeat`). A bar keeps its own elapsed time."""
        if self.mode == "lines":
            now = time.perf_counter()
            if now - self._last_line >= self.interval:
                self._last_line = now
                self._unshown = False
                log.info("%s", self.status_line())

    # ------------------------------------------------------------------ figures
    @property
    def elapsed(self) -> float:
        """Seconds since the work started."""
        return time.perf_counter() - self._start

    @property
    def eta(self) -> float:
        """Estimated seconds to go (``inf`` when unknown): elapsed / done * left."""
        if self.total is None or self.completed <= 0:
            return math.inf
        return self.elapsed / self.completed * max(0, self.total - self.completed)

    def _figures(self) -> str:
        # a copy: the heartbeat thread may read while the work thread updates
        return ", ".join(f"{k} {_figure(v)}" for k, v in list(self.fields.items()))

    def status_line(self) -> str:
        """``"sweep: 12/40 runs, solved 9, 0:31 elapsed, ETA 1:40"``."""
        parts = [f"{self.description}: {self._count()}"]
        if self.fields:
            parts.append(self._figures())
        parts.append(f"{format_duration(self.elapsed)} elapsed")
        if self.total is not None:
            parts.append(f"ETA {format_duration(self.eta)}")
        return ", ".join(parts)

    # ------------------------------------------------------------------ Rich
    def _start_bar(self) -> None:
        from rich.console import Console
        from rich.progress import (  # heavy module: rich
            BarColumn,
            MofNCompleteColumn,
            TextColumn,
            TimeElapsedColumn,
            TimeRemainingColumn,
        )
        from rich.progress import Progress as RichProgress  # heavy module: rich

        columns: list[Any] = [TextColumn("[bold]{task.description}")]
        if self.total is not None:
            columns += [BarColumn(), MofNCompleteColumn()]
        else:  # a count whose unit (and total) the work may set later
            columns += [TextColumn("{task.fields[count]}")]
        columns += [TextColumn("{task.fields[figures]}"), TimeElapsedColumn()]
        if self.total is not None:
            columns += [TextColumn("ETA"), TimeRemainingColumn()]
        self._bar = RichProgress(
            *columns, console=Console(file=self._stream), transient=False, refresh_per_second=4
        )
        self._bar.start()
        self._task = self._bar.add_task(
            self.description, total=self.total, completed=self.completed, figures="", count=""
        )
        self._refresh_bar()

    def _count(self) -> str:
        if self.total is None and not self.unit and not self.completed:
            return "started"  # nothing counted (yet)
        count = f"{self.completed}" if self.total is None else f"{self.completed}/{self.total}"
        return count + (" " + self.unit if self.unit else "")

    def _refresh_bar(self) -> None:
        self._bar.update(
            self._task,
            completed=self.completed,
            total=self.total,
            figures=self._figures(),
            count=self._count(),
        )


_ACTIVE: ContextVar[Progress | None] = ContextVar("hierplan_opt_progress", default=None)


@contextmanager
def reporting(progress: Progress | None) -> Generator[Progress | None]:
    """Make ``progress`` the active one inside the block (opened and closed with it);
    ``None`` leaves progress off.

    Example
    -------
    >>> with reporting(Progress("solve", enabled=False)) as p:
    ...     for n in range(1, 4):
    ...         tick("expanded", n, lb=10 + n)
    >>> p.status_line().split(",")[:2], active() is None
    (['solve: 3 expanded', ' lb 13'], True)
    """
    if progress is None:
        yield None
        return
    token = _ACTIVE.set(progress)
    try:
        with progress:
            yield progress
    finally:
        _ACTIVE.reset(token)


@contextmanager
def heartbeat(progress: Progress | None) -> Generator[None]:
    """Call ``progress.beat()`` from a background thread every ``interval`` seconds
    inside the block, so that status lines keep coming while the work reports nothing
    (``hierplan verify --progress`` building a time-expanded model for seconds).

    Example
    -------
    >>> with reporting(Progress("demo", enabled=False, interval=0.01)) as p, heartbeat(p):
    ...     time.sleep(0.05)
    """
    if progress is None:
        yield
        return
    stop = threading.Event()

    def loop() -> None:
        while not stop.wait(max(progress.interval, 0.01)):
            progress.beat()

    thread = threading.Thread(target=loop, name="hierplan-heartbeat", daemon=True)
    thread.start()
    try:
        yield
    finally:
        stop.set()
        thread.join()


def active() -> Progress | None:
    """The progress :func:`tick` updates now, if any."""
    return _ACTIVE.get()


def note(**fields: Any) -> None:
    """Set figures of the active progress (None values are left out), e.g. the final
    cost and bound of a result; nothing without an active progress."""
    progress = _ACTIVE.get()
    if progress is not None:
        progress.update(**{k: v for k, v in fields.items() if v is not None})


def tick(unit: str, done: int, total: int | None = None, **fields: Any) -> None:
    """Report ``done`` steps (``unit``: ``"expanded"``, ``"robots"``...) and figures to
    the active progress; nothing without one (see :func:`reporting`)."""
    progress = _ACTIVE.get()
    if progress is not None:
        progress.unit = unit
        shown = {k: v for k, v in fields.items() if v is not None}
        progress.update(completed=done, total=total, **shown)


#: Seconds between two updates a solver callback makes (HiGHS calls back every few
#: simplex iterations or branch-and-bound nodes).
CALLBACK_INTERVAL = 0.2


@contextmanager
def watching_highs(highs: Any) -> Generator[None]:
    """Show a running HiGHS solve on the active progress, with HiGHS' own figures:
    branch-and-bound nodes, primal and dual bounds and gap of a MIP (``mip_nodes``,
    ``mip_primal``, ``mip_dual``, ``mip_gap``), simplex or IPM iterations and objective
    of an LP (``lp_iter``, ``lp_obj``).

    ``highs`` is a ``highspy.Highs``; its interrupt callbacks update the progress at
    most every :data:`CALLBACK_INTERVAL` seconds, and at once for every better
    incumbent (figures HiGHS has not got yet, infinite bounds, are left out). Without
    an active progress nothing is subscribed (no cost).
    """
    progress = _ACTIVE.get()
    if progress is None:
        yield
        return
    last = [-math.inf]

    def due() -> bool:
        now = time.perf_counter()
        if now - last[0] < CALLBACK_INTERVAL:
            return False
        last[0] = now
        return True

    def finite(**figures: float) -> dict[str, Any]:
        return {k: float(v) for k, v in figures.items() if math.isfinite(v)}

    def on_mip(e: Any, force: bool = False) -> None:
        if force or due():
            out = e.data_out
            progress.update(
                mip_nodes=max(0, int(out.mip_node_count)),
                **finite(
                    mip_primal=out.mip_primal_bound,
                    mip_dual=out.mip_dual_bound,
                    mip_gap=out.mip_gap,
                ),
            )

    def on_solution(e: Any) -> None:  # a better incumbent: shown at once
        on_mip(e, force=True)

    def on_lp(e: Any) -> None:
        if due():
            out = e.data_out
            iters = max(int(out.simplex_iteration_count), int(out.ipm_iteration_count))
            progress.update(lp_iter=iters, **finite(lp_obj=out.objective_function_value))

    subscribed = [
        (highs.cbMipInterrupt, on_mip),
        (highs.cbMipImprovingSolution, on_solution),
        (highs.cbSimplexInterrupt, on_lp),
        (highs.cbIpmInterrupt, on_lp),
    ]
    for event, fn in subscribed:
        event.subscribe(fn)
    try:
        yield
    finally:
        for event, fn in subscribed:
            event.unsubscribe(fn)
