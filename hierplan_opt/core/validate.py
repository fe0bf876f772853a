"""The one independent plan validator. No solver owns it; the CLI and every test use it.

It checks a :class:`Plan` against an :class:`Instance` from scratch: starts, goals
(for teams: every target reached by exactly one robot of its team), moves along edges
only, no blocked cells, no vertex conflicts (parked robots included) and no swap
conflicts.
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass

from hierplan_opt.core.instance import Instance
from hierplan_opt.core.plan import Plan

#: Every kind of violation, in the order they are reported.
KINDS = (
    "agent_count",
    "empty_path",
    "off_map",
    "wrong_start",
    "wrong_goal",
    "target_missed",
    "target_shared",
    "blocked",
    "non_edge",
    "vertex_conflict",
    "swap_conflict",
)


@dataclass(frozen=True)
class Violation:
    """One way a plan is wrong.

    ``agents`` are agent indices, ``vertex`` a vertex id (or None), ``time`` a
    timestep (or None); ``message`` says it in words with the instance's coordinates.
    """

    kind: str
    agents: tuple[int, ...]
    vertex: int | None
    time: int | None
    message: str

    def __str__(self) -> str:
        return f"{self.kind}: {self.message}"


def validate(instance: Instance, plan: Plan) -> list[Violation]:
    """All violations of ``plan`` on ``instance``; an empty list means the plan is valid.

    The checks run in the order of :data:`KINDS`; a plan whose shape is wrong (agent
    count, empty paths, vertices off the map) is not checked further.

    Example
    -------
    >>> from hierplan_opt.core.graph import Graph
    >>> g = Graph.grid(3, 1)
    >>> inst = Instance.mapf(g, [(0, 0), (2, 0)], [(2, 0), (0, 0)])
    >>> [v.kind for v in validate(inst, Plan.from_paths([[0, 1, 2], [2, 1, 0]]))]
    ['vertex_conflict']
    """
    check = _Checker(instance, plan)
    for shape in (check.agent_count, check.empty_paths, check.off_map):
        out = shape()
        if out:
            return out
    return [
        *check.starts_and_goals(),
        *check.team_targets(),
        *check.moves(),
        *check.conflicts(),
    ]


class _Checker:
    """The checks of :func:`validate`, one method per step, sharing names and locations."""

    def __init__(self, instance: Instance, plan: Plan) -> None:
        self.instance = instance
        self.plan = plan
        self.graph = instance.graph
        self.names = [a.name for a in instance.agents]

    def loc(self, v: int) -> str:
        return self.graph.label(v)

    # ------------------------------------------------------------------ shape
    def agent_count(self) -> list[Violation]:
        plan, instance = self.plan, self.instance
        if plan.num_agents == instance.num_agents:
            return []
        msg = f"plan has {plan.num_agents} paths for {instance.num_agents} agents"
        return [Violation("agent_count", (), None, None, msg)]

    def empty_paths(self) -> list[Violation]:
        return [
            Violation("empty_path", (i,), None, None, f"{self.names[i]} has an empty path")
            for i, p in enumerate(self.plan.paths)
            if not p
        ]

    def off_map(self) -> list[Violation]:
        out: list[Violation] = []
        n = self.graph.n
        for i, p in enumerate(self.plan.paths):
            t = next((t for t, v in enumerate(p) if not 0 <= v < n), None)
            if t is not None:
                msg = f"{self.names[i]} is off the map at t={t}"
                out.append(Violation("off_map", (i,), p[t], t, msg))
        return out

    # ------------------------------------------------------------------ ends
    def starts_and_goals(self) -> list[Violation]:
        out: list[Violation] = []
        names, loc = self.names, self.loc
        for i, (a, p) in enumerate(zip(self.instance.agents, self.plan.paths, strict=True)):
            if p[0] != a.start:
                msg = f"{names[i]} starts at {loc(p[0])}, not at its start {loc(a.start)}"
                out.append(Violation("wrong_start", (i,), p[0], 0, msg))
            if a.goal is not None and p[-1] != a.goal:
                msg = f"{names[i]} ends at {loc(p[-1])}, not at its goal {loc(a.goal)}"
                out.append(Violation("wrong_goal", (i,), p[-1], len(p) - 1, msg))
        return out

    def team_targets(self) -> list[Violation]:
        """Every robot of a team ends on one of its targets, each target taken once."""
        out: list[Violation] = []
        names, loc, paths = self.names, self.loc, self.plan.paths
        for team in self.instance.teams:
            ends = Counter(paths[i][-1] for i in team.agents)
            targets = set(team.targets)
            for i in team.agents:
                e = paths[i][-1]
                if e not in targets:
                    msg = (
                        f"{names[i]} ends at {loc(e)}, which is not a target of team {team.name!r}"
                    )
                    out.append(Violation("wrong_goal", (i,), e, len(paths[i]) - 1, msg))
            for t in team.targets:
                if ends[t] == 0:
                    msg = f"target {loc(t)} of team {team.name!r} is reached by no robot"
                    out.append(Violation("target_missed", (), t, None, msg))
                elif ends[t] > 1:
                    who = tuple(i for i in team.agents if paths[i][-1] == t)
                    msg = (
                        f"target {loc(t)} of team {team.name!r} is taken by "
                        f"{', '.join(names[i] for i in who)}"
                    )
                    out.append(Violation("target_shared", who, t, None, msg))
        return out

    # ------------------------------------------------------------------ moves
    def moves(self) -> list[Violation]:
        """No robot on a blocked cell; every step a wait or an edge."""
        out: list[Violation] = []
        g, names, loc = self.graph, self.names, self.loc
        for i, p in enumerate(self.plan.paths):
            for t, v in enumerate(p):
                if not g.passable[v]:
                    msg = f"{names[i]} is on blocked {loc(v)} at t={t}"
                    out.append(Violation("blocked", (i,), v, t, msg))
            for t in range(len(p) - 1):
                u, v = p[t], p[t + 1]
                if u != v and not g.has_edge(u, v):
                    msg = f"{names[i]} jumps {loc(u)} -> {loc(v)} at t={t}, which is not an edge"
                    out.append(Violation("non_edge", (i,), u, t, msg))
        return out

    # ------------------------------------------------------------------ conflicts
    def conflicts(self) -> list[Violation]:
        """Vertex and swap conflicts up to the last timestep any path lists (everyone is
        parked after it)."""
        out: list[Violation] = []
        names, loc = self.names, self.loc
        paths = self.plan.paths
        horizon = self.plan.horizon
        for t in range(horizon + 1):
            occupied: dict[int, int] = {}
            for i, p in enumerate(paths):
                v = p[t] if t < len(p) else p[-1]
                j = occupied.setdefault(v, i)
                if j != i:
                    msg = f"{names[j]} and {names[i]} are both at {loc(v)} at t={t}"
                    out.append(Violation("vertex_conflict", (j, i), v, t, msg))
            if t == horizon:
                break
            moves: dict[tuple[int, int], int] = {}
            for i, p in enumerate(paths):
                if t + 1 >= len(p) or p[t] == p[t + 1]:
                    continue
                u, v = p[t], p[t + 1]
                j = moves.get((v, u))
                if j is not None:
                    msg = (
                        f"{names[j]} and {names[i]} swap {loc(v)} <-> {loc(u)} "
                        f"between t={t} and t={t + 1}"
                    )
                    out.append(Violation("swap_conflict", (j, i), u, t, msg))
                moves[(u, v)] = i
        return out


def is_valid(instance: Instance, plan: Plan) -> bool:
    """Shorthand for ``not validate(instance, plan)``."""
    return not validate(instance, plan)
