"""Instance generators a sweep can name: ``{generator: NAME, params: {...}}``.

Each generator builds an instance from its parameters, the number of agents K and the
run's seed, so a sweep over seeds is a sweep over random instances. Parameters are
checked when the spec is read (unknown or bad ones are one-line errors).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from hierplan_opt.core.errors import InputError
from hierplan_opt.core.graph import Graph
from hierplan_opt.core.instance import Instance


def warehouse_grid(shelf_rows: int, shelf_cols: int, shelf_len: int = 5, aisle: int = 3) -> Graph:
    """A warehouse-like grid: ``shelf_rows x shelf_cols`` shelf blocks (2 x shelf_len).

    Blocks are separated by one-cell passageways; ``aisle`` free columns on the left
    and right and one free row above and below.

    Example
    -------
    >>> g = warehouse_grid(2, 2, shelf_len=3, aisle=2)
    >>> g.shape, g.num_vertices
    ((11, 7), 53)
    """
    w = 2 * aisle + shelf_cols * shelf_len + (shelf_cols - 1)
    h = 2 + shelf_rows * 2 + (shelf_rows - 1)
    blocked = np.zeros((h, w), dtype=bool)
    for r in range(shelf_rows):
        y = 1 + 3 * r
        for c in range(shelf_cols):
            x = aisle + c * (shelf_len + 1)
            blocked[y : y + 2, x : x + shelf_len] = True
    return Graph.grid(w, h, blocked=blocked)


def warehouse_tapf(
    graph: Graph, teams: int, size: int, seed: int, starts_at: str = "sides"
) -> Instance:
    """Targets are cells next to shelves; robots start in the side aisles (``"sides"``)
    or on random free cells away from the targets (``"random"``).

    Example
    -------
    >>> inst = warehouse_tapf(warehouse_grid(2, 2, 3, 2), 2, 2, seed=0)
    >>> len(inst.teams), inst.num_agents
    (2, 4)
    """
    rng = np.random.default_rng(seed)
    w, h = graph.shape  # type: ignore[misc]
    k = teams * size
    free = np.flatnonzero(graph.passable)
    xs = graph.coords[free, 0]
    side = free[(xs < 3) | (xs >= w - 3)]
    near_shelf = [
        v
        for v in free.tolist()
        if any(not graph.passable[u] for u in _grid_nbrs(graph, v))
        and 3 <= graph.coords[v, 0] < w - 3
    ]
    if len(near_shelf) < k:
        raise ValueError(f"the grid is too small for {k} robots")
    targets = rng.choice(np.array(near_shelf), k, replace=False).tolist()
    pool = side if starts_at == "sides" else np.setdiff1d(free, targets)
    if len(pool) < k:
        raise ValueError(f"the grid has fewer than {k} start cells ({starts_at})")
    starts = rng.choice(pool, k, replace=False).tolist()
    spec = [
        (
            [graph.location(v) for v in starts[i * size : (i + 1) * size]],
            [graph.location(v) for v in targets[i * size : (i + 1) * size]],
        )
        for i in range(teams)
    ]
    return Instance.tapf(graph, spec, name=f"warehouse-{teams}x{size}-s{seed}")


def _grid_nbrs(graph: Graph, v: int) -> list[int]:
    x, y = (int(c) for c in graph.coords[v][:2])
    w, h = graph.shape[:2]  # type: ignore[index]
    out = []
    for dx, dy in ((1, 0), (-1, 0), (0, 1), (0, -1)):
        if 0 <= x + dx < w and 0 <= y + dy < h:
            out.append(graph.vertex((x + dx, y + dy)))
    return out


@dataclass(frozen=True)
class Generator:
    """A named instance generator: its parameters (name -> (type, default)) and builder."""

    name: str
    params: dict[str, tuple[type, Any]]
    build: Callable[..., Instance]
    help: str = ""
    problem: str = "mapf"  # what it generates: "mapf" or "tapf"

    def check(self, given: dict[str, Any]) -> None:
        """Refuse unknown parameters and values of the wrong type."""
        for key, value in given.items():
            if key not in self.params:
                raise InputError(
                    f"generator {self.name!r} has no parameter {key!r} "
                    f"(its parameters: {', '.join(self.params)})"
                )
            kind = self.params[key][0]
            ok = isinstance(value, kind) and not isinstance(value, bool)
            if kind is float:
                ok = isinstance(value, (int, float)) and not isinstance(value, bool)
            if kind is bool or kind is str:
                ok = isinstance(value, kind)
            if not ok:
                raise InputError(f"parameter {key!r} must be a {kind.__name__}, got {value!r}")

    def __call__(self, params: dict[str, Any], agents: int, seed: int) -> Instance:
        """Build the instance with ``agents`` agents from ``seed``."""
        self.check(params)
        full = {k: v for k, (_, v) in self.params.items()}
        full.update(params)
        return self.build(agents=agents, seed=seed, **full)


def random_grid(*, width: int, height: int, obstacles: float, agents: int, seed: int) -> Instance:
    """A ``width x height`` grid with a fraction ``obstacles`` of blocked cells and
    random distinct starts and goals in its largest 4-connected free region.

    Example
    -------
    >>> inst = random_grid(width=8, height=8, obstacles=0.2, agents=5, seed=1)
    >>> inst.num_agents, inst.graph.num_vertices <= 64
    (5, True)
    """
    from scipy import ndimage  # heavy module: scipy

    if not 0 <= obstacles < 1:
        raise InputError(f"obstacles must be a fraction in [0, 1), got {obstacles!r}")
    if width < 1 or height < 1:
        raise InputError(f"width and height must be positive, got {width}x{height}")
    rng = np.random.default_rng(seed)
    blocked = rng.random((height, width)) < obstacles
    labelled: Any = ndimage.label(~blocked)  # (labels, number of regions)
    labels, count = labelled
    if count == 0:
        raise InputError("the generated grid has no free cell")
    sizes = np.bincount(labels.ravel())[1:]
    keep = labels == 1 + int(np.argmax(sizes))
    cells = np.argwhere(keep)  # (row, col)
    if len(cells) < agents:
        raise InputError(
            f"random_grid {width}x{height} with obstacles {obstacles} has {len(cells)} "
            f"connected free cells, fewer than {agents} agents"
        )
    graph = Graph.grid(width, height, blocked=~keep)
    pick = lambda: [(int(c), int(r)) for r, c in cells[rng.permutation(len(cells))[:agents]]]  # noqa: E731
    starts, goals = pick(), pick()
    name = f"random-grid-{width}x{height}-{obstacles:g}-s{seed}"
    return Instance.mapf(graph, starts, goals, name=name)


def warehouse(
    *,
    shelf_rows: int,
    shelf_cols: int,
    shelf_len: int,
    aisle: int,
    team_size: int,
    starts: str,
    agents: int,
    seed: int,
) -> Instance:
    """The ``hierplan bench teams`` warehouse: TAPF with ``agents / team_size`` teams,
    targets next to shelves, robots starting in the side aisles (or at random).

    Example
    -------
    >>> inst = warehouse(shelf_rows=2, shelf_cols=2, shelf_len=3, aisle=2, team_size=2,
    ...                  starts="sides", agents=4, seed=0)
    >>> len(inst.teams), inst.num_agents
    (2, 4)
    """
    if agents % team_size:
        raise InputError(f"{agents} agents do not split into teams of {team_size}")
    if starts not in ("sides", "random"):
        raise InputError(f"starts must be 'sides' or 'random', got {starts!r}")
    graph = warehouse_grid(shelf_rows, shelf_cols, shelf_len, aisle)
    try:
        return warehouse_tapf(graph, agents // team_size, team_size, seed, starts_at=starts)
    except ValueError as exc:
        raise InputError(str(exc)) from None


GENERATORS: dict[str, Generator] = {
    g.name: g
    for g in (
        Generator(
            "random_grid",
            {"width": (int, 32), "height": (int, 32), "obstacles": (float, 0.0)},
            random_grid,
            "random obstacles, random starts and goals (MAPF)",
        ),
        Generator(
            "warehouse",
            {
                "shelf_rows": (int, 2),
                "shelf_cols": (int, 3),
                "shelf_len": (int, 5),
                "aisle": (int, 3),
                "team_size": (int, 1),
                "starts": (str, "sides"),
            },
            warehouse,
            "shelf blocks and aisles, teams of robots with targets by the shelves (TAPF)",
            problem="tapf",
        ),
    )
}
