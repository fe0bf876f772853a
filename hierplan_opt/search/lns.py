"""Plan refinement by large neighbourhood search (LNS) for the sum of costs.

The idea of MAPF-LNS (Li, Chen, Harabor, Stuckey, Koenig, IJCAI 2021) and of the
refiners of "Engineering LaCAM*" (Okumura, AAMAS 2024): take a valid plan, remove the
paths of a few agents (the *neighbourhood*), replan them one after another around the
paths of everybody else, and keep the new paths when their total cost is not larger.
Every accepted step keeps the plan valid, so the refiner can be stopped at any time.

Neighbourhoods sweep the agents in a shuffled order, ``size`` agents at a time, with a
new random size between 1 and :data:`MAX_NEIGHBOURHOOD` for each sweep; every other
neighbourhood is instead built around the agent with the largest delay (cost minus its
distance) plus agents whose paths it meets on its own shortest path.

Each agent is replanned by space-time A* (states ``(vertex, time)``, unit moves and
waits) that treats the other agents' paths as hard obstacles: their vertices, the
swaps with them, and their goals from the time they arrive there for good. An agent's
own final arrival must come after the last visit of anybody else to its goal. The
search is bounded by what the neighbourhood may cost at most, so it fails fast when no
improvement is possible.
"""

from __future__ import annotations

import random
from bisect import insort
from heapq import heappop, heappush

from hierplan_opt.core.timer import Deadline
from hierplan_opt.search.pibt_engine import Space

#: Largest neighbourhood (agents replanned together).
MAX_NEIGHBOURHOOD = 30
#: Bits per field of the packed A* heap keys (vertex ids and times below 2**BITS).
BITS = 24
MASK = (1 << BITS) - 1
#: Neighbourhood kinds: random sweeps, around a delayed agent's goal, along its path.
RANDOM, GOAL, PATH = 0, 1, 2
#: Adaptive weights: reaction factor and floor.
REACTION = 0.1
MIN_WEIGHT = 0.05


