"""Highways: a set of directed edges the planners are encouraged (not forced) to use.

A highway set is a ``frozenset`` of ``(u, v)`` vertex-id pairs, each an edge of the
graph (the type of :attr:`Instance.highways <hierplan_opt.core.instance.Instance>`).
This module holds what only needs the graph: the check, the per-cell directions of
4-connected 2D grids (the character grid of Kei18/pibt's iECBS), the two generators
``crisscross`` and ``corridors``, and the share of a plan's moves on highway edges.
The learned generators and the generators by name are in
:mod:`hierplan_opt.core.highways_learned`, the file formats in
:mod:`hierplan_opt.io.highways`, the highway heuristic and low level of the solvers in
:mod:`hierplan_opt.search.highways`.
"""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np

from hierplan_opt.core.errors import InputError
from hierplan_opt.core.graph import Graph
from hierplan_opt.core.options import Option
from hierplan_opt.core.plan import Plan

Highways = frozenset[tuple[int, int]]

#: Values of the ``highways`` option: the instance's own set or a generator.
GENERATORS = ("instance", "crisscross", "corridors", "learned", "flow")
MODES = ("heuristic", "cost")

HIGHWAYS_OPTION = Option(
    "highways",
    "choice",
    "prefer these directed edges: the instance's own, or generated",
    choices=GENERATORS,
    optional=True,
)
W_HWY_OPTION = Option(
    "w_hwy", "float", "highway factor: off-highway edges cost this much more", low=1.0, high=1e9
)
MODE_OPTION = Option(
    "hwy_mode", "choice", "inflate the heuristic or the edge costs off the highways", choices=MODES
)
#: The options every solver with highway support declares (in this order).
HIGHWAY_OPTIONS = (HIGHWAYS_OPTION, W_HWY_OPTION, MODE_OPTION)

#: One-way directions of a grid cell: (dx, dy) with y growing downwards (file rows).
STEPS = {"r": (1, 0), "l": (-1, 0), "u": (0, -1), "d": (0, 1)}
#: The iECBS crossing characters: two out-directions in one cell.
CROSSINGS = {"x": "rd", "y": "ld", "z": "ru", "w": "lu"}
#: Characters of a cell without highway edges (MovingAI obstacle letters included).
NONE_CHARS = frozenset(".@OTWGS")


def check_highways(graph: Graph, edges: Iterable[tuple[int, int]]) -> Highways:
    """``edges`` as a highway set, or :class:`InputError` naming the first non-edge.

    Example
    -------
    >>> g = Graph.grid(3, 1)
    >>> sorted(check_highways(g, [(0, 1), (1, 2)]))
    [(0, 1), (1, 2)]
    >>> check_highways(g, [(0, 2)])
    Traceback (most recent call last):
    ...
    hierplan_opt.core.errors.InputError: highway [0, 0] -> [2, 0] is not an edge of the graph
    """
    out: set[tuple[int, int]] = set()
    for u, v in edges:
        u, v = int(u), int(v)
        if not (0 <= u < graph.n and 0 <= v < graph.n and graph.has_edge(u, v)):
            raise InputError(
                f"highway {_label(graph, u)} -> {_label(graph, v)} is not an edge of the graph"
            )
        out.add((u, v))
    return frozenset(out)


def _label(graph: Graph, v: int) -> str:
    return graph.label(v) if 0 <= v < graph.n else f"vertex id {v}"


def is_2d_grid(graph: Graph) -> bool:
    """Whether ``graph`` is a 4-connected 2D grid (the only kind with cell directions)."""
    return graph.kind == "grid" and graph.shape is not None and len(graph.shape) == 2


def _need_grid(graph: Graph, what: str) -> tuple[int, int]:
    if not is_2d_grid(graph):
        raise InputError(f"{what} needs a 2D grid map, not {graph!r}")
    assert graph.shape is not None
    return graph.shape[0], graph.shape[1]


def cell_char(dirs: str) -> str | None:
    """The iECBS character of a cell with out-directions ``dirs`` (None: not writable).

    Example
    -------
    >>> cell_char(""), cell_char("d"), cell_char("dr"), cell_char("lr")
    ('.', 'd', 'x', None)
    """
    key = "".join(sorted(dirs))
    if not key:
        return "."
    if len(key) == 1:
        return key
    for ch, pair in CROSSINGS.items():
        if "".join(sorted(pair)) == key:
            return ch
    return None


def char_dirs(ch: str) -> str | None:
    """The out-directions of an iECBS character (None: not a highway character).

    Example
    -------
    >>> char_dirs("r"), char_dirs("w"), char_dirs("."), char_dirs("?")
    ('r', 'lu', '', None)
    """
    if ch in STEPS:
        return ch
    if ch in CROSSINGS:
        return CROSSINGS[ch]
    if ch in NONE_CHARS:
        return ""
    return None


def cell_directions(graph: Graph, highways: Iterable[tuple[int, int]]) -> dict[int, str]:
    """Out-directions (letters of ``r l u d``) of every grid cell with highway edges.

    Example
    -------
    >>> g = Graph.grid(2, 2)
    >>> cell_directions(g, [(0, 1), (0, 2)])
    {0: 'dr'}
    """
    _need_grid(graph, "cell directions")
    out: dict[int, str] = {}
    names = {(dx, dy): k for k, (dx, dy) in STEPS.items()}
    for u, v in highways:
        (x0, y0), (x1, y1) = graph.location(u), graph.location(v)
        d = names[(int(x1) - int(x0), int(y1) - int(y0))]
        out[u] = "".join(sorted(out.get(u, "") + d))
    return dict(sorted(out.items()))


