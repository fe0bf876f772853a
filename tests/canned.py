"""The canned cross-check suite: small instances every exact solver must agree on.

Each :class:`Case` builds its instance programmatically (or loads a MovingAI sample) and
lists the objectives that apply. ``golden`` holds optima worked out by hand for the tiny
cases; for the others the agreement of independent exact solvers is the check.
``FAST`` is the deterministic sample run in every CI run; ``CASES`` is the full suite
(``pytest -m slow``).
"""

from __future__ import annotations

import random
from collections.abc import Callable
from dataclasses import dataclass, field
from functools import cache
from pathlib import Path

from hierplan_opt.core.graph import Graph
from hierplan_opt.core.instance import Instance

MOVINGAI = Path(__file__).resolve().parent.parent / "instances" / "movingai"


@dataclass(frozen=True)
class Case:
    """One canned instance: a name, a builder, its objectives and any golden optima."""

    name: str
    build: Callable[[], Instance]
    objectives: tuple[str, ...] = ("soc", "makespan")
    golden: dict[str, int] = field(default_factory=dict)
    fast: bool = True

    def instance(self) -> Instance:
        return _cached(self.name)

    @property
    def kind(self) -> str:
        return "tapf" if self.instance().is_tapf else "mapf"


# --------------------------------------------------------------------------- builders
def corridor_lmrp() -> Instance:
    """libMultiRobotPlanning's corridor: agent1 steps into the pocket to let agent0 by."""
    g = Graph.grid(5, 2, obstacles=[(0, 1), (1, 1), (3, 1), (4, 1)])
    return Instance.mapf(g, [(0, 0), (1, 0)], [(4, 0), (3, 0)], name="corridor_lmrp")


def single_agent() -> Instance:
    return Instance.mapf(Graph.grid(4, 4), [(0, 0)], [(3, 3)], name="single_agent")


def at_goals() -> Instance:
    return Instance.mapf(Graph.grid(3, 3), [(0, 0), (2, 2)], [(0, 0), (2, 2)], name="at_goals")


def follow_chain() -> Instance:
    """Three robots in a 1-wide corridor each move one cell right (following is allowed)."""
    g = Graph.grid(4, 1)
    return Instance.mapf(g, [(0, 0), (1, 0), (2, 0)], [(1, 0), (2, 0), (3, 0)], name="follow")


def cross() -> Instance:
    """Two robots whose only shortest paths meet in the centre of a 3x3 grid."""
    g = Graph.grid(3, 3)
    return Instance.mapf(g, [(0, 1), (1, 0)], [(2, 1), (1, 2)], name="cross")


def swap_pocket(length: int, pocket: int) -> Callable[[], Instance]:
    """Two robots swap ends of a corridor with one side pocket."""

    def make() -> Instance:
        obstacles = [(x, 1) for x in range(length) if x != pocket]
        g = Graph.grid(length, 2, obstacles=obstacles)
        return Instance.mapf(
            g, [(0, 0), (length - 1, 0)], [(length - 1, 0), (0, 0)], name=f"swap{length}"
        )

    return make


def swap_three() -> Instance:
    """Three robots reverse their order in a corridor with two pockets."""
    obstacles = [(x, 1) for x in range(7) if x not in (2, 4)]
    g = Graph.grid(7, 2, obstacles=obstacles)
    return Instance.mapf(g, [(0, 0), (1, 0), (6, 0)], [(6, 0), (5, 0), (0, 0)], name="swap_three")


def corridor_same_way(k: int) -> Callable[[], Instance]:
    def make() -> Instance:
        g = Graph.grid(k + 3, 1)
        return Instance.mapf(
            g, [(i, 0) for i in range(k)], [(i + 3, 0) for i in range(k)], name=f"train{k}"
        )

    return make


