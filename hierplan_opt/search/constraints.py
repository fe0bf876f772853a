"""Constraints of the constraint tree and their per-agent compiled form.

A constraint-tree (CT) constraint is a small tuple ``(kind, agent, a, b, t)``:

=============  ==============================================================
``NEG_V``      agent not at vertex ``a`` at time ``t``
``NEG_E``      agent does not move ``a -> b`` arriving at time ``t``
``POS_V``      agent at vertex ``a`` at time ``t`` (others: not there)
``POS_E``      agent moves ``a -> b`` arriving at ``t`` (others: not at ``b`` at
               ``t``, not at ``a`` at ``t-1``, no move ``b -> a`` at ``t``)
``LEN_GT``     agent's final arrival at its goal is later than ``t``
``LEN_LE``     agent is at its goal at every time ``>= t`` (others: never at that
               goal from ``t`` on) -- the two children of target reasoning
``NEG_RANGE``  agent not at vertex ``a`` at any time in ``[b, t]`` (corridor)
=============  ==============================================================

The low level never walks the tree: every CT node keeps one immutable
:class:`AgentConstraints` per agent, shared with its parent unless a constraint of the
node touches that agent. Vertex and edge constraints are integer keys
``t * n + v`` and ``(t * n + u) * n + v`` so membership tests are a single set lookup.
"""

from __future__ import annotations

import itertools

NEG_V, NEG_E, POS_V, POS_E, LEN_GT, LEN_LE, NEG_RANGE = range(7)
KIND_NAMES = ("NEG_V", "NEG_E", "POS_V", "POS_E", "LEN_GT", "LEN_LE", "NEG_RANGE")
#: Finish time bound meaning "no bound".
NO_BOUND = 1 << 40

_versions = itertools.count(1)
# The containers of AgentConstraints, as bits of its copy-on-write mask.
_VERTEX, _EDGE, _FORBID, _LANDMARKS = 1, 2, 4, 8
_ALL = _VERTEX | _EDGE | _FORBID | _LANDMARKS

Constraint = tuple[int, int, int, int, int]


