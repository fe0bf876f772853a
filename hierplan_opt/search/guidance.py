"""Guide paths that spread agents out: space utilisation optimisation (SUO).

"Engineering LaCAM*" (Okumura, AAMAS 2024) gives PIBT a preferred next vertex per
agent and vertex, read off paths that were planned to *avoid each other* before the
search starts: each agent takes a path at most ``margin`` steps longer than a
shortest one that meets as few other agents as possible (same vertex at the same
time, a swap, or passing over a goal where its agent has arrived). Agents are
replanned in random order, round after round, while the number of such meetings
keeps falling. The paths themselves are not a plan (they may still collide and never
wait); they only tilt PIBT's choices, which spreads traffic over parallel corridors.

Each single-agent search is A* over vertices (time is the path length, there is no
waiting), ordered first by meetings, then by length estimate; a vertex is closed on
its first expansion, so the result is a good path, not necessarily the one with the
fewest meetings.
"""

from __future__ import annotations

import random
from heapq import heappop, heappush

from hierplan_opt.core.timer import Deadline
from hierplan_opt.search.pibt_engine import Space

#: Extra steps a guide path may take over a shortest path.
MARGIN = 10
#: Rounds of replanning every agent (the first one gives most of the effect).
ROUNDS = 2


class _Table:
    """Where the guide paths are: counts per (time, vertex), moves, arrivals at goals."""

    def __init__(self, nv: int) -> None:
        self.nv = nv
        self.at: dict[int, int] = {}
        self.moves: dict[int, int] = {}
        self.arrived: dict[int, int] = {}  # vertex -> time its agent arrives there for good

    def meetings(self, v: int, u: int, t: int) -> int:
        """Meetings of a move ``v -> u`` arriving at time ``t``."""
        nv = self.nv
        c = self.at.get(t * nv + u, 0)
        if u != v:
            c += self.moves.get((t * nv + u) * nv + v, 0)  # someone moves u -> v then
        a = self.arrived.get(u)
        if a is not None and a <= t:
            c += 1
        return c

    def add(self, path: list[int], sign: int) -> None:
        nv = self.nv
        for t, v in enumerate(path):
            k = t * nv + v
            self.at[k] = self.at.get(k, 0) + sign
            if t:
                u = path[t - 1]
                if u != v:
                    mk = (t * nv + u) * nv + v  # a move u -> v arriving at t
                    self.moves[mk] = self.moves.get(mk, 0) + sign
        if sign > 0:
            self.arrived[path[-1]] = len(path) - 1
        else:
            self.arrived.pop(path[-1], None)


def guide_paths(
    space: Space,
    deadline: Deadline,
    seed: int = 0,
    *,
    rounds: int = ROUNDS,
    margin: int = MARGIN,
) -> list[list[int]] | None:
    """Guide paths (compact ids) for every agent: up to ``rounds`` rounds, fewer when a
    round does not reduce the meetings; None when ``deadline`` passes before the first
    round is complete.

    Example
    -------
    >>> from hierplan_opt.core.graph import Graph
    >>> from hierplan_opt.core.instance import Instance
    >>> inst = Instance.mapf(Graph.grid(3, 3), [(0, 0), (0, 2)], [(2, 0), (2, 2)])
    >>> space = Space(inst)
    >>> [len(p) - 1 for p in guide_paths(space, Deadline(5))]
    [2, 2]
    """
    rng = random.Random(seed)
    n = space.n_agents
    table = _Table(space.nv)
    paths: list[list[int]] = [[] for _ in range(n)]
    best_total: int | None = None
    best_paths: list[list[int]] | None = None
    for _ in range(rounds):
        order = list(range(n))
        rng.shuffle(order)
        for i in order:
            if deadline.expired():
                return best_paths
            if paths[i]:
                table.add(paths[i], -1)
            p = _path(space, table, i, margin)
            paths[i] = p
            table.add(p, +1)
        total = 0
        for p in paths:
            last = len(p) - 1
            for t in range(1, last + 1):
                # minus the agent itself: its own visit, and its own arrival at the end
                total += table.meetings(p[t - 1], p[t], t) - 1 - (t == last)
        if best_total is not None and total >= best_total:
            break
        best_total = total
        best_paths = [p[:] for p in paths]
        if total == 0:
            break
    return best_paths


def guide_table(paths: list[list[int]]) -> list[dict[int, int]]:
    """Per agent: vertex -> the next vertex on its guide path."""
    return [{p[t]: p[t + 1] for t in range(len(p) - 1)} for p in paths]


def _path(space: Space, table: _Table, i: int, margin: int) -> list[int]:
    s = space.starts[i]
    gl = space.goals[i]
    d = space.dist[i]
    bound = d[s] + margin
    adj = space.adj
    parent: dict[int, int] = {}
    heap = [(0, d[s], s, 0, -1)]
    while heap:
        c, _, v, g, par = heappop(heap)
        if v in parent:
            continue
        parent[v] = par
        if v == gl:
            path = [v]
            x = par
            while x >= 0:
                path.append(x)
                x = parent[x]
            path.reverse()
            return path
        g1 = g + 1
        for u in adj[v]:
            if u in parent:
                continue
            f = g1 + d[u]
            if f > bound:
                continue
            heappush(heap, (c + table.meetings(v, u, g1), f, u, g1, v))
    return [s]  # cannot happen on a connected instance (the bound admits a shortest path)
