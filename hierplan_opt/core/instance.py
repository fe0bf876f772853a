"""Problem instances: MAPF (one goal per agent) and TAPF (teams with target sets).

Anonymous MAPF is TAPF with a single team. Agents carry optional kinematics used by
scheduling (MAPF-POST); highways are an optional set of directed edges.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from typing import Any, cast

from hierplan_opt.core.errors import InputError
from hierplan_opt.core.graph import Graph, Location

DRIVES = ("omni", "differential")
LocationLike = Location | Sequence[int]


@dataclass(frozen=True)
class Kinematics:
    """Motion limits of one robot type.

    ``drive`` is ``"omni"`` (moves in any direction without turning) or
    ``"differential"`` (turns in place at ``omega_max`` rad/s before moving).
    ``v_max`` is in graph length units per second; ``a_max`` (optional) enables the
    acceleration-aware lower bound; ``radius`` is the robot's footprint radius.

    Example
    -------
    >>> Kinematics("pioneer", drive="differential", v_max=0.5, omega_max=1.0).v_max
    0.5
    >>> Kinematics(v_max=-1)  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    hierplan_opt.core.errors.InputError: kinematics of 'default': v_max must be ... got -1
    """

    robot_type: str = "default"
    drive: str = "omni"
    v_max: float = 1.0
    omega_max: float | None = None
    a_max: float | None = None
    radius: float = 0.0

    def __post_init__(self) -> None:
        who = f"kinematics of {self.robot_type!r}"
        if self.drive not in DRIVES:
            raise InputError(f"{who}: drive must be one of {list(DRIVES)}, got {self.drive!r}")
        _positive(who, "v_max", self.v_max)
        if self.omega_max is not None:
            _positive(who, "omega_max", self.omega_max)
        elif self.drive == "differential":
            raise InputError(f"{who}: a differential-drive robot needs omega_max")
        if self.a_max is not None:
            _positive(who, "a_max", self.a_max)
        if (
            isinstance(self.radius, bool)
            or not isinstance(cast(object, self.radius), (int, float))
            or not math.isfinite(self.radius)
            or self.radius < 0
        ):
            raise InputError(f"{who}: radius must be a finite number >= 0, got {self.radius!r}")


def _positive(who: str, name: str, value: object) -> None:
    if (
        isinstance(value, bool)
        or not isinstance(value, (int, float))
        or not math.isfinite(value)
        or value <= 0
    ):
        raise InputError(f"{who}: {name} must be a positive finite number, got {value!r}")


DEFAULT_KINEMATICS = Kinematics()


@dataclass(frozen=True)
class Agent:
    """One robot: a name, a start vertex, and (for MAPF) a goal vertex.

    In TAPF instances ``goal`` is None and ``team`` is the index of its team.
    """

    name: str
    start: int
    goal: int | None = None
    team: int | None = None
    kinematics: Kinematics = DEFAULT_KINEMATICS


@dataclass(frozen=True)
class Team:
    """A team of exchangeable robots (indices into ``Instance.agents``) and its targets."""

    name: str
    agents: tuple[int, ...]
    targets: tuple[int, ...]


@dataclass(frozen=True)
class Instance:
    """A MAPF or TAPF instance on a :class:`Graph`.

    Construction checks what makes an instance ill-formed (starts or targets off the
    graph, two robots on one start, team sizes that differ from their target counts).
    Two agents with one goal is *allowed* here, so that solvers can report it as
    INFEASIBLE; the file readers refuse it as bad input.

    Example
    -------
    >>> g = Graph.grid(5, 2, obstacles=[(0, 1), (1, 1), (3, 1), (4, 1)])
    >>> inst = Instance.mapf(g, [(0, 0), (1, 0)], [(4, 0), (3, 0)])
    >>> inst.num_agents, inst.soc_lower_bound(), inst.makespan_lower_bound()
    (2, 6, 4)
    """

    graph: Graph
    agents: tuple[Agent, ...]
    teams: tuple[Team, ...] = ()
    highways: frozenset[tuple[int, int]] | None = None
    name: str = "instance"
    meta: dict[str, Any] = field(default_factory=dict[str, Any], compare=False, hash=False)

    def __post_init__(self) -> None:
        g = self.graph
        if not self.agents:
            raise InputError("the instance has no agents")
        names: set[str] = set()
        starts: dict[int, str] = {}
        for a in self.agents:
            if a.name in names:
                raise InputError(f"agent name {a.name!r} is used twice")
            names.add(a.name)
            self._check_vertex(a.start, f"start of agent {a.name!r}")
            if a.start in starts:
                raise InputError(
                    f"agents {starts[a.start]!r} and {a.name!r} share the start {_loc(g, a.start)}"
                )
            starts[a.start] = a.name
        if self.teams:
            seen_targets: dict[int, str] = {}
            members: list[int] = []
            for ti, team in enumerate(self.teams):
                if len(team.agents) != len(team.targets):
                    raise InputError(
                        f"team {team.name!r} has {len(team.agents)} robots but "
                        f"{len(team.targets)} targets"
                    )
                if not team.agents:
                    raise InputError(f"team {team.name!r} has no robots")
                for t in team.targets:
                    self._check_vertex(t, f"target of team {team.name!r}")
                    if t in seen_targets:
                        raise InputError(
                            f"target {_loc(g, t)} is given to both team "
                            f"{seen_targets[t]!r} and team {team.name!r}"
                        )
                    seen_targets[t] = team.name
                for i in team.agents:
                    if not 0 <= i < len(self.agents) or self.agents[i].team != ti:
                        raise InputError(f"team {team.name!r} lists agent index {i} wrongly")
                members += list(team.agents)
            if sorted(members) != list(range(len(self.agents))):
                raise InputError("every agent must belong to exactly one team")
        else:
            for a in self.agents:
                if a.goal is None:
                    raise InputError(f"agent {a.name!r} has no goal")
                self._check_vertex(a.goal, f"goal of agent {a.name!r}")
        if self.highways is not None:
            for u, v in self.highways:
                if not g.has_edge(u, v):
                    raise InputError(
                        f"highway {_loc(g, u)} -> {_loc(g, v)} is not an edge of the graph"
                    )

    def _check_vertex(self, v: int, what: str) -> None:
        g = self.graph
        if not isinstance(cast(object, v), int) or not 0 <= v < g.n:
            raise InputError(f"{what} is outside the map")
        if not g.passable[v]:
            raise InputError(f"{what} {_loc(g, v)} is on an obstacle")

    # ------------------------------------------------------------------ builders
    @classmethod
    def mapf(
        cls,
        graph: Graph,
        starts: Sequence[Location | Sequence[int]],
        goals: Sequence[Location | Sequence[int]],
        *,
        names: Sequence[str] | None = None,
        kinematics: Sequence[Kinematics] | Kinematics | None = None,
        highways: Iterable[tuple[Location, Location]] | None = None,
        name: str = "instance",
    ) -> Instance:
        """A MAPF instance from start and goal *locations* (coordinates or names).

        Agents are named ``agent0..agentK-1`` unless ``names`` is given.
        """
        if len(starts) != len(goals):
            raise InputError(f"{len(starts)} starts but {len(goals)} goals")
        names = list(names) if names is not None else [f"agent{i}" for i in range(len(starts))]
        kins = _kinematics_list(kinematics, len(starts))
        agents = tuple(
            Agent(names[i], graph.vertex(s), graph.vertex(t), None, kins[i])
            for i, (s, t) in enumerate(zip(starts, goals, strict=True))
        )
        return cls(graph, agents, (), _highways(graph, highways), name)

    @classmethod
    def tapf(
        cls,
        graph: Graph,
        teams: Sequence[tuple[Sequence[LocationLike], Sequence[LocationLike]]],
        *,
        team_names: Sequence[str] | None = None,
        kinematics: Sequence[Kinematics] | Kinematics | None = None,
        highways: Iterable[tuple[Location, Location]] | None = None,
        name: str = "instance",
    ) -> Instance:
        """A TAPF instance from ``[(starts, targets), ...]`` per team.

        Agents are named ``agent0..`` in team order. ``kinematics`` is one per team
        (or one for all).

        Example
        -------
        >>> g = Graph.grid(3, 3)
        >>> inst = Instance.tapf(g, [([(0, 0), (2, 2)], [(0, 2), (2, 0)])])
        >>> inst.is_tapf, inst.teams[0].agents
        (True, (0, 1))
        """
        team_names = list(team_names) if team_names else [f"team{i}" for i in range(len(teams))]
        kins = _kinematics_list(kinematics, len(teams))
        agents: list[Agent] = []
        team_objs: list[Team] = []
        for ti, (starts, targets) in enumerate(teams):
            idx: list[int] = []
            for s in starts:
                idx.append(len(agents))
                agents.append(Agent(f"agent{len(agents)}", graph.vertex(s), None, ti, kins[ti]))
            team_objs.append(
                Team(team_names[ti], tuple(idx), tuple(graph.vertex(t) for t in targets))
            )
        return cls(graph, tuple(agents), tuple(team_objs), _highways(graph, highways), name)

    # ------------------------------------------------------------------ queries
    @property
    def num_agents(self) -> int:
        return len(self.agents)

    @property
    def is_tapf(self) -> bool:
        """True when targets are given to teams rather than to agents."""
        return bool(self.teams)

    @property
    def starts(self) -> list[int]:
        return [a.start for a in self.agents]

    @property
    def goals(self) -> list[int]:
        """Goal of every agent (MAPF only)."""
        if self.is_tapf:
            raise InputError("a TAPF instance has no fixed goals; use goal_sets()")
        return [a.goal for a in self.agents]  # type: ignore[misc]

    def goal_set(self, agent: int) -> tuple[int, ...]:
        """The vertices agent ``agent`` may end at: its goal, or its team's targets."""
        a = self.agents[agent]
        if a.team is not None:
            return self.teams[a.team].targets
        assert a.goal is not None
        return (a.goal,)

    def with_goals(self, goals: Sequence[int]) -> Instance:
        """The MAPF instance that fixes each agent's goal (e.g. after assignment)."""
        agents = tuple(
            Agent(a.name, a.start, int(g), None, a.kinematics)
            for a, g in zip(self.agents, goals, strict=True)
        )
        return Instance(self.graph, agents, (), self.highways, self.name, dict(self.meta))

    def subset(self, k: int) -> Instance:
        """The MAPF instance with the first ``k`` agents."""
        if self.is_tapf:
            raise InputError("subset() applies to MAPF instances")
        if not 1 <= k <= self.num_agents:
            raise InputError(f"k must be in 1..{self.num_agents}, got {k}")
        return Instance(self.graph, self.agents[:k], (), self.highways, self.name, dict(self.meta))

    def soc_lower_bound(self) -> int:
        """Sum over agents of the distance to the nearest admissible goal."""
        return sum(self.min_distance(i) for i in range(self.num_agents))

    def makespan_lower_bound(self) -> int:
        """Max over agents (and, for teams, over targets) of the nearest distance."""
        lb = max(self.min_distance(i) for i in range(self.num_agents))
        for team in self.teams:
            for t in team.targets:
                d = self.graph.dist_to(t)
                lb = max(lb, min(int(d[self.agents[i].start]) for i in team.agents))
        return lb

    def min_distance(self, i: int) -> int:
        """Timestep distance from agent ``i``'s start to its nearest admissible goal."""
        s = self.agents[i].start
        return min(int(self.graph.dist_to(t)[s]) for t in self.goal_set(i))

    def __repr__(self) -> str:
        kind = f"TAPF, {len(self.teams)} teams" if self.is_tapf else "MAPF"
        return f"Instance({self.name!r}, {kind}, {self.num_agents} agents, {self.graph!r})"


def _loc(g: Graph, v: int) -> str:
    return g.label(v)


def _kinematics_list(
    kinematics: Sequence[Kinematics] | Kinematics | None, k: int
) -> list[Kinematics]:
    if kinematics is None:
        return [DEFAULT_KINEMATICS] * k
    if isinstance(kinematics, Kinematics):
        return [kinematics] * k
    kins = list(kinematics)
    if len(kins) != k:
        raise InputError(f"expected {k} kinematics entries, got {len(kins)}")
    return kins


def _highways(
    graph: Graph, highways: Iterable[tuple[Location, Location]] | None
) -> frozenset[tuple[int, int]] | None:
    if highways is None:
        return None
    return frozenset((graph.vertex(u), graph.vertex(v)) for u, v in highways)
