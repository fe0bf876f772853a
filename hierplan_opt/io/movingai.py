"""MovingAI benchmark files: ``.map`` grids and ``.scen`` scenarios.

A ``.map`` file is::

    type octile
    height H
    width W
    map
    <H rows of W characters>

with ``.`` and ``G`` (and ``S``, swamp) passable and ``@ O T W`` blocked. A ``.scen``
file starts with ``version 1`` and has one agent per line, nine tab-separated fields:
``bucket map width height start_x start_y goal_x goal_y optimal_length``, with
x = column and y = row. :func:`load_scen` takes the first K agents, named
``agent0..agentK-1`` in file order.
"""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np

from hierplan_opt.core.errors import InputError
from hierplan_opt.core.graph import UNREACHABLE, Graph
from hierplan_opt.core.instance import Instance
from hierplan_opt.io._common import check_grid, wrap
from hierplan_opt.io.files import write_text
from hierplan_opt.io.yaml import Ctx, read_text

FREE = frozenset(".GS")
BLOCKED = frozenset("@OTW")


def load_map(path: str | Path) -> Graph:
    """Read a MovingAI ``.map`` file into a 4-connected grid :class:`Graph`.

    Example
    -------
    >>> import os, tempfile
    >>> f = os.path.join(tempfile.mkdtemp(), "tiny.map")
    >>> _ = open(f, "w").write("type octile\\nheight 2\\nwidth 3\\nmap\\n.@.\\n...\\n")
    >>> g = load_map(f)
    >>> g.shape, g.num_vertices, bool(g.passable[g.vertex((1, 0))])
    ((3, 2), 5, False)
    """
    text = read_text(path)
    return parse_map(text, str(path))


def parse_map(text: str, name: str = "<map>") -> Graph:
    """Parse the text of a ``.map`` file (``name`` is used in error messages).

    Example
    -------
    >>> parse_map("type octile\\nheight 1\\nwidth 2\\nmap\\n.@\\n").num_vertices
    1
    """
    ctx = Ctx(name)
    lines = text.splitlines()
    if not lines:
        raise ctx.error("empty file, expected the header line 'type octile'", 1)

    def header(i: int) -> list[str]:
        if i >= len(lines):
            raise ctx.error(
                "file ends inside the header (expected type, height, width, map)", i + 1
            )
        return lines[i].split()

    first = header(0)
    if len(first) != 2 or first[0] != "type":
        raise ctx.error(f"expected the header line 'type octile', got {lines[0].strip()!r}", 1)
    size: dict[str, int] = {}
    i = 1
    while i < 3:
        fields = header(i)
        if len(fields) != 2 or fields[0] not in ("height", "width") or fields[0] in size:
            want = "height H" if "height" not in size else "width W"
            raise ctx.error(f"expected the header line '{want}', got {lines[i].strip()!r}", i + 1)
        if not re.fullmatch(r"\d+", fields[1]) or int(fields[1]) < 1:
            raise ctx.error(f"{fields[0]} must be a positive integer, got {fields[1]!r}", i + 1)
        size[fields[0]] = int(fields[1])
        i += 1
    if header(3) != ["map"]:
        raise ctx.error(f"expected the header line 'map', got {lines[3].strip()!r}", 4)
    width, height = size["width"], size["height"]
    check_grid(ctx, [width, height], 2)
    rows = [ln.rstrip("\r\n") for ln in lines[4:]]
    while rows and not rows[-1].strip():
        rows.pop()
    if len(rows) != height:
        raise ctx.error(
            f"the header says height {height} but the map has {len(rows)} rows",
            4 + min(len(rows), height) + (1 if len(rows) > height else 0),
        )
    blocked = np.zeros((height, width), dtype=bool)
    for y, row in enumerate(rows):
        lineno = y + 5
        row = row.rstrip()
        if len(row) != width:
            raise ctx.error(f"row {y} has {len(row)} cells, expected width {width}", lineno)
        blocked[y] = blocked_cells(row, y, ctx, lineno)
    return Graph.grid(width, height, blocked=blocked)


