"""A scoped, restored pause of Python's cyclic garbage collector for search loops.

Tree searches such as CBS allocate millions of small objects and keep most of them (the
tree). Reference counting frees what they drop; the cyclic collector finds nothing
among them, yet every collection scans the young objects and the full ones the whole
heap, in pauses that grow with it:

- default thresholds: 20-25 % of CBS's time on a 5 s instance, and 9.7 of 30 s of
  EECBS on empty-32-32-even-1 k200 (w 1.005);
- generation 0 raised to 100,000 (the previous setting here): still 13 % of CBS on
  random-32-32-20-random-1 k50 (2.7 of 20.6 s) and 9 % on room-32-32-4-even-1 k30,
  with full collections of 1.9 s at 30 s on random k60, over a time limit when they
  fall at its end.

:func:`paused_gc` turns the collector off for the duration of a ``with`` block and
back on afterwards, also when the block raises. The searches that run inside it
leave no cyclic garbage (``tests/test_collector.py`` checks CBS, ECBS and EECBS with
the collector's debug list): what they drop is freed at once, and their trees when
the search object dies, inside the block (within the time limit, see
``Deadline.keep_back_heap``).

The switch is process-wide. The context manager is re-entrant and thread-safe: a
counter under a lock makes the first entry record the state and turn the collector
off, and the last exit turn it back on if it was on. Nothing changes when the
collector is already off.
"""

from __future__ import annotations

import gc
import threading
from collections.abc import Generator
from contextlib import contextmanager

_lock = threading.Lock()
_depth = 0
_was_enabled = False


@contextmanager
def paused_gc() -> Generator[None, None, None]:
    """The cyclic garbage collector off inside the block (see the module doc).

    Example
    -------
    >>> import gc
    >>> before = gc.isenabled()
    >>> with paused_gc():
    ...     gc.isenabled()
    False
    >>> gc.isenabled() == before
    True
    """
    global _depth, _was_enabled
    with _lock:
        if _depth == 0:
            _was_enabled = gc.isenabled()
            gc.disable()
        _depth += 1
    try:
        yield
    finally:
        with _lock:
            _depth -= 1
            if _depth == 0 and _was_enabled:
                gc.enable()
