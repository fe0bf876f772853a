"""Wall-clock deadlines shared by every solver."""

from __future__ import annotations

import math
import time


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

    __slots__ = ("limit", "start", "_end")

    def __init__(self, time_limit: float | None) -> None:
        if time_limit is not None and (not math.isfinite(time_limit) or time_limit < 0):
            from hierplan_opt.core.errors import OptionError

            raise OptionError(f"time_limit must be a finite number >= 0, got {time_limit!r}")
        self.limit = time_limit
        self.start = time.perf_counter()
        self._end = math.inf if time_limit is None else self.start + time_limit

    def expired(self) -> bool:
        """True once the budget is used up."""
        return time.perf_counter() >= self._end

    def remaining(self) -> float:
        """Seconds left (``inf`` without a limit, never negative)."""
        return max(0.0, self._end - time.perf_counter())

    def elapsed(self) -> float:
        """Seconds since the deadline was made."""
        return time.perf_counter() - self.start
