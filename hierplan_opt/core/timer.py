"""Wall-clock deadlines shared by every solver."""

from __future__ import annotations

import math
import time
from typing import cast

from hierplan_opt.core.errors import OptionError


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
        self.limit = time_limit = check_time_limit(time_limit, allow_zero=True)
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
