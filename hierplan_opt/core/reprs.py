"""Short ``repr`` for result objects that hold big arrays and long tuples.

A dataclass's generated ``repr`` prints every array element: ``print(schedule)`` of a
12-robot warehouse was 34 KB, its STN 52 KB. :func:`short_repr` keeps each field that
reads in a few words as it is and summarises the others (shape and dtype of an array,
the length of a sequence, the keys of a dict, the class of a nested object).

Example
-------
>>> from dataclasses import dataclass
>>> import numpy as np
>>> @dataclass
... class Demo:
...     name: str
...     times: np.ndarray
...     __repr__ = short_repr
>>> Demo("a", np.arange(1000.0))
Demo(name='a', times=<array (1000,) float64>)
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from typing import Any, cast

import numpy as np

#: Longest field value (characters) shown as its own ``repr``.
FIELD_LIMIT = 60


def summary(value: Any, limit: int = FIELD_LIMIT) -> str:
    """``repr(value)`` when at most ``limit`` characters, else a summary of it.

    Example
    -------
    >>> summary((1, 2)), summary(tuple(range(100))), summary({"a" * 40: 1, "b" * 40: 2})
    ('(1, 2)', '<tuple of 100 int>', "<dict of 2: 'aaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaa', ...>")
    """
    if isinstance(value, np.ndarray):
        arr = cast("np.ndarray[Any, np.dtype[Any]]", value)
        if arr.size <= 6:
            text = np.array2string(arr, separator=", ", threshold=6)
            if len(text) <= limit:
                return text
        shape = ", ".join(str(n) for n in arr.shape) + ("," if arr.ndim == 1 else "")
        return f"<array ({shape}) {arr.dtype}>"
    text = repr(value)
    if len(text) <= limit:
        return text
    if isinstance(value, (tuple, list)):
        items = cast("Sequence[object]", value)
        kinds = sorted({type(x).__name__ for x in items})
        of = kinds[0] if len(kinds) == 1 else "mixed"
        return f"<{type(items).__name__} of {len(items)} {of}>"
    if isinstance(value, dict):
        table = cast("dict[object, object]", value)
        keys: list[str] = []
        for k in table:
            keys.append(repr(k))
            if sum(map(len, keys)) > limit // 2:
                break
        more = ", ..." if len(keys) < len(table) else ""
        return f"<dict of {len(table)}: {', '.join(keys)}{more}>"
    if isinstance(value, str):
        return repr(value[: limit - 5] + "...")
    return f"<{type(value).__name__}>"


def short_repr(self: Any) -> str:
    """``Class(field=value, ...)`` of a dataclass with every value :func:`summary`-ised
    (fields declared with ``repr=False`` left out); use as ``__repr__ = short_repr``.

    Example
    -------
    >>> from hierplan_opt.core.result import Result, Status
    >>> r = Result(Status.INFEASIBLE, None, solver="cbs", stats={"reason": "x" * 80})
    >>> repr(r).split(", ")[-1]
    "stats=<dict of 1: 'reason'>)"
    """
    fields = [f for f in dataclasses.fields(self) if f.repr]
    parts = [f"{f.name}={summary(getattr(self, f.name))}" for f in fields]
    return f"{type(self).__name__}({', '.join(parts)})"
