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
    from scipy import ndimage

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
    from hierplan_opt.bench.teams import warehouse_grid, warehouse_tapf

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