def blocked_cells(row: str, y: int, ctx: Ctx, line: int | None) -> np.ndarray:
    """Which cells of map row ``y`` are blocked; unknown characters are refused.

    Example
    -------
    >>> blocked_cells(".@T.", 0, Ctx("m.map"), 5).tolist()
    [False, True, True, False]
    """
    out = np.zeros(len(row), dtype=bool)
    for x, ch in enumerate(row):
        if ch in BLOCKED:
            out[x] = True
        elif ch not in FREE:
            raise ctx.error(
                f"unknown map character {ch!r} at x={x} in row {y} "
                "(free: '.' 'G' 'S'; blocked: '@' 'O' 'T' 'W')",
                line,
            )
    return out


def load_scen(
    path: str | Path,
    graph: Graph,
    agents: int | None = None,
    *,
    name: str | None = None,
    map_name: str | None = None,
) -> Instance:
    """Read the first ``agents`` agents (default: all) of a ``.scen`` file on ``graph``.

    Agents are named ``agent0..agentK-1`` in file order. Bad lines, agents outside the
    map or on obstacles, duplicate starts or goals among the chosen agents and a map
    size that differs from ``graph`` are refused with ``file:line: problem``. With
    ``map_name`` (the map's file name), a scenario line written for another map is
    refused too: a scenario of another map of the same size would otherwise be read
    as if it were this map's (folders and the ``.map`` suffix are ignored, case too).

    Example
    -------
    >>> import os, tempfile
    >>> d = tempfile.mkdtemp()
    >>> _ = open(os.path.join(d, "t.map"), "w").write(
    ...     "type octile\\nheight 1\\nwidth 3\\nmap\\n...\\n")
    >>> _ = open(os.path.join(d, "t.scen"), "w").write(
    ...     "version 1\\n0\\tt.map\\t3\\t1\\t0\\t0\\t2\\t0\\t2\\n")
    >>> inst = load_scen(os.path.join(d, "t.scen"), load_map(os.path.join(d, "t.map")))
    >>> inst.agents[0].name, inst.graph.location(inst.agents[0].goal)
    ('agent0', (2, 0))
    """
    ctx = Ctx(path)
    text = read_text(path)
    entries = parse_scen(text, str(path))
    e_maps = scen_map_names(text) if map_name is not None else []
    if graph.kind != "grid" or graph.shape is None or len(graph.shape) != 2:
        raise ctx.error("a scenario needs a 2D grid map")
    width, height = graph.shape
    if agents is not None:
        if isinstance(agents, bool) or not isinstance(agents, int):
            raise InputError(f"--agents must be an integer, got {agents!r}")
        if agents < 1:
            raise InputError(f"--agents must be at least 1, got {agents}")
        if agents > len(entries):
            raise ctx.error(f"--agents {agents} but the scenario has {len(entries)} agents")
    k = len(entries) if agents is None else agents
    if k == 0:
        raise ctx.error("the scenario has no agents")
    starts: dict[int, int] = {}
    goals: dict[int, int] = {}
    s_list: list[tuple[int, int]] = []
    g_list: list[tuple[int, int]] = []
    for i, e in enumerate(entries[:k]):
        lineno, (mw, mh), s, g = e
        if map_name is not None and not same_map(e_maps[i], map_name):
            raise ctx.error(
                f"the scenario is for map {e_maps[i]!r}, not {map_name!r} (rename the "
                "files or pass --ignore-scen-map / check_scen_map=False)",
                lineno,
            )
        if (mw, mh) != (width, height):
            raise ctx.error(
                f"the scenario says the map is {mw}x{mh} but the map is {width}x{height}", lineno
            )
        for what, (x, y), seen in (("start", s, starts), ("goal", g, goals)):
            if not (0 <= x < width and 0 <= y < height):
                raise ctx.error(
                    f"agent{i} {what} [{x}, {y}] is outside the {width}x{height} map", lineno
                )
            v = graph.vertex((x, y))
            if not graph.passable[v]:
                raise ctx.error(f"agent{i} {what} [{x}, {y}] is on an obstacle", lineno)
            if v in seen:
                raise ctx.error(
                    f"agent{i} has the same {what} [{x}, {y}] as agent{seen[v]}", lineno
                )
            seen[v] = i
        s_list.append(s)
        g_list.append(g)
    inst = wrap(
        ctx, None, lambda: Instance.mapf(graph, s_list, g_list, name=name or Path(path).stem)
    )
    inst.meta.update({"format": "movingai", "scen": str(path)})
    return inst


