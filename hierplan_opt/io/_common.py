"""Checks shared by the instance readers: locations, starts and goals with file lines."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, TypeVar

from hierplan_opt.core.errors import InputError
from hierplan_opt.core.graph import Graph
from hierplan_opt.core.instance import Instance
from hierplan_opt.io.files import check_grid as _check
from hierplan_opt.io.yaml import Ctx

T = TypeVar("T")


def location(
    ctx: Ctx,
    graph: Graph,
    value: Any,
    what: str,
    line: int | None,
    *,
    free: bool = True,
) -> int:
    """The vertex id of a location written in a file (``[x, y(, z)]`` or a vertex name).

    Refuses non-integer coordinates, locations outside the map, unknown vertex names and
    (with ``free``) blocked cells, naming ``what`` and the line.
    """
    if graph.kind == "roadmap":
        if isinstance(value, (list, dict)) or value is None or isinstance(value, bool):
            raise ctx.error(f"{what} must be a vertex name, got {value!r}", line)
        name = str(value)
        try:
            return graph.vertex(name)
        except InputError:
            raise ctx.error(f"{what} {name!r} is not a vertex of the roadmap", line) from None
    assert graph.shape is not None
    dims = len(graph.shape)
    if not isinstance(value, list) or len(value) != dims:
        form = "[x, y]" if dims == 2 else "[x, y, z]"
        raise ctx.error(f"{what} must be {form}, got {value!r}", line)
    coords = [ctx.integer(c, f"{what} coordinate", line) for c in value]
    if any(not 0 <= c < s for c, s in zip(coords, graph.shape, strict=True)):
        size = "x".join(map(str, graph.shape))
        raise ctx.error(f"{what} {coords} is outside the {size} map", line)
    v = graph.vertex(tuple(coords))
    if free and not graph.passable[v]:
        raise ctx.error(f"{what} {coords} is on an obstacle", line)
    return v


class Unique:
    """Refuses a second use of a vertex as a start (or as a goal) with both agent names."""

    def __init__(self, ctx: Ctx, graph: Graph, kind: str) -> None:
        self.ctx, self.graph, self.kind = ctx, graph, kind
        self.seen: dict[int, str] = {}

    def add(self, v: int, who: str, line: int | None) -> None:
        if v in self.seen:
            raise self.ctx.error(
                f"{who} has the same {self.kind} {self.graph.label(v)} as {self.seen[v]}",
                line,
            )
        self.seen[v] = who


def check_grid(ctx: Ctx, dims: list[int], line: int | None) -> None:
    """Refuse a grid too large to allocate (see :func:`hierplan_opt.io.files.check_grid`)."""

    _check(dims, f"{ctx.file}:{line}: " if line else f"{ctx.file}: ")


def grid_2d(instance: Instance, what: str) -> Graph:
    """The instance's graph, refusing anything but a 2D grid for format ``what``."""
    g = instance.graph
    if g.kind != "grid" or g.shape is None or len(g.shape) != 2:
        raise InputError(f"{what} holds plans on 2D grids only")
    return g


def grid_xy(graph: Graph, v: int) -> tuple[int, int]:
    """Column and row ``(x, y)`` of vertex ``v`` of a 2D grid."""
    assert graph.shape is not None
    y, x = divmod(int(v), graph.shape[0])
    return x, y


def grid_cell(ctx: Ctx, graph: Graph, x: int, y: int, what: str, line: int | None) -> int:
    """The vertex id of cell ``(x, y)`` of a 2D grid, refusing cells outside the map.

    Blocked cells are allowed: the validator names them with the timestep.
    """
    assert graph.shape is not None
    width, height = graph.shape
    if not (0 <= x < width and 0 <= y < height):
        raise ctx.error(f"{what} is outside the {width}x{height} map", line)
    return x + width * y


def wrap(ctx: Ctx, line: int | None, fn: Callable[[], T]) -> T:
    """Run ``fn``; an :class:`InputError` it raises gets the ``file:line:`` prefix."""
    try:
        return fn()
    except InputError as exc:
        msg = str(exc)
        if msg.startswith(ctx.file + ":"):
            raise
        raise ctx.error(msg, line) from None
