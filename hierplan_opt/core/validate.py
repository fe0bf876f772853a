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

    Example
    -------
    >>> from hierplan_opt.core.graph import Graph
    >>> g = Graph.grid(3, 1)
    >>> inst = Instance.mapf(g, [(0, 0), (2, 0)], [(2, 0), (0, 0)])
    >>> [v.kind for v in validate(inst, Plan.from_paths([[0, 1, 2], [2, 1, 0]]))]
    ['vertex_conflict']
    """
    g = instance.graph
    names = [a.name for a in instance.agents]
    out: list[Violation] = []

    def loc(v: int) -> str:
        if not 0 <= v < g.n:
            return f"vertex id {v}"
        x = g.location(v)
        return repr(x) if isinstance(x, str) else str(list(x))

    if plan.num_agents != instance.num_agents:
        out.append(
            Violation(
                "agent_count",
                (),
                None,
                None,
                f"plan has {plan.num_agents} paths for {instance.num_agents} agents",
            )
        )
        return out
    for i, p in enumerate(plan.paths):
        if not p:
            out.append(Violation("empty_path", (i,), None, None, f"{names[i]} has an empty path"))
    if out:
        return out
    off = False
    for i, p in enumerate(plan.paths):
        for t, v in enumerate(p):
            if not 0 <= v < g.n:
                out.append(Violation("off_map", (i,), v, t, f"{names[i]} is off the map at t={t}"))
                off = True
                break
    if off:
        return out

    # Starts and goals.
    for i, (a, p) in enumerate(zip(instance.agents, plan.paths, strict=True)):
        if p[0] != a.start:
            out.append(
                Violation(
                    "wrong_start",
                    (i,),
                    p[0],
                    0,
                    f"{names[i]} starts at {loc(p[0])}, not at its start {loc(a.start)}",
                )
            )
        if a.goal is not None and p[-1] != a.goal:
            out.append(
                Violation(
                    "wrong_goal",
                    (i,),
                    p[-1],
                    len(p) - 1,
                    f"{names[i]} ends at {loc(p[-1])}, not at its goal {loc(a.goal)}",
                )
            )
    for team in instance.teams:
        ends = Counter(plan.paths[i][-1] for i in team.agents)
        targets = set(team.targets)
        for i in team.agents:
            e = plan.paths[i][-1]
            if e not in targets:
                out.append(
                    Violation(
                        "wrong_goal",
                        (i,),
                        e,
                        len(plan.paths[i]) - 1,
                        f"{names[i]} ends at {loc(e)}, which is not a target of team {team.name!r}",
                    )
                )
        for t in team.targets:
            if ends[t] == 0:
                out.append(
                    Violation(
                        "target_missed",
                        (),
                        t,
                        None,
                        f"target {loc(t)} of team {team.name!r} is reached by no robot",
                    )
                )
            elif ends[t] > 1:
                who = tuple(i for i in team.agents if plan.paths[i][-1] == t)
                out.append(
                    Violation(
                        "target_shared",
                        who,
                        t,
                        None,
                        f"target {loc(t)} of team {team.name!r} is taken by "
                        f"{', '.join(names[i] for i in who)}",
                    )
                )

    # Blocked cells and moves along edges.
    for i, p in enumerate(plan.paths):
        for t, v in enumerate(p):
            if not g.passable[v]:
                out.append(
                    Violation("blocked", (i,), v, t, f"{names[i]} is on blocked {loc(v)} at t={t}")
                )
        for t in range(len(p) - 1):
            u, v = p[t], p[t + 1]
            if u != v and not g.has_edge(u, v):
                out.append(
                    Violation(
                        "non_edge",
                        (i,),
                        u,
                        t,
                        f"{names[i]} jumps {loc(u)} -> {loc(v)} at t={t}, which is not an edge",
                    )
                )

    # Conflicts, up to the last timestep any path lists (everyone is parked after it).
    horizon = plan.horizon
    paths = plan.paths
    n = len(paths)
    for t in range(horizon + 1):
        occupied: dict[int, int] = {}
        for i in range(n):
            p = paths[i]
            v = p[t] if t < len(p) else p[-1]
            j = occupied.get(v)
            if j is None:
                occupied[v] = i
            else:
                out.append(
                    Violation(
                        "vertex_conflict",
                        (j, i),
                        v,
                        t,
                        f"{names[j]} and {names[i]} are both at {loc(v)} at t={t}",
                    )
                )
        if t == horizon:
            break
        moves: dict[tuple[int, int], int] = {}
        for i in range(n):
            p = paths[i]
            if t + 1 >= len(p):
                continue
            u, v = p[t], p[t + 1]
            if u == v:
                continue
            j = moves.get((v, u))
            if j is not None:
                out.append(
                    Violation(
                        "swap_conflict",
                        (j, i),
                        u,
                        t,
                        f"{names[j]} and {names[i]} swap {loc(v)} <-> {loc(u)} "
                        f"between t={t} and t={t + 1}",
                    )
                )
            moves[(u, v)] = i
    return out


def is_valid(instance: Instance, plan: Plan) -> bool:
    """Shorthand for ``not validate(instance, plan)``."""
    return not validate(instance, plan)
