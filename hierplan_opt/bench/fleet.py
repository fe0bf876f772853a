"""A large valid plan for timing MAPF-POST: 1000 robots on the warehouse map.

The MovingAI warehouse scenarios stop at 450 agents, and no solver of the toolkit plans
1000 robots on ``warehouse-10-20-10-2-1`` quickly yet (at 17 % of the free cells, random
starts and goals need a coupled planner; prioritized planning and trip-by-trip plans
get stuck). :func:`fleet_plan` therefore builds the plan first and the instance from
it: robots start on distinct random cells and make a few *trips* in rounds; in each
round, one after another, robots pick a random cell 10-40 steps away that a shortest
path reaches avoiding every other robot's cell and the paths already taken this round,
and take that path; everybody else waits. Movers' paths are vertex-disjoint and nobody
stands on them, so the plan has no conflicts (the validator checks it anyway). A
robot's goal is where its last trip ends. The plan is not a MAPF solution of anything
a user asked for; its size (about one visit per robot and path cell) and its sharing of
cells between robots are what the MAPF-POST benchmark needs.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import breadth_first_order

from hierplan_opt.core.graph import Graph
from hierplan_opt.core.instance import Instance
from hierplan_opt.core.plan import Plan


def _reachable(g: Graph, src: int, blocked: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """BFS order and predecessors from ``src`` avoiding ``blocked`` vertices."""
    ok = ~blocked
    ok[src] = True
    rows = np.repeat(np.arange(g.n), np.diff(g.indptr))
    keep = ok[rows] & ok[g.indices]
    m = sp.csr_matrix(
        (np.ones(int(keep.sum()), dtype=np.int8), (rows[keep], g.indices[keep])), shape=(g.n, g.n)
    )
    order, pred = breadth_first_order(m, src, directed=True, return_predecessors=True)
    return order, pred


def fleet_plan(
    graph: Graph,
    agents: int,
    *,
    trips: int = 4,
    trip_steps: tuple[int, int] = (10, 40),
    seed: int = 0,
    max_rounds: int = 200,
) -> tuple[Instance, Plan]:
    """A valid plan of ``agents`` robots making ``trips`` trips each, and its instance.

    Example
    -------
    >>> from hierplan_opt.core.validate import validate
    >>> inst, plan = fleet_plan(Graph.grid(8, 8), 6, trips=2, trip_steps=(2, 5), seed=1)
    >>> validate(inst, plan), inst.num_agents
    ([], 6)
    """
    rng = np.random.default_rng(seed)
    free = np.flatnonzero(graph.passable)
    pos = rng.choice(free, agents, replace=False).astype(np.int64)
    starts = pos.copy()
    paths: list[list[int]] = [[int(v)] for v in pos]
    left = np.full(agents, trips)
    lo, hi = trip_steps
    for _ in range(max_rounds):
        if not left.any():
            break
        occupied = np.zeros(graph.n, dtype=bool)
        occupied[pos] = True
        busy = occupied.copy()
        moves: dict[int, list[int]] = {}
        for i in rng.permutation(np.flatnonzero(left > 0)).tolist():
            order, pred = _reachable(graph, int(pos[i]), busy)
            # Depth of each reached vertex (BFS order: parents come first).
            depth = np.zeros(graph.n, dtype=np.int64)
            for v in order[1:].tolist():
                depth[v] = depth[pred[v]] + 1
            far = order[(depth[order] >= lo) & (depth[order] <= hi)]
            if not len(far):
                continue
            v = int(rng.choice(far))
            p = [v]
            while p[-1] != pos[i]:
                p.append(int(pred[p[-1]]))
            p.reverse()
            moves[i] = p
            busy[p] = True
        if not moves:
            break
        length = max(len(p) for p in moves.values()) - 1
        for i in range(agents):
            p = moves.get(i)
            if p is None:
                paths[i] += [int(pos[i])] * length
            else:
                paths[i] += p[1:] + [p[-1]] * (length - len(p) + 1)
                pos[i] = p[-1]
                left[i] -= 1
    inst = Instance.mapf(
        graph,
        [graph.location(int(v)) for v in starts],
        [graph.location(int(v)) for v in pos],
        name=f"fleet-{agents}-seed{seed}",
    )
    return inst, Plan.from_paths(paths)


def fleet_row(graph: Graph, agents: int, repeats: int, seed: int = 0) -> str:
    """One line of ``hierplan bench post``: MAPF-POST's earliest schedule of a
    :func:`fleet_plan` (medians of ``repeats`` runs of ``postprocess`` without the
    validator, which is timed once on its own)."""
    import statistics
    import time

    from hierplan_opt.core.validate import validate
    from hierplan_opt.schedule import postprocess, replay

    inst, plan = fleet_plan(graph, agents, seed=seed)
    t0 = time.perf_counter()
    bad = validate(inst, plan)
    t_valid = time.perf_counter() - t0
    if bad:
        raise RuntimeError(f"fleet plan invalid: {bad[0]}")
    runs = []
    s = postprocess(inst, plan, check_plan=False)  # warm-up (imports), not timed
    for _ in range(max(repeats, 1)):
        t0 = time.perf_counter()
        s = postprocess(inst, plan, check_plan=False)
        runs.append(time.perf_counter() - t0)
    rep = replay(s, inst)
    st = s.stats
    return (
        f"fleet {agents} robots (fleet_plan, {agents * 4} trips): SOC {plan.sum_of_costs}, "
        f"{st['tpg_nodes']} nodes, {st['type2_arcs']} type-2 arcs; earliest schedule "
        f"{statistics.median(runs):.3f} s (median of {repeats}: build {st['tpg_time']:.3f} + "
        f"{st['stn_time']:.3f}, solve {st['solve_time']:.3f}, windows "
        f"{st['window_time']:.3f}), validator {t_valid:.3f} s, replay "
        f"{'ok' if rep.ok else 'FAILED'}"
    )
