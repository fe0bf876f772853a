"""Independent brute-force optimal makespan for tiny MAPF / TAPF instances (tests only).

Breadth-first search over joint configurations (one vertex per robot), with the
collision rules written out from the problem definition: all robots move or wait at
once, no two robots on one vertex, no two robots swapping along an edge. A joint
configuration is a goal when every robot stands on a target of its team (MAPF: its
own goal) and every target is covered. The BFS depth of the first goal is the optimal
makespan (robots stay at their final vertices afterwards, so reaching a goal
configuration at time T is a plan of makespan T). Shares no code with the solvers.
"""

from __future__ import annotations

import itertools
from collections import deque

from hierplan_opt import Graph, Instance


def _neighbours(graph: Graph, v: int) -> list[int]:
    return [v, *(int(u) for u in graph.neighbors(v))]


def brute_force_makespan(instance: Instance, max_depth: int = 40) -> int | None:
    """Optimal makespan by BFS over joint configurations, or None if none within depth."""
    g = instance.graph
    k = instance.num_agents
    if instance.is_tapf:
        team_of = [a.team for a in instance.agents]
        target_sets = [frozenset(t.targets) for t in instance.teams]

        def is_goal(conf: tuple[int, ...]) -> bool:
            for ti, targets in enumerate(target_sets):
                ends = {conf[i] for i in range(k) if team_of[i] == ti}
                if ends != targets:
                    return False
            return True
    else:
        goals = tuple(a.goal for a in instance.agents)

        def is_goal(conf: tuple[int, ...]) -> bool:
            return conf == goals

    start = tuple(a.start for a in instance.agents)
    if is_goal(start):
        return 0
    seen = {start}
    frontier = deque([(start, 0)])
    moves = {}
    while frontier:
        conf, d = frontier.popleft()
        if d >= max_depth:
            continue
        options = []
        for v in conf:
            if v not in moves:
                moves[v] = _neighbours(g, v)
            options.append(moves[v])
        for nxt in itertools.product(*options):
            if len(set(nxt)) < k:
                continue  # vertex conflict
            swap = False
            for i in range(k):
                if nxt[i] == conf[i]:
                    continue
                for j in range(i + 1, k):
                    if nxt[i] == conf[j] and nxt[j] == conf[i]:
                        swap = True
                        break
                if swap:
                    break
            if swap or nxt in seen:
                continue
            if is_goal(nxt):
                return d + 1
            seen.add(nxt)
            frontier.append((nxt, d + 1))
    return None