class AgentConstraints:
    """Everything the low level must respect for one agent, in lookup-friendly form.

    Instances are treated as immutable: :meth:`add` returns a modified copy. ``ver`` is
    a process-unique id used as a cache key (MDDs, pairwise heuristic values).

    Attributes
    ----------
    vertex : set[int]
        Forbidden ``t * n + v``.
    edge : set[int]
        Forbidden moves ``(t * n + u) * n + v`` (arriving at ``v`` at ``t``).
    forbid_from : dict[int, int]
        ``v -> T``: the agent may not be at ``v`` at any time ``>= T``.
    landmarks : dict[int, int]
        ``t -> v``: the agent must be at ``v`` at time ``t``.
    min_finish : int
        The final arrival at the goal must be at a time ``>= min_finish``.
    max_finish : int
        ... and ``<= max_finish`` (length constraint or makespan bound).
    tmax : int
        Largest time any constraint mentions (after it nothing changes with time).
    infeasible : bool
        Two landmarks contradict each other: no path exists.

    Example
    -------
    >>> c = AgentConstraints.root(n=10, goal=3)
    >>> c2 = c.add((NEG_V, 0, 3, -1, 4), n=10, goal=3)
    >>> c2.min_finish, c.min_finish, (4 * 10 + 3) in c2.vertex
    (5, 0, True)
    """

    __slots__ = (
        "vertex",
        "edge",
        "forbid_from",
        "landmarks",
        "min_finish",
        "max_finish",
        "tmax",
        "infeasible",
        "ver",
        "count",
        "parent",
        "delta",
        "derived",
        "_content",
        "_shared",
    )

    def __init__(self) -> None:
        self.vertex: set[int] = set()
        self.edge: set[int] = set()
        self.forbid_from: dict[int, int] = {}
        self.landmarks: dict[int, int] = {}
        self.min_finish = 0
        self.max_finish = NO_BOUND
        self.tmax = 0
        self.infeasible = False
        self.ver = next(_versions)
        self.count = 0
        # Provenance, so an MDD can be restricted instead of rebuilt: this object is
        # ``parent`` plus own constraints ``delta`` and ``derived`` (constraint, goal of
        # its agent) pairs implied by other agents' positive constraints.
        self.parent: AgentConstraints | None = None
        self.delta: tuple[Constraint, ...] = ()
        self.derived: tuple[tuple[Constraint, int], ...] = ()
        self._content: tuple[object, ...] | None = None
        # Copy on write: the containers a copy still shares with its parent (bits
        # _VERTEX, _EDGE, _FORBID, _LANDMARKS). Most copies are derived constraints of
        # target reasoning, which touch only ``forbid_from``: copying every set of every
        # other agent per CT child was a fifth of CBS's time on empty-32-32 k200.
        self._shared = 0

    @classmethod
    def root(cls, n: int, goal: int, max_finish: int = NO_BOUND) -> AgentConstraints:
        """No constraints except an optional bound on the finish time (makespan)."""
        c = cls()
        c.max_finish = max_finish
        return c

    def copy(self) -> AgentConstraints:
        """A new version with the same constraints (containers shared until written).

        Example
        -------
        >>> a = AgentConstraints.root(10, 3).add((NEG_V, 0, 5, -1, 2), n=10, goal=3)
        >>> b = a.add((NEG_V, 0, 6, -1, 2), n=10, goal=3)
        >>> sorted(a.vertex), sorted(b.vertex)
        ([25], [25, 26])
        """
        c = AgentConstraints.__new__(AgentConstraints)
        c.vertex = self.vertex
        c.edge = self.edge
        c.forbid_from = self.forbid_from
        c.landmarks = self.landmarks
        c._shared = _ALL
        c.min_finish = self.min_finish
        c.max_finish = self.max_finish
        c.tmax = self.tmax
        c.infeasible = self.infeasible
        c.ver = next(_versions)
        c.count = self.count
        c.parent = self
        c.delta = ()
        c.derived = ()
        c._content = None
        return c

    def content(self) -> tuple[object, ...]:
        """A hashable value equal for two objects exactly when they constrain alike.

        Unlike ``ver`` (one per object), two CT nodes that reach the same constraints
        by different branches share it, so a result that depends only on the
        constraints (a WDG pair weight) is computed once. Cached; the object is
        treated as immutable.

        Example
        -------
        >>> a = AgentConstraints.root(10, 3).add((NEG_V, 0, 5, -1, 2), n=10, goal=3)
        >>> b = AgentConstraints.root(10, 3).add((NEG_V, 0, 5, -1, 2), n=10, goal=3)
        >>> a.ver != b.ver, a.content() == b.content()
        (True, True)
        """
        c = self._content
        if c is None:
            c = self._content = (
                frozenset(self.vertex),
                frozenset(self.edge),
                frozenset(self.forbid_from.items()),
                frozenset(self.landmarks.items()),
                self.min_finish,
                self.max_finish,
                self.infeasible,
            )
        return c

    # ------------------------------------------------------------------ building
    def add(self, con: Constraint, *, n: int, goal: int) -> AgentConstraints:
        """A copy with ``con`` applied to its own agent (see :func:`add_derived`)."""
        c = self.copy()
        c._apply_own(con, n, goal)
        c.delta = (con,)
        return c

    def add_many(self, cons: list[Constraint], *, n: int, goal: int) -> AgentConstraints:
        c = self.copy()
        for con in cons:
            c._apply_own(con, n, goal)
        c.delta = tuple(cons)
        return c

    def _own(self, part: int) -> None:
        """Give this object its own copy of the shared container ``part`` (a bit)."""
        self._shared &= ~part
        if part == _VERTEX:
            self.vertex = set(self.vertex)
        elif part == _EDGE:
            self.edge = set(self.edge)
        elif part == _FORBID:
            self.forbid_from = dict(self.forbid_from)
        else:
            self.landmarks = dict(self.landmarks)

    def _neg_vertex(self, v: int, t: int, n: int, goal: int) -> None:
        if self._shared & _VERTEX:
            self._own(_VERTEX)
        self.vertex.add(t * n + v)
        if v == goal and t + 1 > self.min_finish:
            self.min_finish = t + 1
        if t > self.tmax:
            self.tmax = t

    def _landmark(self, v: int, t: int, goal: int) -> None:
        if self._shared & _LANDMARKS:
            self._own(_LANDMARKS)
        old = self.landmarks.get(t)
        if old is not None and old != v:
            self.infeasible = True
        self.landmarks[t] = v
        if v != goal and t + 1 > self.min_finish:
            self.min_finish = t + 1
        if t > self.tmax:
            self.tmax = t

    def _apply_own(self, con: Constraint, n: int, goal: int) -> None:
        kind, _, a, b, t = con
        self.count += 1
        if kind == NEG_V:
            self._neg_vertex(a, t, n, goal)
        elif kind == NEG_E:
            if self._shared & _EDGE:
                self._own(_EDGE)
            self.edge.add((t * n + a) * n + b)
            if t > self.tmax:
                self.tmax = t
        elif kind == POS_V:
            self._landmark(a, t, goal)
        elif kind == POS_E:
            self._landmark(a, t - 1, goal)
            self._landmark(b, t, goal)
        elif kind == LEN_GT:
            if t + 1 > self.min_finish:
                self.min_finish = t + 1
            if t > self.tmax:
                self.tmax = t
        elif kind == LEN_LE:
            if t < self.max_finish:
                self.max_finish = t
            if t > self.tmax:
                self.tmax = t
        elif kind == NEG_RANGE:
            for tt in range(b, t + 1):
                self._neg_vertex(a, tt, n, goal)
        else:  # pragma: no cover - programming error
            raise ValueError(f"unknown constraint kind {kind}")

    def _apply_derived(self, con: Constraint, n: int, other_goal: int, goal: int) -> None:
        """Apply the negative constraints a positive constraint of another agent implies."""
        kind, _, a, b, t = con
        self.count += 1
        if kind == POS_V:
            self._neg_vertex(a, t, n, goal)
        elif kind == POS_E:
            self._neg_vertex(b, t, n, goal)
            self._neg_vertex(a, t - 1, n, goal)
            if self._shared & _EDGE:
                self._own(_EDGE)
            self.edge.add((t * n + b) * n + a)
        elif kind == LEN_LE:
            old = self.forbid_from.get(other_goal)
            if old is None or t < old:
                if self._shared & _FORBID:
                    self._own(_FORBID)
                self.forbid_from[other_goal] = t
            if t > self.tmax:
                self.tmax = t
            if other_goal == goal:
                self.infeasible = True

    # ------------------------------------------------------------------ queries
    def allows_path(self, path: tuple[int, ...] | list[int], n: int) -> bool:
        """Whether ``path`` (then parked at its end forever) satisfies every constraint."""
        if self.infeasible:
            return False
        vc = self.vertex
        ec = self.edge
        ff = self.forbid_from
        last = len(path) - 1
        prev = path[0]
        for t, v in enumerate(path):
            if t * n + v in vc:
                return False
            if ff and v in ff and t >= ff[v]:
                return False
            if t and ((t * n + prev) * n + v) in ec:
                return False
            prev = v
        g = path[-1]
        for t, v in self.landmarks.items():
            if (path[t] if t <= last else g) != v:
                return False
        cost = last
        while cost > 0 and path[cost - 1] == g:
            cost -= 1
        if cost < self.min_finish or cost > self.max_finish:
            return False
        if ff and g in ff:
            return False
        # Parked at the goal after the path ends: later vertex constraints on it.
        return not any(key % n == g and key // n > last for key in vc)


def is_positive(con: Constraint) -> bool:
    """Whether ``con`` also constrains the other agents (positive / length-<= kind)."""
    return con[0] in (POS_V, POS_E, LEN_LE)


def add_derived(
    c: AgentConstraints, cons: list[Constraint], *, n: int, goals: list[int], goal: int
) -> AgentConstraints:
    """A copy of ``c`` (another agent's constraints) with what ``cons`` imply for it."""
    out = c.copy()
    for con in cons:
        out._apply_derived(con, n, goals[con[1]], goal)
    out.derived = tuple([(con, goals[con[1]]) for con in cons])
    return out


def violates_derived(con: Constraint, path: tuple[int, ...], n: int, goals: list[int]) -> bool:
    """Whether another agent's ``path`` breaks what the positive ``con`` implies."""
    kind, agent, a, b, t = con
    if kind == LEN_LE:  # the most frequent (target reasoning): one C scan of the path
        g = goals[agent]
        return path[-1] == g or g in path[t:]
    last = len(path) - 1

    def at(tt: int) -> int:
        return path[tt] if tt <= last else path[-1]

    if kind == POS_V:
        return at(t) == a
    if kind == POS_E:
        return at(t) == b or at(t - 1) == a or (at(t - 1) == b and at(t) == a)
    return False