ScenEntry = tuple[int, tuple[int, int], tuple[int, int], tuple[int, int]]


def scen_map_names(text: str) -> list[str]:
    """The map field of every agent line of a ``.scen`` text (after :func:`parse_scen`).

    Example
    -------
    >>> scen_map_names("version 1\\n0\\tmaps/m.map\\t3\\t1\\t0\\t0\\t2\\t0\\t2\\n")
    ['maps/m.map']
    """
    out = []
    for raw in text.splitlines()[1:]:
        if not raw.strip():
            continue
        fields = raw.rstrip("\r\n").split("\t")
        if len(fields) != 9:
            fields = raw.split()
        out.append(fields[1].strip())
    return out


def same_map(scen_field: str, map_name: str) -> bool:
    """Whether a scenario's map field names the map file ``map_name``.

    Only the file name counts (not the folder), without ``.map`` and case.

    Example
    -------
    >>> same_map("maps\\\\Random-32-32-20.map", "random-32-32-20.map"), same_map("a.map", "b.map")
    (True, False)
    """

    def stem(text: str) -> str:
        base = text.replace("\\", "/").rsplit("/", 1)[-1].strip().lower()
        return base[:-4] if base.endswith(".map") else base

    return stem(scen_field) == stem(map_name)


def parse_scen(text: str, name: str = "<scen>") -> list[ScenEntry]:
    """Parse a ``.scen`` text into ``(line, (width, height), start, goal)`` entries.

    Example
    -------
    >>> parse_scen("version 1\\n0\\tm.map\\t3\\t1\\t0\\t0\\t2\\t0\\t2\\n")
    [(2, (3, 1), (0, 0), (2, 0))]
    """
    ctx = Ctx(name)
    lines = text.splitlines()
    if not lines or not re.fullmatch(r"version\s+1(\.0)?", lines[0].strip()):
        got = lines[0].strip() if lines else ""
        raise ctx.error(f"expected the first line 'version 1', got {got!r}", 1)
    out: list[ScenEntry] = []
    for idx, raw in enumerate(lines[1:], start=2):
        if not raw.strip():
            continue
        fields = raw.rstrip("\r\n").split("\t")
        if len(fields) != 9:
            fields = raw.split()  # tolerate space-separated files
        if len(fields) != 9:
            raise ctx.error(
                f"expected 9 tab-separated fields (bucket map width height start_x start_y "
                f"goal_x goal_y optimal_length), got {len(fields)}",
                idx,
            )
        names = ("bucket", "map", "width", "height", "start_x", "start_y", "goal_x", "goal_y")
        nums: list[int] = []
        for j in (0, 2, 3, 4, 5, 6, 7):
            f = fields[j].strip()
            if not re.fullmatch(r"-?\d+", f):
                raise ctx.error(f"field {names[j]} must be an integer, got {f!r}", idx)
            nums.append(int(f))
        _bucket, w, h, sx, sy, gx, gy = nums
        if w < 1 or h < 1:
            raise ctx.error(f"map size {w}x{h} must be positive", idx)
        try:
            opt = float(fields[8])
        except ValueError:
            raise ctx.error(
                f"field optimal_length must be a number, got {fields[8].strip()!r}", idx
            ) from None
        if not math.isfinite(opt) or opt < 0:
            raise ctx.error(
                f"field optimal_length must be a finite number >= 0, got {fields[8].strip()!r}",
                idx,
            )
        out.append((idx, (w, h), (sx, sy), (gx, gy)))
    return out


