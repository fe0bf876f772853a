"""The one converter of numbers (and the containers that hold them) to file values.

Every writer of YAML, JSON, CSV comment lines and NPZ metadata passes its statistics
and settings through :func:`plain`, so that numpy scalars and arrays, tuples, enums and
the line-tracking mappings of :mod:`hierplan_opt.io.yaml` are written the same way
everywhere, and a non-finite float is written one way: as null (YAML ``null``, JSON
``null``). Files never hold ``inf`` or ``nan``: JSON has no spelling for them, and a
reader that meets null where a number belongs knows it is missing or unbounded.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from enum import Enum
from typing import Any

import numpy as np

__all__ = ["plain", "to_json"]


def plain(
    value: Any,
    *,
    digits: int | None = None,
    significant: int | None = None,
    integral: bool = False,
    strict: bool = False,
    max_depth: int | None = None,
) -> Any:
    """``value`` as plain file data: ``dict`` with string keys, ``list``, ``int``,
    ``float``, ``bool``, ``str`` and ``None``.

    - numpy integers, floats and booleans become Python ones; arrays and tuples lists;
      mappings (also :class:`~hierplan_opt.io.yaml.LDict`) dicts with ``str`` keys; an
      :class:`~enum.Enum` its value;
    - a non-finite float (``inf``, ``-inf``, ``nan``) becomes None;
    - ``digits`` rounds floats to that many decimals, ``significant`` to that many
      significant digits; ``integral`` writes a float that is a whole number after
      rounding as an ``int`` (``2`` rather than ``2.0``);
    - anything else is returned as it is, or (``strict``) raises :class:`TypeError`;
      ``max_depth`` (with ``strict``) refuses values more than that many levels down.

    Example
    -------
    >>> plain({1: (np.int64(2), 0.1234567, float("inf")), "a": np.arange(2)}, digits=3)
    {'1': [2, 0.123, None], 'a': [0, 1]}
    >>> plain([2.0000000001, float("nan"), np.float32(1.5)], digits=9, integral=True)
    [2, None, 1.5]
    >>> plain(123456.789, significant=6), plain(np.bool_(True))
    (123457.0, True)
    """
    return _plain(value, digits, significant, integral, strict, max_depth, 0)


def to_json(value: Any, **options: Any) -> str:
    """``value`` as JSON text, through :func:`plain` (a non-finite float is null, never
    ``Infinity``); ``options`` go to :func:`json.dumps` (``indent``, ``sort_keys``,
    ``default`` for objects that are no file data).

    Example
    -------
    >>> to_json({"lb": float("inf"), "n": np.int64(3), "xs": (1, 2)}, sort_keys=True)
    '{"lb": null, "n": 3, "xs": [1, 2]}'
    """
    return json.dumps(plain(value), allow_nan=False, **options)


def _plain(
    v: Any,
    digits: int | None,
    significant: int | None,
    integral: bool,
    strict: bool,
    max_depth: int | None,
    depth: int,
) -> Any:
    if strict and max_depth is not None and depth > max_depth:
        raise TypeError(f"nested deeper than {max_depth}")
    if v is None or isinstance(v, (bool, str)):
        return v
    if isinstance(v, np.bool_):
        return bool(v)
    if isinstance(v, (int, np.integer)):
        return int(v)
    if isinstance(v, (float, np.floating)):
        f = float(v)
        if not math.isfinite(f):
            return None
        if digits is not None:
            f = round(f, digits)
        if significant is not None:
            f = float(f"{f:.{significant}g}")
        if integral and f == int(f) and abs(f) < 1e15:
            return int(f)
        return f
    if isinstance(v, Enum):
        return _plain(v.value, digits, significant, integral, strict, max_depth, depth)
    if isinstance(v, np.ndarray):
        return _plain(v.tolist(), digits, significant, integral, strict, max_depth, depth)
    if isinstance(v, (list, tuple)):
        return [_plain(x, digits, significant, integral, strict, max_depth, depth + 1) for x in v]
    if isinstance(v, Mapping):
        return {
            str(k): _plain(x, digits, significant, integral, strict, max_depth, depth + 1)
            for k, x in v.items()
        }
    if strict:
        raise TypeError(f"no file value for {type(v).__name__}")
    return v
