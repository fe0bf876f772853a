"""Checks that prove an instance has no plan, and a horizon that bounds every plan.

:func:`quick_infeasibility` is the front door's check, run once before any solver. On
undirected graphs it is *exact* for MAPF and TAPF: it returns a reason exactly when no
plan exists (:mod:`hierplan_opt.core.pebble_motion`, `docs/feasibility.md`). On directed
roadmaps it runs only the necessary checks (reachability, shared goals, assignment).

:func:`makespan_upper_bound` gives time-expanded formulations a finite horizon: a
solvable instance always has a plan within it.
"""

from __future__ import annotations

import math
from collections import Counter
from collections.abc import Iterator

import numpy as np

from hierplan_opt.core.graph import UNREACHABLE
from hierplan_opt.core.instance import Instance
from hierplan_opt.core.pebble_motion import (
    PebbleStructure,
    Violation,
    arrangement_violation,
    one_by_one,
)


def quick_infeasibility(instance: Instance) -> str | None:
    """A one-line reason why ``instance`` has no plan, or None if it has one.

    Checks: a goal no agent path can reach; two agents with one goal; for teams, no
    assignment of robots to targets in which every robot reaches its target; then, on
    undirected graphs, the exact pebble-motion test (agents that cannot pass each other,
    rings that keep their cyclic order, full components that only rotate). None means
    "a plan exists" on undirected graphs and "no check proves otherwise" on directed ones.

    Example
    -------
    >>> from hierplan_opt.core.graph import Graph
    >>> g = Graph.grid(3, 1, obstacles=[(1, 0)])
    >>> quick_infeasibility(Instance.mapf(g, [(0, 0)], [(2, 0)]))
    "agent 'agent0' cannot reach its goal [2, 0] from [0, 0]"
    >>> corridor = Graph.grid(4, 1)
    >>> why = quick_infeasibility(Instance.mapf(corridor, [(0, 0), (1, 0)], [(3, 0), (2, 0)]))
    >>> why.split(":")[0]
    "agent 'agent0' cannot get from [0, 0] to its goal [3, 0]"
    """
    g = instance.graph

    def loc(v: int) -> str:
        x = g.location(v)
        return repr(x) if isinstance(x, str) else str(list(x))

    if not instance.is_tapf:
        counts = Counter(a.goal for a in instance.agents)
        for goal, c in counts.items():
            if c > 1:
                who = [a.name for a in instance.agents if a.goal == goal]
                return f"agents {', '.join(map(repr, who))} share the goal {loc(goal)}"  # type: ignore[arg-type]
        if not g.directed and one_by_one(g.adj, instance.starts, instance.goals):  # type: ignore[arg-type]
            return None  # a plan exists (no need for the pebble-motion structure)

    if g.directed:

        def reaches(s: int, t: int) -> bool:
            return bool(g.dist_to(t)[s] < UNREACHABLE)
    else:
        comp = PebbleStructure.of(g).comp  # undirected: same component, no BFS per goal

        def reaches(s: int, t: int) -> bool:
            return comp[s] == comp[t]

    if not instance.is_tapf:
        for a in instance.agents:
            assert a.goal is not None
            if not reaches(a.start, a.goal):
                return f"agent {a.name!r} cannot reach its goal {loc(a.goal)} from {loc(a.start)}"
    else:
        # Imported here: scipy.optimize costs ~0.3 s to import, which MAPF never needs.
        from scipy.optimize import linear_sum_assignment

        for team in instance.teams:
            starts = [instance.agents[i].start for i in team.agents]
            reach = np.array([[reaches(s, t) for t in team.targets] for s in starts], dtype=bool)
            rows, cols = linear_sum_assignment(~reach)
            if not reach[rows, cols].all():
                return (
                    f"team {team.name!r}: no assignment lets every robot reach a target "
                    "(some targets are unreachable from enough starts)"
                )
    if g.directed:
        if joint_reachable(instance) is False:
            return (
                "no sequence of moves brings the agents to their goals (the exhaustive "
                "search of the joint configurations of this directed roadmap)"
            )
        return None
    why = _pebble_violation(instance)
    return None if why is None else _describe(instance, why)