def load_movingai(
    map_path: str | Path,
    scen_path: str | Path,
    agents: int | None = None,
    *,
    check_scen_map: bool = True,
) -> Instance:
    """Read a ``.map`` and the first ``agents`` agents of a ``.scen``.

    The scenario must name this map (see :func:`load_scen`) unless ``check_scen_map``
    is False.

    Example
    -------
    >>> import os, tempfile
    >>> d = tempfile.mkdtemp()
    >>> m, s = os.path.join(d, "t.map"), os.path.join(d, "t.scen")
    >>> _ = open(m, "w").write("type octile\\nheight 1\\nwidth 3\\nmap\\n...\\n")
    >>> _ = open(s, "w").write("version 1\\n0\\tt.map\\t3\\t1\\t0\\t0\\t2\\t0\\t2\\n")
    >>> load_movingai(m, s).soc_lower_bound()
    2
    """
    graph = load_map(map_path)
    name = Path(map_path).name if check_scen_map else None
    inst = load_scen(scen_path, graph, agents, map_name=name)
    inst.meta["map"] = str(map_path)
    return inst


# ---------------------------------------------------------------- writing
def map_text(graph: Graph) -> str:
    """The ``.map`` text of a 2D grid (blocked cells as ``@``).

    Example
    -------
    >>> print(map_text(Graph.grid(3, 1, obstacles=[(1, 0)])), end="")
    type octile
    height 1
    width 3
    map
    .@.
    """
    if graph.kind != "grid" or graph.shape is None or len(graph.shape) != 2:
        raise InputError("the MovingAI .map format holds only 2D grids")
    width, height = graph.shape
    free = graph.passable.reshape(height, width)
    rows = ["".join("." if f else "@" for f in row) for row in free]
    return f"type octile\nheight {height}\nwidth {width}\nmap\n" + "\n".join(rows) + "\n"


def save_map(path: str | Path, graph: Graph) -> None:
    """Write a 2D grid as a MovingAI ``.map`` file.

    Example
    -------
    >>> import os, tempfile
    >>> f = os.path.join(tempfile.mkdtemp(), "g.map")
    >>> save_map(f, Graph.grid(4, 2, obstacles=[(1, 1)]))
    >>> load_map(f).num_vertices
    7
    """
    write_text(path, map_text(graph))


def scen_text(instance: Instance, map_name: str) -> str:
    """The ``.scen`` text of a MAPF instance on a 2D grid (bucket 0, 4-connected lengths).

    Example
    -------
    >>> inst = Instance.mapf(Graph.grid(3, 1), [(0, 0)], [(2, 0)])
    >>> scen_text(inst, "g.map").splitlines()[1].split("\\t")
    ['0', 'g.map', '3', '1', '0', '0', '2', '0', '2.00000000']
    """
    g = instance.graph
    if g.kind != "grid" or g.shape is None or len(g.shape) != 2:
        raise InputError("the MovingAI .scen format holds only 2D grids")
    if instance.is_tapf:
        raise InputError("the MovingAI .scen format holds only MAPF instances (no teams)")
    width, height = g.shape
    out = ["version 1"]
    for a in instance.agents:
        assert a.goal is not None
        sx, sy = g.location(a.start)  # type: ignore[misc]
        gx, gy = g.location(a.goal)  # type: ignore[misc]
        d = g.dist(a.start, a.goal)
        length = f"{float(d):.8f}" if d < UNREACHABLE else "0"
        out.append(f"0\t{map_name}\t{width}\t{height}\t{sx}\t{sy}\t{gx}\t{gy}\t{length}")
    return "\n".join(out) + "\n"


def save_scen(path: str | Path, instance: Instance, map_name: str | None = None) -> None:
    """Write a MAPF instance's agents as a ``.scen`` file (map name defaults to the stem).

    Agent names are not stored: reading it back names them ``agent0..``.

    Example
    -------
    >>> import os, tempfile
    >>> d = tempfile.mkdtemp()
    >>> inst = Instance.mapf(Graph.grid(3, 1), [(0, 0)], [(2, 0)])
    >>> save_map(os.path.join(d, "g.map"), inst.graph)
    >>> save_scen(os.path.join(d, "g.scen"), inst)
    >>> load_movingai(os.path.join(d, "g.map"), os.path.join(d, "g.scen")).starts
    [0]
    """
    name = map_name or Path(path).with_suffix(".map").name
    write_text(path, scen_text(instance, name))