class Refiner:
    """LNS over a plan given as compact-id paths (trimmed: each ends on its arrival).

    Example
    -------
    >>> from hierplan_opt.core.graph import Graph
    >>> from hierplan_opt.core.instance import Instance
    >>> inst = Instance.mapf(Graph.grid(3, 3), [(0, 0)], [(2, 2)])
    >>> space = Space(inst)
    >>> r = Refiner(space, [[0, 0, 0, 1, 2, 5, 8]], seed=0)  # waits twice, then goes
    >>> r.cost, r.step(), r.cost
    (6, 2, 4)
    """

    def __init__(self, space: Space, paths: list[list[int]], seed: int = 0) -> None:
        self.space = space
        self.nv = space.nv
        self.succ = [p[0] for p in space.perms]  # neighbours plus the vertex itself
        self.rng = random.Random(seed)
        self.paths: list[list[int]] = []
        self.occ: dict[int, int] = {}  # t * nv + v -> agent
        # goal vertex -> time its agent rests there for good (MASK: nobody)
        self.park_at = [MASK] * space.nv
        self.visits: list[list[int]] = [[] for _ in range(space.nv)]  # sorted times per vertex
        self.sweep: list[int] = []
        self.size = 1
        self.replanned = 0
        self.accepted = 0
        #: Weights of the neighbourhood kinds (RANDOM, GOAL, PATH).
        self.weights = [1.0, 1.0, 1.0]
        #: Give up on one agent after this many A* expansions.
        self.expansion_limit = max(1000, 2 * space.nv)
        self.reset(paths)

    # ------------------------------------------------------------------ the plan
    def reset(self, paths: list[list[int]]) -> None:
        """Start over from another plan (e.g. a better one the search found)."""
        self.occ.clear()
        self.park_at = [MASK] * self.nv
        for visits in self.visits:
            visits.clear()
        self.paths = [list(p) for p in paths]
        for i in range(len(self.paths)):
            self._add(i)
        self.sweep = []

    @property
    def cost(self) -> int:
        """Sum of costs of the current plan."""
        return sum(len(p) - 1 for p in self.paths)

    def _add(self, i: int) -> None:
        nv = self.nv
        occ = self.occ
        visits = self.visits
        p = self.paths[i]
        for t, v in enumerate(p):
            occ[t * nv + v] = i
            insort(visits[v], t)
        self.park_at[p[-1]] = len(p) - 1

    def _remove(self, i: int) -> None:
        nv = self.nv
        occ = self.occ
        visits = self.visits
        p = self.paths[i]
        for t, v in enumerate(p):
            del occ[t * nv + v]
            visits[v].remove(t)
        self.park_at[p[-1]] = MASK

    # ------------------------------------------------------------------ one agent
    def replan(self, i: int, bound: int) -> list[int] | None:
        """Cheapest path of agent ``i`` around the others with cost at most ``bound``.

        Space-time A*: states ``(vertex, time)``, unit moves and waits; the estimate
        is the larger of the distance to the goal and the earliest time the goal is
        free for good. (Safe-interval planning was measured slower on the congested
        plans this refines: many short intervals per vertex.)
        """
        space = self.space
        s = space.starts[i]
        gl = space.goals[i]
        d = space.dist[i]
        visits = self.visits[gl]
        # The final arrival comes after the last visit of anybody else to the goal.
        after = visits[-1] + 1 if visits else 0
        h0 = max(d[s], after)
        if h0 > bound:
            return None
        self.replanned += 1
        nv = self.nv
        occ = self.occ
        park = self.park_at
        succ = self.succ
        parent: dict[int, int] = {s: -1}
        # Heap entries are single ints: estimate, then later time first, then vertex.
        heap = [(h0 << 2 * BITS) | (MASK << BITS) | s]
        budget = self.expansion_limit
        while heap:
            e = heappop(heap)
            v = e & MASK
            t = MASK - ((e >> BITS) & MASK)
            if v == gl and t >= after:
                path = [v]
                key = parent[t * nv + v]
                while key >= 0:
                    path.append(key % nv)
                    key = parent[key]
                path.reverse()
                return path
            budget -= 1
            if budget < 0:
                return None
            t1 = t + 1
            base0 = t * nv
            base1 = t1 * nv
            key0 = base0 + v
            tbits = (MASK - t1) << BITS
            mover = occ.get(base1 + v)  # whoever enters v next: no swapping with them
            for u in succ[v]:
                k1 = base1 + u
                if k1 in parent or k1 in occ or park[u] <= t1:
                    continue
                if mover is not None and u != v and occ.get(base0 + u) == mover:
                    continue
                fu = t1 + d[u]
                if fu < after:
                    fu = after
                if fu > bound:
                    continue
                parent[k1] = key0
                heappush(heap, (fu << 2 * BITS) | tbits | u)
        return None

    # ------------------------------------------------------------------ neighbourhoods
    def _random_neighbourhood(self) -> list[int]:
        n = len(self.paths)
        if not self.sweep:
            self.sweep = list(range(n))
            self.rng.shuffle(self.sweep)
            self.size = self.rng.randint(1, max(1, min(MAX_NEIGHBOURHOOD, n // 4)))
        k = min(self.size, len(self.sweep))
        out = self.sweep[-k:]
        del self.sweep[-k:]
        return out

    def _delayed_agent(self) -> int | None:
        """An agent drawn with probability proportional to its delay (None: no delays)."""
        space = self.space
        dist = space.dist
        starts = space.starts
        delays = [len(p) - 1 - dist[i][starts[i]] for i, p in enumerate(self.paths)]
        total = sum(delays)
        if total <= 0:
            return None
        x = self.rng.randrange(total)
        a = 0
        while x >= delays[a]:
            x -= delays[a]
            a += 1
        return a

    def _size(self) -> int:
        return self.rng.randint(2, max(2, min(MAX_NEIGHBOURHOOD, len(self.paths) // 4)))

    def _goal_neighbourhood(self) -> list[int] | None:
        """A delayed agent first, then the agents that visit its goal after it could
        have arrived there: their visits keep it from finishing early."""
        a = self._delayed_agent()
        if a is None:
            return None
        space = self.space
        gl = space.goals[a]
        early = space.dist[a][space.starts[a]]
        nv = self.nv
        occ = self.occ
        want = self._size()
        group = [a]
        seen = {a}
        for t in reversed(self.visits[gl]):
            if t < early or len(group) >= want:
                break
            b = occ[t * nv + gl]
            if b not in seen:
                seen.add(b)
                group.append(b)
        return group

    def _path_neighbourhood(self) -> list[int] | None:
        """A delayed agent first, then the agents in the way of a shortest path of it
        (on its vertices about when it would pass there), as in MAPF-LNS's agent-based
        neighbourhoods."""
        a = self._delayed_agent()
        if a is None:
            return None
        space = self.space
        d = space.dist[a]
        adj = space.adj
        nv = self.nv
        occ = self.occ
        rng = self.rng
        want = self._size()
        group = [a]
        seen = {a}
        v = space.starts[a]
        t = 0
        while len(group) < want:
            for tt in (t, t + 1):
                b = occ.get(tt * nv + v)
                if b is not None and b not in seen:
                    seen.add(b)
                    group.append(b)
            if d[v] == 0:
                break
            down = [u for u in adj[v] if d[u] < d[v]]
            v = down[rng.randrange(len(down))]
            t += 1
        return group

    def _neighbourhood(self) -> tuple[int, list[int]]:
        """Which kind (drawn by adaptive weight) and the agents."""
        w = self.weights
        x = self.rng.random() * sum(w)
        kind = 0
        while kind < len(w) - 1 and x >= w[kind]:
            x -= w[kind]
            kind += 1
        group = None
        if kind == GOAL:
            group = self._goal_neighbourhood()
        elif kind == PATH:
            group = self._path_neighbourhood()
        if group is None:
            kind = RANDOM
            group = self._random_neighbourhood()
        return kind, group

    def step(self) -> int:
        """Try one neighbourhood; returns the cost saved (0 when nothing improved).

        The kinds of neighbourhood are drawn by weights that follow their recent
        savings per replanned agent (adaptive LNS, as in MAPF-LNS).
        """
        kind, group = self._neighbourhood()
        saved = self._replace(group)
        w = self.weights
        w[kind] = max(MIN_WEIGHT, (1 - REACTION) * w[kind] + REACTION * saved / len(group))
        return saved

    def _replace(self, group: list[int]) -> int:
        space = self.space
        old = {a: self.paths[a] for a in group}
        old_cost = sum(len(p) - 1 for p in old.values())
        for a in group:
            self._remove(a)
        rest = sum(space.dist[a][space.starts[a]] for a in group)
        spent = 0
        done: list[int] = []
        ok = True
        for a in group:
            rest -= space.dist[a][space.starts[a]]
            p = self.replan(a, old_cost - spent - rest)
            if p is None:
                ok = False
                break
            self.paths[a] = p
            self._add(a)
            done.append(a)
            spent += len(p) - 1
        if ok and spent <= old_cost:
            self.accepted += 1
            return old_cost - spent
        for a in done:
            self._remove(a)
        for a in group:
            self.paths[a] = old[a]
            self._add(a)
        return 0

    def run(self, deadline: Deadline) -> int:
        """Refine until ``deadline``; returns the total cost saved."""
        saved = 0
        while not deadline.expired():
            saved += self.step()
        return saved
