"""Brute force over joint configurations for the feasibility tests (tests only).

The move rule is the validator's (``hierplan_opt.core.validate``): in one timestep every
agent waits or moves along one edge, no two agents end on one vertex, and no two agents
swap along an edge; an agent may move into a vertex that another agent leaves at the same
timestep, so chains and rotations along cycles of length >= 3 are allowed. Shares no code
with :mod:`hierplan_opt.core.pebble_motion`.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Iterator, Sequence

Config = tuple[int, ...]


def successors(adj: Sequence[Sequence[int]], conf: Config) -> Iterator[Config]:
    """Every configuration one synchronous step away (waiting everywhere included)."""
    k = len(conf)
    where = {v: i for i, v in enumerate(conf)}
    choice = [0] * k
    used: set[int] = set()

    def rec(i: int) -> Iterator[Config]:
        if i == k:
            yield tuple(choice)
            return
        u = conf[i]
        for v in (u, *adj[u]):
            if v in used:
                continue
            j = where.get(v)
            # j < i already chose; j moving v -> u while i moves u -> v is a swap.
            if v != u and j is not None and j < i and choice[j] == u:
                continue
            used.add(v)
            choice[i] = v
            yield from rec(i + 1)
            used.discard(v)

    # A swap with a later agent is caught when that agent chooses.
    yield from rec(0)


def all_configs(n: int, k: int) -> Iterator[Config]:
    """All placements of ``k`` labelled agents on distinct vertices ``0..n-1``."""
    from itertools import permutations

    return permutations(range(n), k)


def reachability_classes(adj: Sequence[Sequence[int]], k: int) -> dict[Config, int]:
    """Component id of every configuration of ``k`` agents (reachability is symmetric)."""
    comp: dict[Config, int] = {}
    cid = 0
    for c0 in all_configs(len(adj), k):
        if c0 in comp:
            continue
        comp[c0] = cid
        todo = [c0]
        while todo:
            c = todo.pop()
            for d in successors(adj, c):
                if d not in comp:
                    comp[d] = cid
                    todo.append(d)
        cid += 1
    return comp


def shortest_plan(adj: Sequence[Sequence[int]], start: Config, goal: Config) -> list[Config] | None:
    """A minimum-makespan sequence of configurations from ``start`` to ``goal``, or None."""
    parent: dict[Config, Config | None] = {start: None}
    q = deque([start])
    while q:
        c = q.popleft()
        if c == goal:
            out = [c]
            while (p := parent[out[-1]]) is not None:
                out.append(p)
            return out[::-1]
        for d in successors(adj, c):
            if d not in parent:
                parent[d] = c
                q.append(d)
    return None


def distances_from(adj: Sequence[Sequence[int]], start: Config) -> dict[Config, int]:
    """BFS depth (optimal makespan) of every configuration reachable from ``start``."""
    dist = {start: 0}
    q = deque([start])
    while q:
        c = q.popleft()
        for d in successors(adj, c):
            if d not in dist:
                dist[d] = dist[c] + 1
                q.append(d)
    return dist
