"""Wall-clock deadlines shared by every solver, and the memory watch of long searches."""

from __future__ import annotations

import math
import sys
import time
from typing import cast

from hierplan_opt.core.errors import OptionError
from hierplan_opt.core.resources import MEMORY_MARGIN, memory_available, memory_limits, memory_use


def check_time_limit(time_limit: float | None, *, allow_zero: bool = False) -> float | None:
    """``time_limit`` if it is None (no limit) or a positive number of seconds.

    ``allow_zero`` admits an exhausted budget (internal deadlines); users give ``> 0``.

    Example
    -------
    >>> check_time_limit(2.5), check_time_limit(None)
    (2.5, None)
    >>> check_time_limit(0)
    Traceback (most recent call last):
    ...
    hierplan_opt.core.errors.OptionError: time_limit must be a positive number of seconds, got 0
    """
    if time_limit is None:
        return None
    given = cast(object, time_limit)  # callers may pass anything: check at run time
    if (
        isinstance(given, bool)
        or not isinstance(given, (int, float))
        or not math.isfinite(given)
        or given < 0
        or (given == 0 and not allow_zero)
    ):
        what = "a number of seconds >= 0" if allow_zero else "a positive number of seconds"
        raise OptionError(f"time_limit must be {what}, got {time_limit!r}")
    return float(time_limit)


#: Seconds it takes to free one block of Python's small-object allocator: 91-99 ns
#: measured freeing CBS's OPEN (11-14 million blocks: random-32-32-20 k60 and
#: empty-32-32 k200 after 30 s), 128 ns for EECBS's tree (14 million blocks,
#: empty-32-32 k200 after 60 s). Freeing is one cascade of C calls, so it can only be
#: budgeted for, not interrupted.
FREE_S_PER_BLOCK = 130e-9
#: Seconds between two measurements of :meth:`Deadline.keep_back_heap`.
HEAP_CHECK_S = 0.25


