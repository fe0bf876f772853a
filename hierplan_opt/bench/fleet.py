"""A large valid plan for timing MAPF-POST: 1000 robots on the warehouse map.

The MovingAI warehouse scenarios stop at 450 agents. :func:`lacam_fleet` draws random
starts and goals (the recipe of ``instances/large/generate.py``: with seed 1 on
``warehouse-10-20-10-2-1`` these are the robots of
``instances/large/warehouse-10-20-10-2-1-gen-1.scen``) and plans them with LaCAM (its
first plan, a few seconds for 1000 robots); this is the plan the MAPF-POST benchmark
times. When LaCAM finds no plan in its time limit, :func:`fleet_plan` is the fallback:
it builds a plan first and the instance from it: robots start on distinct random
cells and make a few *trips* in rounds; in each round, one after another, robots pick
a random cell 10-40 steps away that a shortest path reaches avoiding every other
robot's cell and the paths already taken this round, and take that path; everybody
else waits. Movers' paths are vertex-disjoint and nobody stands on them, so the plan
has no conflicts (the validator checks it anyway). A robot's goal is where its last
trip ends.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import breadth_first_order

from hierplan_opt.api import solve
from hierplan_opt.core.graph import Graph
from hierplan_opt.core.instance import Instance
from hierplan_opt.core.plan import Plan
from hierplan_opt.core.validate import validate


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


def lacam_fleet(
    graph: Graph, agents: int, *, seed: int = 1, time_limit: float = 60.0
) -> tuple[Instance, Plan, float] | None:
    """Random starts and goals for ``agents`` robots, LaCAM's first plan and its time.

    Starts are the first ``agents`` free cells (row by row) of one ``random.Random(seed)``
    shuffle, goals of a second one. None when LaCAM finds no plan within ``time_limit``.

    Example
    -------
    >>> from hierplan_opt.core.validate import validate
    >>> inst, plan, seconds = lacam_fleet(Graph.grid(8, 8), 20)
    >>> validate(inst, plan), inst.num_agents
    ([], 20)
    """
    import random

    cells = sorted(
        (graph.location(int(v)) for v in np.flatnonzero(graph.passable)),
        key=lambda c: (c[1], c[0]),
    )
    rng = random.Random(seed)
    starts = cells[:]
    rng.shuffle(starts)
    goals = cells[:]
    rng.shuffle(goals)
    inst = Instance.mapf(graph, starts[:agents], goals[:agents], name=f"fleet-{agents}-seed{seed}")
    r = solve(inst, "lacam", time_limit=time_limit, seed=0, anytime=0)
    if r.plan is None:
        return None
    return inst, r.plan, float(r.stats["first_time"])


def fleet_row(graph: Graph, agents: int, repeats: int, seed: int = 1) -> str:
    """One line of ``hierplan bench post``: MAPF-POST's earliest schedule of a
    :func:`lacam_fleet` plan (:func:`fleet_plan` if LaCAM finds none); medians of
    ``repeats`` runs of ``postprocess`` without the validator, which is timed once on
    its own."""
    import statistics
    import time

    from hierplan_opt.schedule import postprocess, replay

    found = lacam_fleet(graph, agents, seed=seed)
    if found is not None:
        inst, plan, t_plan = found
        source = f"lacam first plan {t_plan:.1f} s, random starts/goals seed {seed}"
    else:
        inst, plan = fleet_plan(graph, agents, seed=seed)
        source = f"fleet_plan, {agents * 4} trips: lacam found no plan"
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
        f"fleet {agents} robots ({source}): SOC {plan.sum_of_costs}, "
        f"{st['tpg_nodes']} nodes, {st['type2_arcs']} type-2 arcs; earliest schedule "
        f"{statistics.median(runs):.3f} s (median of {repeats}: build {st['tpg_time']:.3f} + "
        f"{st['stn_time']:.3f}, solve {st['solve_time']:.3f}, windows "
        f"{st['window_time']:.3f}), validator {t_valid:.3f} s, replay "
        f"{'ok' if rep.ok else 'FAILED'}"
    )
