"""Conflicts between agents' paths: the one :class:`Conflict` type of every search solver.

Paths are tuples of vertex ids indexed by timestep; after its last step an agent stays
parked at its last vertex forever. Two paths conflict when the agents are at one vertex
at one time (a *vertex* conflict; a *target* conflict when one of them is already parked
there for good) or swap over an edge between two timesteps (an *edge* conflict).
:meth:`~hierplan_opt.search.reservations.Reservations.conflicts_of` finds the conflicts
of one path incrementally; :func:`find_conflicts` scans a whole set of paths.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import NamedTuple

#: Conflict kinds (see :class:`Conflict`).
VERTEX, EDGE, TARGET = 0, 1, 2
KIND_NAMES = ("vertex", "edge", "target")


class Conflict(NamedTuple):
    """One conflict between agents ``a`` and ``b`` at timestep ``t``.

    =========  ===========================================================
    ``kind``   meaning
    =========  ===========================================================
    VERTEX     ``a`` and ``b`` are both at ``v`` at ``t`` (``u == -1``)
    EDGE       ``a`` moves ``u -> v`` and ``b`` moves ``v -> u``, arriving at ``t``
    TARGET     ``a`` is parked at its goal ``v`` (arrived before ``t``) and ``b`` is
               at ``v`` at ``t`` (``u == -1``)
    =========  ===========================================================

    Example
    -------
    >>> c = Conflict(3, VERTEX, 0, 1, -1, 7)
    >>> c.t, KIND_NAMES[c.kind], (c.a, c.b), c.v
    (3, 'vertex', (0, 1), 7)
    """

    t: int
    kind: int
    a: int
    b: int
    u: int
    v: int


def find_conflicts(paths: Sequence[tuple[int, ...]], n: int) -> list[Conflict]:
    """Every vertex, swap and target conflict between the paths (parked agents included).

    ``n`` is the number of vertex ids. Each conflicting pair is reported once per
    conflict, the agent with the smaller index first for vertex and edge conflicts.

    Example
    -------
    >>> find_conflicts([(0, 1, 2), (2, 1, 0)], n=3)
    [Conflict(t=1, kind=0, a=0, b=1, u=-1, v=1)]
    >>> find_conflicts([(1,), (0, 1, 2)], n=3)
    [Conflict(t=1, kind=2, a=0, b=1, u=-1, v=1)]
    """
    # Every conflicting pair is reported (CBS children keep their parent's conflicts
    # among agents they did not replan, so a pair missing here would never be seen again).
    # One pass that fills the occupancy as it goes (cheaper than a full Reservations
    # table: find_conflicts runs at every root, also the small ones of WDG).
    occ: dict[int, list[int]] = {}
    goal_at: dict[int, tuple[int, int]] = {}
    for a, p in enumerate(paths):
        goal_at[p[-1]] = (a, len(p) - 1)
    out: list[Conflict] = []
    for a, p in enumerate(paths):
        prev = p[0]
        for t, v in enumerate(p):
            key = t * n + v
            lst = occ.get(key)
            if lst is None:
                occ[key] = [a]
            else:
                for b in lst:
                    out.append(Conflict(t, VERTEX, b, a, -1, v))
                lst.append(a)
            ga = goal_at.get(v)
            if ga is not None and ga[0] != a and t > ga[1]:
                out.append(Conflict(t, TARGET, ga[0], a, -1, v))
            if t and prev != v:
                # a swap with an agent b that was at v at t-1 and is at prev at t
                l1 = occ.get((t - 1) * n + v)
                l2 = occ.get(t * n + prev)
                if l1 is not None and l2 is not None:
                    for b in l1:
                        if b != a and b in l2:
                            out.append(Conflict(t, EDGE, b, a, v, prev))
            prev = v
    return out
