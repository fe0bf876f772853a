"""Small geometric primitives shared by the schedule modules (metres, any dimension)."""

from __future__ import annotations

import numpy as np


def segment_distance(p1: np.ndarray, q1: np.ndarray, p2: np.ndarray, q2: np.ndarray) -> np.ndarray:
    """Distances between segments ``p1q1`` and ``p2q2`` (row-wise arrays, any dim).

    Example
    -------
    >>> a = np.array([[0.0, 0.0]]); b = np.array([[1.0, 0.0]])
    >>> segment_distance(a, b, np.array([[0.5, 2.0]]), np.array([[3.0, 2.0]])).tolist()
    [2.0]
    >>> segment_distance(a, b, np.array([[0.5, -1.0]]), np.array([[0.5, 1.0]])).tolist()
    [0.0]
    """
    return segment_closest(p1, q1, p2, q2)[0]


def segment_closest(
    p1: np.ndarray, q1: np.ndarray, p2: np.ndarray, q2: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Distances between segments ``p1q1`` and ``p2q2`` (row-wise, any dim) and the
    fractions ``s``, ``t`` in [0, 1] of a closest pair of points ``p1 + s (q1 - p1)``,
    ``p2 + t (q2 - p2)``.

    Example
    -------
    >>> a = np.array([[0.0, 0.0]]); b = np.array([[2.0, 2.0]])
    >>> d, s, t = segment_closest(a, b, np.array([[0.0, 2.0]]), np.array([[2.0, 0.0]]))
    >>> d.tolist(), s.tolist(), t.tolist()
    ([0.0], [0.5], [0.5])
    """
    d1 = q1 - p1
    d2 = q2 - p2
    r = p1 - p2
    a = np.einsum("ij,ij->i", d1, d1)
    e = np.einsum("ij,ij->i", d2, d2)
    f = np.einsum("ij,ij->i", d2, r)
    c = np.einsum("ij,ij->i", d1, r)
    b = np.einsum("ij,ij->i", d1, d2)
    denom = a * e - b * b
    safe_a = np.where(a > 0, a, 1.0)
    safe_e = np.where(e > 0, e, 1.0)
    with np.errstate(divide="ignore", invalid="ignore"):
        s = np.where(
            denom > 1e-12, np.clip((b * f - c * e) / np.where(denom > 0, denom, 1), 0, 1), 0
        )
    t = np.where(e > 0, (b * s + f) / safe_e, 0.0)
    low = t < 0
    high = t > 1
    t = np.clip(t, 0, 1)
    s = np.where(low, np.clip(-c / safe_a, 0, 1), s)
    s = np.where(high, np.clip((b - c) / safe_a, 0, 1), s)
    s = np.where(a > 0, s, 0.0)
    t = np.where((a <= 0) & (e > 0), np.clip(f / safe_e, 0, 1), t)
    diff = p1 + d1 * s[:, None] - p2 - d2 * t[:, None]
    return np.sqrt(np.einsum("ij,ij->i", diff, diff)), s, t