#: Joint configurations of the map (robots of a team exchangeable) up to which
#: :func:`joint_reachable` runs at all: it can then visit every one.
JOINT_STATES = 20_000
#: Partial joint moves it enumerates at most (about 0.2 s).
JOINT_STEPS = 200_000


def joint_reachable(
    instance: Instance, max_states: int = JOINT_STATES, max_steps: int = JOINT_STEPS
) -> bool | None:
    """Whether some plan exists, decided by breadth-first search over the joint
    configurations (every agent waits or takes an arc at each step; no two on one vertex,
    no two over one edge in opposite directions; rotations along cycles and following
    are allowed, as in :func:`hierplan_opt.core.validate.validate`). Robots of one team
    are exchangeable. None when the map has more than ``max_states`` joint
    configurations or the search would exceed ``max_steps`` partial moves: the front
    door's exact test on directed roadmaps, where the pebble-motion test does not apply,
    for instances small enough to enumerate.

    Example
    -------
    >>> from hierplan_opt.core.graph import Graph
    >>> ring = [("A", "B"), ("B", "C"), ("C", "A")]
    >>> g = Graph.roadmap({"A": (0, 0), "B": (1, 0), "C": (0, 1)}, ring, directed=True)
    >>> joint_reachable(Instance.mapf(g, ["A", "B", "C"], ["B", "C", "A"]))  # rotate
    True
    >>> joint_reachable(Instance.mapf(g, ["A", "B", "C"], ["B", "A", "C"]))  # transpose
    False
    """
    g = instance.graph
    k = instance.num_agents
    if _configurations(instance) > max_states:
        return None  # more configurations than the search may visit: not worth starting
    adj = g.adj
    if instance.is_tapf:
        groups = [list(t.agents) for t in instance.teams]
        goal_sets = [tuple(sorted(t.targets)) for t in instance.teams]
    else:
        groups = [[i] for i in range(k)]
        goal_sets = [(a.goal,) for a in instance.agents]  # type: ignore[misc]
    order = [i for grp in groups for i in grp]  # state positions grouped by team

    def canon(pos: list[int]) -> tuple[int, ...]:
        out: list[int] = []
        at = 0
        for grp in groups:
            out += sorted(pos[at : at + len(grp)])
            at += len(grp)
        return tuple(out)

    goal = tuple(v for gs in goal_sets for v in gs)
    start = canon([instance.agents[i].start for i in order])
    if start == goal:
        return True
    seen = {start}
    frontier = [start]
    budget = [max_steps]
    while frontier:
        nxt_frontier: list[tuple[int, ...]] = []
        for state in frontier:
            for nxt in _joint_moves(state, adj, budget):
                c = canon(nxt)
                if c == goal:
                    return True
                if c not in seen:
                    seen.add(c)
                    nxt_frontier.append(c)
            if budget[0] < 0 or len(seen) > max_states:
                return None
        frontier = nxt_frontier
    return False


def _joint_moves(
    state: tuple[int, ...], adj: list[list[int]], budget: list[int]
) -> Iterator[list[int]]:
    """Every joint move from ``state`` (wait or one arc each; no shared vertex, no swap);
    each partial choice spends one unit of ``budget[0]``, and none is made below 0."""
    k = len(state)
    nxt = [0] * k
    taken: dict[int, int] = {}  # vertex -> the slot moving there this step

    def assign(i: int) -> Iterator[list[int]]:
        if i == k:
            yield nxt
            return
        u = state[i]
        for v in (u, *adj[u]):
            budget[0] -= 1
            if budget[0] < 0:
                return
            if v in taken:
                continue
            j = taken.get(u) if v != u else None  # a swap: the agent at v moves to u
            if j is not None and state[j] == v:
                continue
            taken[v] = i
            nxt[i] = v
            yield from assign(i + 1)
            del taken[v]

    yield from assign(0)


def _configurations(instance: Instance) -> int:
    """Joint configurations of the whole map (robots of a team exchangeable)."""
    n = instance.graph.num_vertices
    ways = math.perm(n, instance.num_agents) if instance.num_agents <= n else 0
    for team in instance.teams:
        ways //= math.factorial(len(team.agents))
    return ways