class Deadline:
    """A wall-clock budget that starts when the object is made.

    ``None`` means no limit. Solvers poll :meth:`expired` in their main loop and hand
    :meth:`remaining` to back ends (CP-SAT, HiGHS, IPOPT).

    Example
    -------
    >>> d = Deadline(None)
    >>> d.expired(), d.remaining()
    (False, inf)
    """

    __slots__ = (
        "limit",
        "start",
        "stopped_by",
        "_end",
        "_kept",
        "_heap_base",
        "_heap_next",
        "_limits",
        "_margins",
        "_short",
    )

    def __init__(self, time_limit: float | None) -> None:
        self.limit = time_limit = check_time_limit(time_limit, allow_zero=True)
        self.start = time.perf_counter()
        self._end = math.inf if time_limit is None else self.start + time_limit
        self._kept = 0.0
        self._heap_base = -1  # allocated blocks at the first keep_back_heap call
        # perf_counter time of its next measurement: the first after HEAP_CHECK_S, so a
        # short solve never pays one (sys.getallocatedblocks walks the arenas, /proc)
        self._heap_next = self.start + HEAP_CHECK_S
        # The memory limits and the margins below them, read at the first measurement
        # (a deadline of a short call never reads them); see _memory_short.
        self._limits: tuple[float, float] | None = None
        self._margins = (MEMORY_MARGIN, MEMORY_MARGIN)
        #: None, or ``"memory_limit"`` once :meth:`keep_back_heap` stopped the search
        #: near the data limit (then :meth:`expired` is True).
        self.stopped_by: str | None = None
        self._short = ""  # what ran short, for stop_stats

    def expired(self) -> bool:
        """True once the budget is used up."""
        return time.perf_counter() >= self._end - self._kept

    def keep_back(self, seconds: float) -> None:
        """Keep the budget's last ``seconds`` for the work after the main loop:
        :meth:`expired` and :meth:`remaining` count them as spent. Each call replaces
        the reserve before.

        Example
        -------
        >>> d = Deadline(10.0)
        >>> d.keep_back(4.0)
        >>> 5.9 < d.remaining() <= 6.0
        True
        """
        self._kept = max(0.0, float(seconds))

    def keep_back_heap(self) -> None:
        """Keep back the time it takes to free what the caller allocated since its
        first measurement (see :data:`FREE_S_PER_BLOCK`); measured from
        :data:`HEAP_CHECK_S` seconds on and at most every :data:`HEAP_CHECK_S` seconds,
        so a search may call it once per iteration.

        A search that holds millions of objects takes seconds to free them when it
        returns (CBS's OPEN on empty-32-32 k200: 2.7 s after a 60 s limit); the time
        limit covers that too.

        Example
        -------
        >>> d = Deadline(10.0)
        >>> d._heap_next = 0.0  # measure now (normally from HEAP_CHECK_S on)
        >>> d.keep_back_heap()
        >>> heap = [[i] for i in range(200_000)]
        >>> d._heap_next = 0.0  # measure again now (normally every HEAP_CHECK_S)
        >>> d.keep_back_heap()
        >>> d.remaining() < 9.99
        True
        """
        now = time.perf_counter()
        if now < self._heap_next:
            return
        self._heap_next = now + HEAP_CHECK_S
        short = self._memory_short()
        if short:
            self.stop_for_memory(short)
            return
        if self._end == math.inf:
            return
        blocks = sys.getallocatedblocks()  # walks pymalloc's arenas: ~1 ms per GB
        if self._heap_base < 0:
            self._heap_base = blocks
        self.keep_back(FREE_S_PER_BLOCK * max(0, blocks - self._heap_base))

    def _memory_short(self) -> str:
        """What is short if the process is within its margin of one of its memory limits
        or the machine (or container) has less than ``MEMORY_MARGIN`` left, else ""
        (see :mod:`.resources`).

        The margin below a limit is ``MEMORY_MARGIN``, or a quarter of the room left at
        the first call if that is less (a 512 MB sweep worker with numba loaded has
        60-190 MB left: a fixed 256 MB would stop every search at once)."""
        if memory_available() < MEMORY_MARGIN:
            return f"the machine's free memory (under {MEMORY_MARGIN >> 20} MB left)"
        limits = self._limits
        first = limits is None
        if limits is None:  # read once (``hierplan`` sets them before any solve)
            limits = self._limits = memory_limits()
        if min(limits) == math.inf:
            return ""
        uses = memory_use()
        if first:
            room = [max(0.0, x - u) for x, u in zip(limits, uses, strict=True)]
            self._margins = (min(MEMORY_MARGIN, room[0] / 4), min(MEMORY_MARGIN, room[1] / 4))
        for i, use in enumerate(uses):
            if use > limits[i] - self._margins[i]:
                # RLIMIT_DATA is what ``hierplan solve --memory-limit`` sets
                hint = ", --memory-limit GB raises it" if i == 0 else ""
                return f"the memory limit ({limits[i] / (1 << 30):.1f} GB{hint})"
        return ""

    def stop_for_memory(self, short: str = "the memory limit") -> None:
        """End the budget now because memory ran short (see ``resources.MEMORY_MARGIN``).

        Example
        -------
        >>> d = Deadline(None)
        >>> d.stop_for_memory()
        >>> d.expired(), d.remaining(), d.stopped_by
        (True, 0.0, 'memory_limit')
        """
        self.stopped_by = "memory_limit"
        self._short = short
        self._end = -math.inf

    def stop_stats(self, what: str) -> dict[str, str]:
        """The entries a result's ``stats`` gets when ``what`` stopped for memory
        (``stopped_by`` and a one-line ``reason``); none otherwise.

        Example
        -------
        >>> d = Deadline(None)
        >>> d.stop_stats("CBS")
        {}
        >>> d.stop_for_memory()
        >>> d.stop_stats("CBS")["reason"][:31]
        'CBS stopped at the memory limit'
        """
        if self.stopped_by is None:
            return {}
        reason = (
            f"{what} stopped at {self._short or 'the memory limit'} after {self.elapsed():.1f} s"
        )
        return {"stopped_by": self.stopped_by, "reason": reason}

    def limit_stats(self, what: str) -> dict[str, str]:
        """The entries a result's ``stats`` gets when this budget stopped ``what``: those
        of :meth:`stop_stats` when memory ran short, else ``stopped_by="time_limit"``
        (the name the summary line shows, as the formulations' ``stopped_by``).

        Example
        -------
        >>> Deadline(0).limit_stats("ECBS")
        {'stopped_by': 'time_limit'}
        >>> d = Deadline(None)
        >>> d.stop_for_memory()
        >>> d.limit_stats("ECBS")["stopped_by"]
        'memory_limit'
        """
        return self.stop_stats(what) or {"stopped_by": "time_limit"}

    def remaining(self) -> float:
        """Seconds left (``inf`` without a limit, never negative)."""
        return max(0.0, self._end - self._kept - time.perf_counter())

    def elapsed(self) -> float:
        """Seconds since the deadline was made."""
        return time.perf_counter() - self.start