def edge_from_cell(graph: Graph, x: int, y: int, d: str) -> tuple[int, int] | None:
    """The grid edge leaving cell ``(x, y)`` in direction ``d`` (None: off the graph)."""
    width, height = _need_grid(graph, "cell directions")
    dx, dy = STEPS[d]
    x1, y1 = x + dx, y + dy
    if not (0 <= x1 < width and 0 <= y1 < height):
        return None
    u, v = graph.vertex((x, y)), graph.vertex((x1, y1))
    if not (graph.passable[u] and graph.passable[v]):
        return None
    return u, v


# ---------------------------------------------------------------- generators
def crisscross(graph: Graph) -> Highways:
    """Every grid edge one way: rows alternate east/west, columns south/north.

    Row ``y`` runs east when ``y`` is even, west when odd; column ``x`` runs south
    (growing ``y``) when ``x`` is even, north when odd (the CRISSCROSS highway of the
    original ECBS+HWY code, here on the map's own coordinates).

    Example
    -------
    >>> hw = crisscross(Graph.grid(2, 2))
    >>> sorted(hw)  # row 0 east, row 1 west, column 0 south, column 1 north
    [(0, 1), (0, 2), (3, 1), (3, 2)]
    """
    _need_grid(graph, "crisscross highways")
    out: set[tuple[int, int]] = set()
    for u, v in graph.edges():
        x0, y0 = (int(c) for c in graph.coords[u][:2])
        x1, y1 = (int(c) for c in graph.coords[v][:2])
        if y0 == y1:  # horizontal
            east = x1 > x0
            if east == (y0 % 2 == 0):
                out.add((u, v))
        else:
            south = y1 > y0
            if south == (x0 % 2 == 0):
                out.add((u, v))
    return frozenset(out)


def corridors(graph: Graph, max_width: int = 2) -> Highways:
    """One-way lanes along the narrow aisles of a grid map (a warehouse's passageways).

    A cell lies in a horizontal aisle when the free cells above and below it, up to
    the next obstacle or border, make a column run of at most ``max_width`` cells; its
    horizontal edges (also those leaving or entering the aisle) become highway edges.
    Width-1 aisles alternate in the order of their rows (the first runs east) and
    columns (the first runs north), so traffic circles the blocks between them
    clockwise; in a width-2 aisle traffic keeps right (the lower lane runs east, the
    left lane south). Open areas get no highways.

    Example
    -------
    >>> g = Graph.grid(5, 3, obstacles=[(1, 1), (2, 1), (3, 1)])
    >>> dirs = cell_directions(g, corridors(g))  # clockwise around the shelf
    >>> [dirs[g.vertex(c)] for c in [(0, 0), (4, 0), (4, 2), (0, 2)]]
    ['r', 'd', 'l', 'u']
    """
    width, height = _need_grid(graph, "corridor highways")
    free = graph.passable.reshape(height, width)
    proposed: list[tuple[int, int]] = []
    for axis in (0, 1):  # 0: horizontal aisles (runs along y), 1: vertical aisles
        grid = free if axis == 0 else free.T
        lines, across = grid.shape  # lines: positions along the run axis
        run_len = np.zeros_like(grid, dtype=int)
        run_top = np.zeros_like(grid, dtype=int)
        for c in range(across):
            r = 0
            while r < lines:
                if not grid[r, c]:
                    r += 1
                    continue
                s = r
                while r < lines and grid[r, c]:
                    r += 1
                run_len[s:r, c] = r - s
                run_top[s:r, c] = s
        aisle = grid & (run_len <= max_width)
        # Number the width-1 aisle lines in order, so neighbouring aisles alternate.
        single = sorted({int(r) for r in np.nonzero(aisle & (run_len == 1))[0]})
        index = {r: i for i, r in enumerate(single)}
        for r, c in zip(*np.nonzero(aisle), strict=True):
            r, c = int(r), int(c)
            # forward = growing x (east) or growing y (south); y grows downwards
            if run_len[r, c] == 1:  # first row east, first column north: clockwise
                forward = index[r] % 2 == (0 if axis == 0 else 1)
            else:  # width 2: keep right (east on the lower lane, south on the left)
                forward = (r != run_top[r, c]) == (axis == 0)
            for c1, fwd in ((c + 1, True), (c - 1, False)):
                if not 0 <= c1 < across or not grid[r, c1]:
                    continue
                a, b = (c, c1) if fwd == forward else (c1, c)
                cells = [(a, r), (b, r)] if axis == 0 else [(r, a), (r, b)]
                proposed.append((graph.vertex(cells[0]), graph.vertex(cells[1])))
    # An edge between two aisles that disagree (e.g. where a width-1 aisle meets a
    # width-2 one) gets no highway rather than both directions.
    both = set(proposed)
    return frozenset(e for e in both if (e[1], e[0]) not in both)


def reversed_highways(highways: Iterable[tuple[int, int]]) -> Highways:
    """Every highway edge pointing the other way (the worst choice, for tests).

    Example
    -------
    >>> sorted(reversed_highways({(0, 1), (1, 2)}))
    [(1, 0), (2, 1)]
    """
    return frozenset((v, u) for u, v in highways)


# ---------------------------------------------------------------- plan statistics
def highway_share(plan: Plan, highways: Iterable[tuple[int, int]]) -> float:
    """The share of the plan's moves (waits excluded) that follow a highway edge.

    Example
    -------
    >>> highway_share(Plan.from_paths([[0, 1, 2], [3, 3, 4]]), {(0, 1)})
    0.3333333333333333
    """
    hw = set(highways)
    moves = on = 0
    for p in plan.paths:
        for u, v in zip(p, p[1:], strict=False):
            if u != v:
                moves += 1
                on += (u, v) in hw
    return on / moves if moves else 0.0
