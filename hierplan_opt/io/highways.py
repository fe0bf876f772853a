"""Highway files in the three formats in use, for a given map.

* ``hierplan`` (``.yaml``/``.yml``): the project's YAML, a list of directed edges
  and/or per-cell directions::

      highways:                # directed edges [from, to] in map coordinates
        - [[0, 0], [1, 0]]
      directions:              # or: one string per row (y = 0 first), one character
        - "rrrd"               # per cell, the characters of the grid format below
        - "u..d"

* ``grid`` (``.highway``, Kei18/pibt's iECBS, kept beside ``NAME.map`` as
  ``NAME.map.highway``): one line per map row, one character per cell: ``r l u d``
  a one-way edge leaving the cell east, west, north (row - 1) or south (row + 1);
  the crossings ``x`` (r+d), ``y`` (l+d), ``z`` (r+u), ``w`` (l+u); ``.`` (or a
  MovingAI obstacle letter) none.

* ``edges`` (``.hwy``, hangma-usc/ECBS_Replan): a header ``p edges NV NE`` (NV the
  number of distinct end vertices, NE the number of edges) and NE lines ``e FROM TO``
  with vertex ids ``row * width + column`` of the map (ECBS_Replan's maps carry their
  padding border inside the map, so ids refer to the map as written).

Every reader refuses bad highways (an edge off the graph, an unknown character, a
grid of the wrong size, a malformed line) with one line naming file and line.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from hierplan_opt.core.errors import InputError
from hierplan_opt.core.graph import Graph
from hierplan_opt.core.highways import (
    Highways,
    cell_char,
    cell_directions,
    char_dirs,
    check_highways,
    edge_from_cell,
    is_2d_grid,
)
from hierplan_opt.io.yaml import Ctx, read_text, read_yaml
from hierplan_opt.io.yaml_format import _highways as parse_highway_edges

FORMATS = ("hierplan", "grid", "edges")
_SUFFIX = {".yaml": "hierplan", ".yml": "hierplan", ".highway": "grid", ".hwy": "edges"}


def guess_format(path: str | Path, text: str) -> str:
    """The format of a highway file, from its suffix, else from its first line.

    Example
    -------
    >>> guess_format("a.hwy", ""), guess_format("x", "p edges 2 1\\n"), guess_format("x", "r.\\n")
    ('edges', 'edges', 'grid')
    """
    fmt = _SUFFIX.get(Path(path).suffix.lower())
    if fmt:
        return fmt
    first = next((ln.strip() for ln in text.splitlines() if ln.strip()), "")
    if first.startswith("p "):
        return "edges"
    if ":" in first or first.startswith("#"):
        return "hierplan"
    return "grid"


def load_highways(path: str | Path, graph: Graph, format: str | None = None) -> Highways:
    """Read a highway file for ``graph`` (format from the suffix or the content).

    Example
    -------
    >>> import os, tempfile
    >>> g = Graph.grid(3, 2)
    >>> f = os.path.join(tempfile.mkdtemp(), "h.hwy")
    >>> _ = open(f, "w").write("p edges 3 2\\ne 0 1\\ne 1 2\\n")
    >>> sorted(load_highways(f, g))
    [(0, 1), (1, 2)]
    """
    text = read_text(path)
    fmt = format or guess_format(path, text)
    if fmt == "hierplan":
        return parse_yaml(path, graph, text)
    if fmt == "grid":
        return parse_grid(text, graph, str(path))
    if fmt == "edges":
        return parse_edges(text, graph, str(path))
    raise InputError(f"unknown highway format {fmt!r} (use {', '.join(FORMATS)})")


def save_highways(
    path: str | Path, graph: Graph, highways: Highways, format: str | None = None
) -> None:
    """Write ``highways`` (format from ``format`` or the suffix; default hierplan YAML).

    The text is built (and checked) before the file is opened.
    """
    fmt = format or _SUFFIX.get(Path(path).suffix.lower(), "hierplan")
    if fmt == "hierplan":
        text = yaml_text(graph, highways)
    elif fmt == "grid":
        text = grid_text(graph, highways)
    elif fmt == "edges":
        text = edges_text(graph, highways)
    else:
        raise InputError(f"unknown highway format {fmt!r} (use {', '.join(FORMATS)})")
    Path(path).write_text(text, encoding="utf-8")


# ---------------------------------------------------------------- the grid format
def parse_grid(text: str, graph: Graph, name: str = "<highways>", first_line: int = 1) -> Highways:
    """Highways from iECBS character rows (one line per map row).

    Example
    -------
    >>> g = Graph.grid(3, 2)
    >>> sorted(parse_grid("rrd\\n..l\\n", g))
    [(0, 1), (1, 2), (2, 5), (5, 4)]
    >>> parse_grid("r?d\\n...\\n", g, "h.highway")
    Traceback (most recent call last):
    ...
    hierplan_opt.core.errors.InputError: h.highway:1: unknown highway character '?' in column 1 ...
    """
    rows = text.splitlines()
    return _parse_rows(rows, graph, Ctx(name), list(range(first_line, first_line + len(rows))))


def _parse_rows(rows: list[str], graph: Graph, ctx: Ctx, lines: list[int]) -> Highways:
    if not is_2d_grid(graph):
        raise ctx.error("per-cell highway directions need a 2D grid map")
    assert graph.shape is not None
    width, height = graph.shape
    # trailing empty lines are allowed; anything else must be a full row
    while rows and not rows[-1].strip():
        rows = rows[:-1]
    if len(rows) != height:
        raise ctx.error(f"the highway grid has {len(rows)} rows, the map has {height}")
    out: set[tuple[int, int]] = set()
    for y, (row, line) in enumerate(zip(rows, lines, strict=False)):
        row = row.rstrip("\r")
        if len(row) != width:
            raise ctx.error(f"row {y} has {len(row)} cells, the map is {width} wide", line)
        for x, ch in enumerate(row):
            dirs = char_dirs(ch)
            if dirs is None:
                raise ctx.error(
                    f"unknown highway character {ch!r} in column {x} "
                    "(use r l u d x y z w, or . for none)",
                    line,
                )
            for d in dirs:
                e = edge_from_cell(graph, x, y, d)
                if e is None:
                    raise ctx.error(
                        f"highway {ch!r} at [{x}, {y}] leads off the graph (direction {d})", line
                    )
                out.add(e)
    return frozenset(out)


def grid_text(graph: Graph, highways: Highways) -> str:
    """The iECBS character rows of ``highways`` (blocked cells as ``@``).

    Example
    -------
    >>> print(grid_text(Graph.grid(3, 2, obstacles=[(0, 1)]), {(0, 1), (1, 4), (1, 2)}), end="")
    rx.
    @..
    """
    if not is_2d_grid(graph):
        raise InputError("the highway grid format needs a 2D grid map")
    assert graph.shape is not None
    width, height = graph.shape
    dirs = cell_directions(graph, highways)
    rows: list[str] = []
    for y in range(height):
        row = []
        for x in range(width):
            v = graph.vertex((x, y))
            if not graph.passable[v]:
                row.append("@")
                continue
            ch = cell_char(dirs.get(v, ""))
            if ch is None:
                raise InputError(
                    f"cell [{x}, {y}] has highway directions {dirs[v]!r}, "
                    "which the grid format cannot write (at most two, not opposite)"
                )
            row.append(ch)
        rows.append("".join(row))
    return "\n".join(rows) + "\n"


# ---------------------------------------------------------------- the edge list format
def parse_edges(text: str, graph: Graph, name: str = "<highways>") -> Highways:
    """Highways from an ECBS_Replan edge list (``p edges NV NE`` then ``e FROM TO``).

    Example
    -------
    >>> g = Graph.grid(3, 1)
    >>> parse_edges("p edges 2 1\\ne 0 2\\n", g, "h.hwy")
    Traceback (most recent call last):
    ...
    hierplan_opt.core.errors.InputError: h.hwy:2: highway [0, 0] -> [2, 0] is not an edge ...
    """
    ctx = Ctx(name)
    lines = [(i + 1, ln.split()) for i, ln in enumerate(text.splitlines()) if ln.strip()]
    if not lines or lines[0][1][:2] != ["p", "edges"] or len(lines[0][1]) != 4:
        raise ctx.error("the first line must be 'p edges NV NE'", lines[0][0] if lines else 1)
    head_line, head = lines[0]
    try:
        nv, ne = int(head[2]), int(head[3])
    except ValueError:
        raise ctx.error(f"'p edges NV NE' needs two integers, got {head[2:]}", head_line) from None
    body = lines[1:]
    if len(body) != ne:
        raise ctx.error(f"the header announces {ne} edges, the file has {len(body)}", head_line)
    out: set[tuple[int, int]] = set()
    for line, parts in body:
        if len(parts) != 3 or parts[0] != "e":
            raise ctx.error(f"an edge line must be 'e FROM TO', got {' '.join(parts)!r}", line)
        try:
            u, v = int(parts[1]), int(parts[2])
        except ValueError:
            raise ctx.error(f"vertex ids must be integers, got {parts[1:]}", line) from None
        try:
            out |= check_highways(graph, [(u, v)])
        except InputError as exc:
            raise ctx.error(str(exc), line) from None
    ends = {u for u, _ in out} | {v for _, v in out}
    if nv != len(ends):
        raise ctx.error(
            f"the header announces {nv} vertices, the edges have {len(ends)}", head_line
        )
    return frozenset(out)


def edges_text(graph: Graph, highways: Highways) -> str:
    """The ECBS_Replan edge list of ``highways`` (sorted).

    Example
    -------
    >>> print(edges_text(Graph.grid(3, 1), {(1, 2), (0, 1)}), end="")
    p edges 3 2
    e 0 1
    e 1 2
    """
    hw = sorted(check_highways(graph, highways))
    ends = {u for u, _ in hw} | {v for _, v in hw}
    return "".join([f"p edges {len(ends)} {len(hw)}\n"] + [f"e {u} {v}\n" for u, v in hw])


# ---------------------------------------------------------------- the project's YAML
def parse_yaml(path: str | Path, graph: Graph, text: str | None = None) -> Highways:
    """Highways from the project's YAML (``highways:`` edges and/or ``directions:`` rows)."""

    ctx = Ctx(path)
    data: Any = read_yaml(path, text)
    top = ctx.mapping(data, "the highway file", 1)
    ctx.check_keys(top, "the highway file", ("format", "highways", "directions"))
    if "highways" not in top and "directions" not in top:
        raise ctx.error("a highway file needs 'highways:' (edges) or 'directions:' (rows)", 1)
    out: set[tuple[int, int]] = set()
    if top.get("highways") is not None:
        out |= parse_highway_edges(ctx, graph, top["highways"], ctx.line_of(top, "highways"))
    if top.get("directions") is not None:
        rows = ctx.sequence(top["directions"], "directions", ctx.line_of(top, "directions"))
        texts = [
            ctx.string(r, "a row of directions", ctx.line_of(rows, i)) for i, r in enumerate(rows)
        ]
        lines = [ctx.line_of(rows, i) or 0 for i in range(len(rows))]
        out |= _parse_rows(texts, graph, ctx, lines)
    return frozenset(out)


def yaml_text(graph: Graph, highways: Highways, *, directions: bool = False) -> str:
    """The project's YAML: a ``highways:`` edge list, or ``directions:`` rows.

    Example
    -------
    >>> print(yaml_text(Graph.grid(2, 1), {(0, 1)}), end="")
    format: hierplan/1
    highways:
      - [[0, 0], [1, 0]]
    """
    out = ["format: hierplan/1"]
    if directions:
        out.append("directions:")
        out += [f'  - "{row}"' for row in grid_text(graph, highways).splitlines()]
    else:
        hw = sorted(check_highways(graph, highways))
        out.append("highways:" if hw else "highways: []")
        out += [f"  - [{graph.label(u)}, {graph.label(v)}]" for u, v in hw]
    return "\n".join(out) + "\n"


__all__ = [
    "FORMATS",
    "edges_text",
    "grid_text",
    "guess_format",
    "load_highways",
    "parse_edges",
    "parse_grid",
    "parse_yaml",
    "save_highways",
    "yaml_text",
]
