"""A scoped, restored setting of Python's cyclic garbage collector for search loops.

Tree searches such as CBS allocate and drop millions of small, acyclic objects (paths,
constraint sets, heap entries, dictionaries). Reference counting frees them; the cyclic
collector finds nothing among them but still runs a generation-0 scan every 700
allocations by default, which measured 20-25 % of CBS's time on a 5 s instance.
:func:`relaxed_gc` raises the generation-0 threshold for the duration of a ``with``
block and puts the previous thresholds back afterwards, also when the block raises.

The thresholds are process-wide. The context manager is re-entrant and thread-safe:
a counter under a lock makes the first entry save and set the thresholds and the last
exit restore them, so nested or concurrent searches leave the process as they found
it. Thresholds that other code sets while a block is active are overwritten by that
restore. Nothing is done when the collector is disabled (``gc.disable()``).

Inside the block the oldest generation is not collected at all: a search keeps most
of what it allocates (the tree), so every full collection scans the whole heap, and
those pauses grow with it (1.9 s at 30 s of CBS on random-32-32-20 k60, over a
time limit when they fall at its end). Cycles made inside the block are still
collected by the two younger generations, only in larger batches; the generation-0
threshold bounds the number of container objects a batch can hold. Cyclic garbage
that outlives both younger generations waits for the first full collection after the
block.
"""

from __future__ import annotations

import gc
import threading
from collections.abc import Generator
from contextlib import contextmanager

#: Generation-0 threshold inside :func:`relaxed_gc` (Python's default is 700).
GEN0_THRESHOLD = 100_000
#: Generation-2 threshold inside :func:`relaxed_gc`: never reached (no full collection).
GEN2_NEVER = 2**31 - 1

_lock = threading.Lock()
_depth = 0
_saved: tuple[int, int, int] | None = None


@contextmanager
def relaxed_gc(gen0: int = GEN0_THRESHOLD) -> Generator[None, None, None]:
    """Collect generation 0 only every ``gen0`` allocations inside the block, and
    never the oldest generation.

    Never lowers a generation-0 threshold that is already higher; generation 1's is
    kept.

    Example
    -------
    >>> import gc
    >>> before = gc.get_threshold()
    >>> with relaxed_gc():
    ...     t = gc.get_threshold()
    ...     t[0] >= GEN0_THRESHOLD, t[2] == GEN2_NEVER
    (True, True)
    >>> gc.get_threshold() == before
    True
    """
    global _depth, _saved
    with _lock:
        if _depth == 0:
            _saved = gc.get_threshold()
            if gc.isenabled() and _saved[0] != 0:
                gc.set_threshold(max(gen0, _saved[0]), _saved[1], GEN2_NEVER)
        _depth += 1
    try:
        yield
    finally:
        with _lock:
            _depth -= 1
            if _depth == 0 and _saved is not None:
                gc.set_threshold(*_saved)
                _saved = None
