"""The reservation table: where a set of agents' paths are, indexed for the searches.

One :class:`Reservations` serves every search solver: the low levels count (or avoid)
conflicts with it while they expand states, and the high levels find the conflicts of
a new path with :meth:`Reservations.conflicts_of` instead of re-scanning every path.

Keys follow the constraints' layout (:mod:`hierplan_opt.search.constraints`): a vertex
at a time is ``t * N + v`` and a move ``u -> v`` arriving at ``t`` is ``(t * N + u) * N
+ v``, with ``N`` the number of vertex ids.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Protocol

from hierplan_opt.search.conflicts import EDGE, TARGET, VERTEX, Conflict

#: ``park_t`` of a vertex where nobody parks: later than any timestep.
NEVER = 1 << 60

Path = tuple[int, ...]


class Mirror(Protocol):
    """A dense copy of the table kept in step with it (the compiled low level's
    :class:`~hierplan_opt.search.jit.CatMirror`; declared here so that this module
    does not import the one that reads it)."""

    def update(self, path: Sequence[int], delta: int, park: int) -> None: ...

    def detach(self) -> None: ...


class DenseCopy(Protocol):
    """A copy that holds the reservations itself
    (:class:`~hierplan_opt.search.jit.DenseMirror`)."""

    def add(self, agent: int, path: Sequence[int], stamp: int) -> None: ...

    def remove(self, agent: int, path: Sequence[int]) -> None: ...

    def conflicts_of(
        self, r: int, path: Sequence[int], skip: frozenset[int] | set[int]
    ) -> list[Conflict]: ...

    def parked(self) -> tuple[dict[int, tuple[int, int]], list[int]]: ...


class Reservations:
    """The paths of some agents, indexed by vertex-time, by move and by parked goal.

    Attributes
    ----------
    vt : dict[int, list[int]]
        ``t * N + v`` -> the agents at ``v`` at ``t`` (up to the last step of their paths).
    et : dict[int, list[int]]
        ``(t * N + u) * N + v`` -> the agents moving ``u -> v`` and arriving at ``t``.
    parked : dict[int, tuple[int, int]]
        ``v -> (agent, T)``: ``agent``'s path ends at ``v`` at ``T``; it stays there.
    park_t : list[int]
        ``park_t[v]`` is that ``T`` (:data:`NEVER` where nobody parks), for fast lookups.
    paths : list[Path | None]
        The reserved path of every agent (None when absent).
    horizon : int
        At least the last timestep of every reserved path.

    Example
    -------
    >>> r = Reservations(10)
    >>> r.add(0, (1, 2, 3))
    >>> r.vt[1 * 10 + 2], r.et[(1 * 10 + 1) * 10 + 2], r.parked[3]
    ([0], [0], (0, 2))
    >>> r.remove(0)
    >>> r.vt, r.et, r.parked
    ({}, {}, {})
    """

    __slots__ = (
        "n",
        "moves",
        "vt",
        "et",
        "parked",
        "park_t",
        "paths",
        "horizon",
        "mirror",
        "stamps",
        "clock",
        "dense_ok",
        "dense",
    )

    def __init__(self, n: int, *, moves: bool = True, dense_ok: bool = False) -> None:
        self.n = n
        #: Whether ``et`` is kept (a table used only for conflicts_of can do without).
        self.moves = moves
        self.vt: dict[int, list[int]] = {}
        self.et: dict[int, list[int]] = {}
        self.parked: dict[int, tuple[int, int]] = {}
        self.park_t: list[int] = [NEVER] * n
        self.paths: list[Path | None] = []
        self.horizon = 0
        #: The compiled low level's dense copy (:class:`~hierplan_opt.search.jit.CatMirror`),
        #: attached by its first call and kept in step here; None otherwise.
        self.mirror: Mirror | None = None
        #: ``stamps[a]``: when ``a``'s path was added (a clock of adds). The agents listed
        #: at a key of ``vt`` / ``et`` are those of their reservations, in stamp order.
        self.stamps: list[int] = []
        self.clock = 0
        #: Whether the compiled low level may take the table over (``dense``): CBS's own
        #: table, which only CBS's calls read.
        self.dense_ok = dense_ok
        #: The compiled low level's own copy (:class:`~hierplan_opt.search.jit.DenseMirror`)
        #: once it has taken the table over: then it alone holds the reservations (the
        #: dicts above stay empty; about ten times cheaper to patch) and answers
        #: :meth:`conflicts_of`; :meth:`undense` hands them back.
        self.dense: DenseCopy | None = None

    # ------------------------------------------------------------------ updates
    def add(self, agent: int, path: Path) -> None:
        """Reserve ``path`` for ``agent`` (which must hold no reservation)."""
        last = len(path) - 1
        if last > self.horizon:
            self.horizon = last
        paths = self.paths
        if agent >= len(paths):
            grow = agent + 1 - len(paths)
            paths.extend([None] * grow)
            self.stamps.extend([0] * grow)
        paths[agent] = path
        self.clock += 1
        self.stamps[agent] = self.clock
        if self.dense is not None:
            self.dense.add(agent, path, self.clock)
            return
        vkeys, ekeys = self._keys(path)
        _put(self.vt, vkeys, agent)
        _put(self.et, ekeys, agent)
        self.parked[path[-1]] = (agent, last)
        self.park_t[path[-1]] = last
        if self.mirror is not None:
            self.mirror.update(path, 1, last)

    def _keys(self, path: Path) -> tuple[list[int], list[int]]:
        """The vertex-time keys and (if kept) the move keys of ``path``."""
        n = self.n
        vkeys = [t * n + v for t, v in enumerate(path)]
        if not self.moves:
            return vkeys, []
        pairs = enumerate(zip(path, path[1:], strict=False), 1)
        return vkeys, [(t * n + u) * n + v for t, (u, v) in pairs if u != v]

    def remove(self, agent: int) -> None:
        """Undo :meth:`add` of ``agent``'s path (nothing if it holds none)."""
        path = self.paths[agent] if agent < len(self.paths) else None
        if path is None:
            return
        self.paths[agent] = None
        if self.dense is not None:
            self.dense.remove(agent, path)
            return
        vkeys, ekeys = self._keys(path)
        _drop(self.vt, vkeys, agent)
        _drop(self.et, ekeys, agent)
        p = self.parked.get(path[-1])
        if p is not None and p[0] == agent:
            del self.parked[path[-1]]
            self.park_t[path[-1]] = NEVER
        if self.mirror is not None:
            self.mirror.update(path, -1, self.park_t[path[-1]])

    def sync(self, paths: Sequence[Path | None], skip: int = -1) -> None:
        """Make the table hold exactly ``paths`` (agent ``i`` on ``paths[i]``), but for
        agent ``skip`` (if given), which holds no reservation afterwards.

        Only the paths that changed (by identity) are re-reserved, so keeping one table
        for a search costs O(changed paths) per step, not O(all paths). ``skip`` serves a
        low-level call for that agent: its old path is not put back only to be removed.
        ``horizon`` counts ``paths[skip]`` too.
        """
        old = self.paths
        if len(old) != len(paths):
            if self.mirror is not None:
                self.mirror.detach()  # counts the old paths out; the next call re-attaches
            self.undense()  # the kernel's copy back first, so the reset below covers it
            self.vt = {}
            self.et = {}
            for v in self.parked:
                self.park_t[v] = NEVER
            self.parked = {}
            self.paths = [None] * len(paths)
            self.stamps = [0] * len(paths)
            for a, p in enumerate(paths):
                if p is not None and a != skip:
                    self.add(a, p)
        else:
            changed = False
            for a, p in enumerate(paths):
                if a == skip:
                    if old[a] is not None:
                        self.remove(a)
                        changed = True
                elif old[a] is not p:
                    self.remove(a)
                    if p is not None:
                        self.add(a, p)
                    changed = True
            if not changed:
                # Same reservations as after the last update: ``horizon`` (at least the
                # last step of each of them) is still valid.
                return
        self.horizon = max(map(len, filter(None, paths)), default=1) - 1  # paths are not empty

    # ------------------------------------------------------------------ queries
    def visits(self, v: int) -> list[int]:
        """Sorted timesteps at which reserved agents are at ``v`` (one entry per agent).

        Example
        -------
        >>> r = Reservations(7)
        >>> r.add(1, (4, 5, 6, 5))
        >>> r.visits(5)
        [1, 3]
        """
        self.undense()
        n = self.n
        vt = self.vt
        out: list[int] = []
        for t in range(self.horizon + 1):
            lst = vt.get(t * n + v)
            if lst:
                out.extend([t] * len(lst))
        return out

    def conflicts_of(
        self, r: int, path: Path, skip: set[int] | frozenset[int] = frozenset()
    ) -> list[Conflict]:
        """Every conflict of agent ``r`` on ``path`` with the reserved agents not in ``skip``.

        ``r``'s own reservation, if any, is ignored. Vertex and edge conflicts name the
        reserved agent first (``Conflict.a``); a target conflict names the parked agent
        first.

        Example
        -------
        >>> r = Reservations(3)
        >>> r.add(0, (0, 1, 2))
        >>> r.conflicts_of(1, (2, 1, 0))
        [Conflict(t=1, kind=0, a=0, b=1, u=-1, v=1)]
        """
        if self.dense is not None:
            return self.dense.conflicts_of(r, path, skip)
        n = self.n
        vt = self.vt
        et = self.et
        moves = self.moves
        parked = self.parked
        out: list[Conflict] = []
        prev = path[0]
        for t, v in enumerate(path):
            lst = vt.get(t * n + v)
            if lst is not None:
                for b in lst:
                    if b != r and b not in skip:
                        out.append(Conflict(t, VERTEX, b, r, -1, v))
            e = parked.get(v)
            if e is not None and e[0] != r and t > e[1] and e[0] not in skip:
                out.append(Conflict(t, TARGET, e[0], r, -1, v))
            if prev != v:  # a swap with an agent b moving v -> prev
                if moves:
                    lst = et.get((t * n + v) * n + prev)
                else:  # from the vertex table: b at v at t - 1 and at prev at t
                    l1 = vt.get((t - 1) * n + v)
                    l2 = vt.get(t * n + prev)
                    lst = [b for b in l1 if b in l2] if l1 is not None and l2 is not None else None
                if lst is not None:
                    for b in lst:
                        if b != r and b not in skip:
                            out.append(Conflict(t, EDGE, b, r, v, prev))
            prev = v
        g = path[-1]
        for t in range(len(path), self.horizon + 1):
            lst = vt.get(t * n + g)
            if lst is not None:
                for b in lst:
                    if b != r and b not in skip:
                        out.append(Conflict(t, TARGET, r, b, -1, g))
        return out

    def undense(self) -> None:
        """Take the reservations back from :attr:`dense` into the dicts (if it holds them).

        The agents are re-added in stamp order, so every key lists them as before.
        """
        d = self.dense
        if d is None:
            return
        self.dense = None
        self.vt = {}
        self.et = {}
        order = sorted(
            (a for a, p in enumerate(self.paths) if p is not None), key=self.stamps.__getitem__
        )
        for a in order:
            p = self.paths[a]
            assert p is not None
            vkeys, ekeys = self._keys(p)
            _put(self.vt, vkeys, a)
            _put(self.et, ekeys, a)
        self.parked, self.park_t = d.parked()


def _put(table: dict[int, list[int]], keys: list[int], agent: int) -> None:
    for k in keys:
        lst = table.get(k)
        if lst is None:
            table[k] = [agent]
        else:
            lst.append(agent)


def _drop(table: dict[int, list[int]], keys: list[int], agent: int) -> None:
    for k in keys:
        lst = table[k]
        if len(lst) == 1:
            del table[k]
        else:
            lst.remove(agent)