def _colouring(instance: Instance) -> tuple[list[int], list[int], list[int], list[int]]:
    """Starts, colours, targets and target colours (MAPF: one colour per agent)."""
    starts = [a.start for a in instance.agents]
    if not instance.is_tapf:
        k = instance.num_agents
        return starts, list(range(k)), [a.goal for a in instance.agents], list(range(k))  # type: ignore[misc]
    colours = [a.team for a in instance.agents]
    targets = [t for team in instance.teams for t in team.targets]
    target_colours = [ti for ti, team in enumerate(instance.teams) for _ in team.targets]
    return starts, colours, targets, target_colours  # type: ignore[return-value]


def _pebble_violation(instance: Instance) -> Violation | None:
    starts, colours, targets, target_colours = _colouring(instance)
    return arrangement_violation(instance.graph, starts, colours, targets, target_colours)


def _describe(instance: Instance, why: Violation) -> str:
    g = instance.graph

    def loc(v: int) -> str:
        x = g.location(v)
        return repr(x) if isinstance(x, str) else str(list(x))

    agent = instance.agents[why.index] if why.index is not None else None
    who = f"agent {agent.name!r}" if agent is not None else "an agent"
    if agent is not None and instance.is_tapf and agent.team is not None:
        who = f"robot {agent.name!r} of team {instance.teams[agent.team].name!r}"
    if why.kind == "fixed":
        return (
            f"{who} at {loc(why.vertex)} can never move: its part of the map has no empty "
            "vertex and no cycle passes through it, but its goal is elsewhere"
        )
    if why.kind == "cyclic":
        return (
            f"the agents on the cycle through {loc(why.vertex)} can only rotate along it "
            "(they cannot pass each other there), and their goals need another cyclic order"
        )
    if why.kind == "parity":
        return (
            f"the agents filling the odd cycles through {loc(why.vertex)} can only be "
            "permuted evenly (no empty vertex), and the goals need an odd permutation"
        )
    if instance.is_tapf:
        return (
            f"{who} at {loc(why.vertex)} cannot reach any target of its team: it cannot pass "
            "the robots in its way (too few empty vertices to reorder them)"
        )
    goal = f" to its goal {loc(why.other)}" if why.other is not None else ""
    return (
        f"{who} cannot get from {loc(why.vertex)}{goal}: it cannot pass the agents in its "
        "way (too few empty vertices to reorder them)"
    )


def makespan_upper_bound(instance: Instance) -> int:
    """A horizon within which every *solvable* instance has a plan.

    Always valid: the number of distinguishable joint configurations minus one (a
    shortest plan never repeats a configuration). For one team (anonymous MAPF) on an
    undirected graph, also the constructive bound sum over components of
    ``|starts not targets| * (component size - 1)``: fill one missing target at a time by
    moving the agents along a shortest path from it to the nearest surplus start, at most
    ``size - 1`` single moves each. The smaller of the applicable bounds is returned.
    A formulation that finds no plan with this makespan may answer INFEASIBLE.

    Example
    -------
    >>> from hierplan_opt.core.graph import Graph
    >>> g = Graph.grid(3, 1)
    >>> makespan_upper_bound(Instance.mapf(g, [(0, 0), (1, 0)], [(1, 0), (2, 0)]))
    5
    >>> makespan_upper_bound(Instance.tapf(g, [([(0, 0), (1, 0)], [(1, 0), (2, 0)])]))
    2
    """
    g = instance.graph
    s = PebbleStructure.of(g)
    colours = [a.team if instance.is_tapf else i for i, a in enumerate(instance.agents)]
    by_comp: dict[int, Counter[int]] = {}
    for a, c in zip(instance.agents, colours, strict=True):
        # On directed roadmaps count the whole map: components of out-arcs are not closed.
        cid = -1 if g.directed else s.comp[a.start]
        by_comp.setdefault(cid, Counter())[c] += 1  # type: ignore[index]
    configurations = 1
    for cid, cnt in by_comp.items():
        n = g.num_vertices if cid < 0 else s.comp_size[cid]
        p = sum(cnt.values())
        ways = math.perm(n, p)
        for m in cnt.values():
            ways //= math.factorial(m)
        configurations *= ways
    bound = configurations - 1
    if instance.is_tapf and len(instance.teams) == 1 and not g.directed:
        starts = {a.start for a in instance.agents}
        targets = set(instance.teams[0].targets)
        moves = sum(s.comp_size[s.comp[v]] - 1 for v in starts - targets)
        bound = min(bound, moves)
    return bound
