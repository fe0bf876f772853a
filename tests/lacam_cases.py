"""Instances shared by the PIBT and LaCAM tests: tunnels, random 2D/3D grids, roadmaps."""

from __future__ import annotations

import random
import time
from pathlib import Path

from canned import _largest_component

import hierplan_opt as hp
from hierplan_opt.core.graph import Graph
from hierplan_opt.core.instance import Instance
from hierplan_opt.io.movingai import load_movingai

ROOT = Path(__file__).resolve().parents[1]
MOVINGAI = ROOT / "instances" / "movingai"
LARGE = ROOT / "instances" / "large"


def tunnel(length: int, branch_at: int, branch_len: int, k: int) -> Instance:
    """A dead-end corridor (column 0) with one side branch; ``k`` robots at its dead end
    must reverse their order. Plain PIBT cannot: the robot in front never lets the
    others overtake it in the branch."""
    w = branch_len + 1
    obstacles = [(x, y) for x in range(1, w) for y in range(length) if y != branch_at]
    g = Graph.grid(w, length, obstacles=obstacles)
    starts = [(0, length - 1 - i) for i in range(k)]
    goals = [(0, length - k + i) for i in range(k)]
    return Instance.mapf(g, starts, goals, name=f"tunnel{length}-{branch_at}-{branch_len}-{k}")


def swap_on_path(length: int) -> Instance:
    """Two robots swap the ends of a path graph without any siding: no plan exists."""
    g = Graph.grid(length, 1)
    return Instance.mapf(g, [(0, 0), (length - 1, 0)], [(length - 1, 0), (0, 0)], name="path")


def one_way_ring() -> Instance:
    """A full one-way ring of three robots asked to transpose two: they can only rotate,
    so no plan exists, and no quick check proves it (LaCAM's exhausted search does)."""
    g = Graph.roadmap(
        {"A": (0, 0), "B": (1, 0), "C": (0, 1)}, [("A", "B"), ("B", "C"), ("C", "A")], directed=True
    )
    return Instance.mapf(g, ["A", "B", "C"], ["B", "A", "C"], name="one-way-ring")


def random_grid(w: int, h: int, d: int | None, density: float, k: int, seed: int) -> Instance:
    """A random 2D (``d`` None) or 3D grid with ``k`` robots in its largest component."""
    rng = random.Random(seed)
    dims = (w, h) if d is None else (w, h, d)
    obstacles = [c for c in _cells(dims) if rng.random() < density]
    g = Graph.grid(*dims, obstacles=obstacles)
    comp = _largest_component(g)
    rng.shuffle(comp)
    starts = comp[:k]
    goals = comp[:]
    rng.shuffle(goals)
    goals = goals[:k]
    return Instance.mapf(
        g, [g.location(v) for v in starts], [g.location(v) for v in goals], name=f"rand{seed}"
    )


def random_roadmap(n: int, k: int, seed: int, *, directed: bool = False) -> Instance:
    """A random connected roadmap (a ring plus chords; both ways round when directed)."""
    rng = random.Random(seed)
    names = [f"v{i}" for i in range(n)]
    vertices = {names[i]: (rng.random() * 10, rng.random() * 10) for i in range(n)}
    edges = {(i, (i + 1) % n) for i in range(n)}
    if directed:
        edges |= {((i + 1) % n, i) for i in range(0, n, 3)}
    for _ in range(n // 2):
        a, b = rng.sample(range(n), 2)
        if (a, b) not in edges and (b, a) not in edges:
            edges.add((a, b))
    g = Graph.roadmap(vertices, [(names[a], names[b]) for a, b in sorted(edges)], directed=directed)
    order = names[:]
    rng.shuffle(order)
    goals = names[:]
    rng.shuffle(goals)
    return Instance.mapf(g, order[:k], goals[:k], name=f"roadmap{seed}")


def movingai(map_name: str, scen: str, k: int) -> Instance:
    return load_movingai(MOVINGAI / f"{map_name}.map", MOVINGAI / scen, k)


def large_empty(k: int) -> Instance:
    return load_movingai(LARGE / "empty-64-64.map", LARGE / "empty-64-64-gen-1.scen", k)


def _cells(dims: tuple[int, ...]) -> list[tuple[int, ...]]:
    if len(dims) == 2:
        return [(x, y) for y in range(dims[1]) for x in range(dims[0])]
    return [(x, y, z) for z in range(dims[2]) for y in range(dims[1]) for x in range(dims[0])]


def check(inst: Instance, res: hp.Result) -> None:
    """A result with a plan is valid and reports its own cost."""
    if res.plan is not None:
        assert hp.validate(inst, res.plan) == []
        assert res.cost == res.plan.sum_of_costs
        assert res.cost is not None and res.lower_bound is not None
        assert res.lower_bound <= res.cost


def assert_quick_time_limit(solver: str) -> None:
    """0.1 s on 2000 agents: back within about the limit, without a plan, saying so."""
    inst = large_empty(2000)
    t0 = time.perf_counter()
    res = hp.solve(inst, solver, time_limit=0.1)
    elapsed = time.perf_counter() - t0
    assert res.status == hp.Status.TIME_LIMIT and res.plan is None
    # The front door's checks (distance tables for all goals, ~1 s) count against the
    # limit; generous bound: the limit, one distance batch or one PIBT step, the load.
    assert elapsed < 10 * 0.1 + 0.5
