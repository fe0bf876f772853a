"""Discrete plans: one vertex per timestep per agent."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

#: Plans of at most this many path entries print in full.
_FULL_REPR = 40


@dataclass(frozen=True)
class Plan:
    """One path per agent (vertex ids, index = timestep).

    An agent stays at the last vertex of its path forever after. Costs follow the
    standard conventions: an agent's cost is the time it last arrives at its final
    vertex (trailing waits do not count); sum of costs adds them, makespan is the max.

    Example
    -------
    >>> p = Plan.from_paths([[0, 1, 2, 2], [5, 5, 4]])
    >>> p.costs, p.sum_of_costs, p.makespan, p.position(1, 10)
    ((2, 2), 4, 2, 4)
    """

    paths: tuple[tuple[int, ...], ...]

    def __repr__(self) -> str:
        """The paths in full for small plans; agents and horizon for the others.

        Example
        -------
        >>> Plan.from_paths([[0, 1], [5]])
        Plan(paths=((0, 1), (5,)))
        >>> Plan.from_paths([[0] * 30] * 1000)
        Plan(<1000 paths>, horizon=29)
        """
        if sum(map(len, self.paths)) <= _FULL_REPR:
            return f"Plan(paths={self.paths!r})"
        return f"Plan(<{self.num_agents} paths>, horizon={self.horizon})"

    @classmethod
    def from_paths(cls, paths: Sequence[Sequence[int]]) -> Plan:
        """A plan from any nested sequence of vertex ids."""
        return cls(tuple(tuple(int(v) for v in p) for p in paths))

    @property
    def num_agents(self) -> int:
        return len(self.paths)

    @property
    def horizon(self) -> int:
        """Last timestep any path lists explicitly."""
        return max((len(p) - 1 for p in self.paths), default=0)

    def position(self, agent: int, t: int) -> int:
        """Vertex of ``agent`` at timestep ``t`` (its last vertex once the path ends)."""
        p = self.paths[agent]
        return p[t] if t < len(p) else p[-1]

    @property
    def costs(self) -> tuple[int, ...]:
        """Per-agent cost: arrival time at the final vertex, trailing waits removed."""
        return tuple(path_cost(p) for p in self.paths)

    @property
    def sum_of_costs(self) -> int:
        return sum(self.costs)

    @property
    def makespan(self) -> int:
        return max(self.costs, default=0)

    def cost(self, objective: str) -> int:
        """``sum_of_costs`` for ``"soc"``, ``makespan`` for ``"makespan"``."""
        if objective == "soc":
            return self.sum_of_costs
        if objective == "makespan":
            return self.makespan
        raise ValueError(f"unknown objective {objective!r} (use 'soc' or 'makespan')")

    def trimmed(self) -> Plan:
        """The same plan with trailing waits removed (each path ends on arrival)."""
        return Plan(tuple(p[: path_cost(p) + 1] for p in self.paths))

    @property
    def ends(self) -> tuple[int, ...]:
        """Final vertex of every agent (for TAPF: the target it was assigned)."""
        return tuple(p[-1] for p in self.paths)


def path_cost(path: Sequence[int]) -> int:
    """Arrival time at the final vertex of ``path``, trailing waits removed."""
    k = len(path) - 1
    while k > 0 and path[k - 1] == path[-1]:
        k -= 1
    return max(k, 0)