def room(seed: int, agents: int, size: int = 9) -> Callable[[], Instance]:
    """Four rooms joined by one-cell doors, robots placed at random (seeded)."""

    def make() -> Instance:
        mid = size // 2
        walls = {(mid, y) for y in range(size)} | {(x, mid) for x in range(size)}
        doors = {
            (mid, mid // 2),
            (mid, mid + 1 + mid // 2),
            (mid // 2, mid),
            (mid + 1 + mid // 2, mid),
        }
        obstacles = sorted(walls - doors)
        g = Graph.grid(size, size, obstacles=obstacles)
        return _random_agents(g, agents, seed, f"room{size}_s{seed}_k{agents}")

    return make


def random_grid(w: int, h: int, density: float, agents: int, seed: int) -> Callable[[], Instance]:
    def make() -> Instance:
        rng = random.Random(seed)
        cells = [(x, y) for x in range(w) for y in range(h)]
        obstacles = [c for c in cells if rng.random() < density]
        g = Graph.grid(w, h, obstacles=obstacles)
        return _random_agents(g, agents, seed, f"random{w}x{h}_s{seed}_k{agents}")

    return make


def _random_agents(g: Graph, k: int, seed: int, name: str) -> Instance:
    """``k`` robots with distinct starts and goals in the largest connected component."""
    rng = random.Random(seed * 7919 + k)
    comp = _largest_component(g)
    picks = rng.sample(comp, 2 * k)
    starts = [g.location(v) for v in picks[:k]]
    goals = [g.location(v) for v in picks[k:]]
    return Instance.mapf(g, starts, goals, name=name)


def _largest_component(g: Graph) -> list[int]:
    seen: set[int] = set()
    best: list[int] = []
    for s in range(g.n):
        if not g.passable[s] or s in seen:
            continue
        comp = [s]
        seen.add(s)
        i = 0
        while i < len(comp):
            for u in g.adj[comp[i]]:
                if u not in seen:
                    seen.add(u)
                    comp.append(u)
            i += 1
        if len(comp) > len(best):
            best = comp
    return sorted(best)


def movingai(map_name: str, scen: str, k: int) -> Callable[[], Instance]:
    def make() -> Instance:
        from hierplan_opt.io.movingai import load_map, load_scen

        g = load_map(MOVINGAI / f"{map_name}.map")
        return load_scen(MOVINGAI / scen, g, agents=k)

    return make


def tapf_corners() -> Instance:
    """One team of two swaps diagonal corners' roles: any robot may take any target."""
    return Instance.tapf(Graph.grid(3, 3), [([(0, 0), (2, 2)], [(0, 2), (2, 0)])], name="corners")


def tapf_corridor() -> Instance:
    """Anonymous robots in a corridor: the team need not pass each other."""
    g = Graph.grid(6, 1)
    return Instance.tapf(g, [([(0, 0), (1, 0)], [(4, 0), (5, 0)])], name="tapf_corridor")


def tapf_paper_like() -> Instance:
    """A small two-team instance in the spirit of the overview's Fig. 3."""
    g = Graph.grid(5, 3, obstacles=[(1, 1), (3, 1)])
    return Instance.tapf(
        g,
        [([(0, 0)], [(4, 2)]), ([(4, 0), (0, 2)], [(2, 0), (2, 2)])],
        name="paper_like",
    )


def tapf_random(w: int, h: int, teams: list[int], seed: int, density: float = 0.1):
    def make() -> Instance:
        rng = random.Random(seed)
        cells = [(x, y) for x in range(w) for y in range(h)]
        obstacles = [c for c in cells if rng.random() < density]
        g = Graph.grid(w, h, obstacles=obstacles)
        comp = _largest_component(g)
        picks = rng.sample(comp, 2 * sum(teams))
        spec = []
        i = 0
        for n in teams:
            starts = [g.location(v) for v in picks[i : i + n]]
            targets = [g.location(v) for v in picks[i + n : i + 2 * n]]
            spec.append((starts, targets))
            i += 2 * n
        return Instance.tapf(g, spec, name=f"tapf{w}x{h}_s{seed}_{'-'.join(map(str, teams))}")

    return make


def tapf_from_scen(map_name: str, scen: str, teams: list[int]) -> Callable[[], Instance]:
    """Teams made of consecutive scenario agents: their goals become the team's targets."""

    def make() -> Instance:
        from hierplan_opt.io.movingai import load_map, load_scen

        g = load_map(MOVINGAI / f"{map_name}.map")
        inst = load_scen(MOVINGAI / scen, g, agents=sum(teams))
        spec = []
        i = 0
        for n in teams:
            agents = inst.agents[i : i + n]
            spec.append(
                ([g.location(a.start) for a in agents], [g.location(a.goal) for a in agents])  # type: ignore[arg-type]
            )
            i += n
        return Instance.tapf(g, spec, name=f"{map_name}_teams_{'-'.join(map(str, teams))}")

    return make


# --------------------------------------------------------------------------- the suite
MAPF = ("soc", "makespan")
TAPF = ("makespan", "soc")

CASES: list[Case] = [
    # tiny golden cases (optima worked out by hand)
    Case("corridor_lmrp", corridor_lmrp, MAPF, {"soc": 8, "makespan": 4}),
    Case("single_agent", single_agent, MAPF, {"soc": 6, "makespan": 6}),
    Case("at_goals", at_goals, MAPF, {"soc": 0, "makespan": 0}),
    Case("follow_chain", follow_chain, MAPF, {"soc": 3, "makespan": 1}),
    Case("cross", cross, MAPF, {"soc": 5, "makespan": 3}),
    # corridors and swaps with side pockets
    Case("swap5_pocket2", swap_pocket(5, 2), MAPF),
    Case("swap6_pocket1", swap_pocket(6, 1), MAPF),
    Case("swap7_pocket3", swap_pocket(7, 3), MAPF, fast=False),
    Case("swap_three", swap_three, MAPF, fast=False),
    Case("train3", corridor_same_way(3), MAPF, {"soc": 9, "makespan": 3}),
    Case("train5", corridor_same_way(5), MAPF, {"soc": 15, "makespan": 3}, fast=False),
    # rooms
    Case("room9_s1_k3", room(1, 3), MAPF),
    Case("room9_s2_k4", room(2, 4), MAPF),
    Case("room9_s3_k5", room(3, 5), MAPF, fast=False),
    Case("room11_s4_k4", room(4, 4, 11), MAPF, fast=False),
    Case("room11_s5_k6", room(5, 6, 11), MAPF, fast=False),
    # random small grids
    Case("random6x6_s1_k3", random_grid(6, 6, 0.15, 3, 1), MAPF),
    Case("random6x6_s2_k4", random_grid(6, 6, 0.15, 4, 2), MAPF, fast=False),
    Case("random8x8_s3_k4", random_grid(8, 8, 0.2, 4, 3), MAPF),
    Case("random8x8_s4_k6", random_grid(8, 8, 0.2, 6, 4), MAPF, fast=False),
    Case("random8x8_s5_k8", random_grid(8, 8, 0.1, 8, 5), MAPF, fast=False),
    Case("random10x10_s6_k6", random_grid(10, 10, 0.2, 6, 6), MAPF, fast=False),
    Case("random10x10_s7_k8", random_grid(10, 10, 0.15, 8, 7), MAPF, fast=False),
    Case("random5x5_s8_k5", random_grid(5, 5, 0.0, 5, 8), MAPF),
    Case("random4x4_s9_k6", random_grid(4, 4, 0.0, 6, 9), MAPF, fast=False),
    # the first agents of the MovingAI samples
    Case("empty-8-8_k4", movingai("empty-8-8", "empty-8-8-even-1.scen", 4), MAPF),
    Case("empty-8-8_k8", movingai("empty-8-8", "empty-8-8-even-1.scen", 8), MAPF, fast=False),
    Case("empty-16-16_k6", movingai("empty-16-16", "empty-16-16-even-1.scen", 6), MAPF, fast=False),
    Case(
        "random-32-32-10_k4",
        movingai("random-32-32-10", "random-32-32-10-even-1.scen", 4),
        MAPF,
        fast=False,
    ),
    Case(
        "random-32-32-20_k3",
        movingai("random-32-32-20", "random-32-32-20-random-1.scen", 3),
        ("soc",),
    ),
    Case(
        "random-32-32-20_k6",
        movingai("random-32-32-20", "random-32-32-20-random-1.scen", 6),
        MAPF,
        fast=False,
    ),
    Case(
        "room-32-32-4_k3", movingai("room-32-32-4", "room-32-32-4-even-1.scen", 3), MAPF, fast=False
    ),
    Case(
        "maze-32-32-2_k2", movingai("maze-32-32-2", "maze-32-32-2-even-1.scen", 2), MAPF, fast=False
    ),
    Case(
        "warehouse_k3",
        movingai("warehouse-10-20-10-2-1", "warehouse-10-20-10-2-1-even-1.scen", 3),
        ("soc",),
        fast=False,
    ),
    # TAPF
    Case("tapf_corners", tapf_corners, TAPF, {"makespan": 2, "soc": 4}),
    Case("tapf_corridor", tapf_corridor, TAPF, {"makespan": 4, "soc": 8}),
    Case("tapf_paper_like", tapf_paper_like, TAPF),
    Case("tapf6x6_one_team", tapf_random(6, 6, [4], 11), TAPF),
    Case("tapf8x8_two_teams", tapf_random(8, 8, [2, 3], 12), TAPF),
    Case("tapf8x8_three_teams", tapf_random(8, 8, [2, 2, 2], 13), TAPF, fast=False),
    Case("tapf10x10_one_team", tapf_random(10, 10, [6], 14, 0.15), TAPF, fast=False),
    Case(
        "tapf_empty-8-8_teams",
        tapf_from_scen("empty-8-8", "empty-8-8-even-1.scen", [3, 3]),
        TAPF,
        fast=False,
    ),
    Case(
        "tapf_empty-16-16_team",
        tapf_from_scen("empty-16-16", "empty-16-16-even-1.scen", [5]),
        ("makespan",),
        fast=False,
    ),
]

BY_NAME = {c.name: c for c in CASES}
FAST = [c for c in CASES if c.fast]


@cache
def _cached(name: str) -> Instance:
    return BY_NAME[name].build()
