"""MAPF Tracker submissions (ShortestPathLab, tracker.pathfinding.ai).

A submission names the benchmark instance and gives one move string per agent::

    map_name,scen_type,type_id,agents,lower_cost,solution_cost,solution_plan
    random-32-32-20,random,1,2,9,9,"3r2d
    d2lw2u"

``map_name`` is the map's file stem, ``scen_type`` and ``type_id`` come from the
scenario's name ``<map>-<even|random>-<id>.scen``, ``agents`` is K (the first K agents
of the scenario). The moves are ``u`` (y - 1, up on the drawn map), ``d`` (y + 1),
``l`` (x - 1), ``r`` (x + 1) and ``w`` (wait), one per timestep from the agent's start,
with run-length encoding (``3r`` = ``rrr``; single moves have no count). Paths end
when the agent arrives, so the string lengths add up to the sum of costs
(``solution_cost``); ``lower_cost`` is a proven lower bound on it, or empty.

The tracker takes CSV (a header row, one submission per row), JSON (an object or a
list) and YAML (a mapping, a list or several documents); ``solution_plan`` may be a
newline-separated string or a list of strings. With ``flip_up_down: true`` the
meaning of ``u`` and ``d`` is swapped.

Two y conventions exist in the wild. The tracker's current documentation has ``d`` for
y + 1 (``"down"``: the pixel origin of MovingAI maps, what this module writes); its older
documentation and its downloadable data use ``u`` for y + 1 (``"up"``): PlanViz's
example 300-agent solution of random-32-32-20-random-1 (``tests/data``) is valid only
read that way. :func:`parse` detects the convention by which one gives paths that stay
on free cells and end at the agents' goals (``"down"`` when both do), unless told;
``stats["tracker_y"]`` says which was used. Older exports name the moves column
``path`` (and start with a byte-order mark); they are read the same way.
"""

from __future__ import annotations

import contextlib
import csv
import io
import json
import re
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml

from hierplan_opt.core.errors import InputError
from hierplan_opt.core.graph import Graph
from hierplan_opt.core.instance import Instance
from hierplan_opt.core.plan import Plan, path_cost
from hierplan_opt.io._common import grid_2d, grid_xy
from hierplan_opt.io.files import limits, write_text
from hierplan_opt.io.yaml import Ctx, check_nesting, read_yaml

FIELDS = (
    "map_name",
    "scen_type",
    "type_id",
    "agents",
    "lower_cost",
    "solution_cost",
    "solution_plan",
)
#: (dx, dy) of each move letter (y grows downwards, as in MovingAI maps).
MOVES = {"u": (0, -1), "d": (0, 1), "l": (-1, 0), "r": (1, 0), "w": (0, 0)}
#: The y conventions: ``"down"`` (``d`` is y + 1, the tracker's current documentation;
#: written by this module) and ``"up"`` (``u`` is y + 1, its older data).
Y_CONVENTIONS = ("down", "up")
#: The convention :func:`dumps` writes.
WRITE_Y = "down"
_LETTER = {v: k for k, v in MOVES.items()}
_RUN = re.compile(r"(\d*)([udlrw])")
_SCEN = re.compile(r"^(?P<map>.+)-(?P<type>even|random)-(?P<id>\d+)$")


@dataclass(frozen=True)
class Submission:
    """One MAPF Tracker submission (see the module text for the fields)."""

    map_name: str
    scen_type: str
    type_id: int
    agents: int
    solution_plan: tuple[str, ...]
    lower_cost: int | None = None
    solution_cost: int | None = None

    def row(self) -> dict[str, Any]:
        """The fields as plain data (``solution_plan`` newline-separated)."""
        return {
            "map_name": self.map_name,
            "scen_type": self.scen_type,
            "type_id": self.type_id,
            "agents": self.agents,
            "lower_cost": self.lower_cost,
            "solution_cost": self.solution_cost,
            "solution_plan": "\n".join(self.solution_plan),
        }


# ---------------------------------------------------------------------- moves
def encode_moves(moves: str) -> str:
    """Run-length encode a move string (runs of one stay single letters).

    Example
    -------
    >>> encode_moves("rrrddwl")
    '3r2dwl'
    """
    return "".join(
        (f"{len(m.group(0))}{m.group(1)}" if len(m.group(0)) > 1 else m.group(1))
        for m in re.finditer(r"([udlrw])\1*", moves)
    )


def decode_moves(text: str, budget: int | None = None) -> str:
    """Expand a run-length encoded move string; refuses anything but counts and letters.

    ``budget`` bounds the expanded length (default: ``limits().max_plan_steps``), so a
    run like ``999999999999w`` is refused instead of filling the memory.

    Example
    -------
    >>> decode_moves("3r2dwl")
    'rrrddwl'
    """

    cap = limits().max_plan_steps if budget is None else budget
    text = text.strip()
    out: list[str] = []
    pos = total = 0
    while pos < len(text):
        m = _RUN.match(text, pos)
        if m is None:
            raise InputError(
                f"bad move {text[pos : pos + 10]!r} at character {pos} "
                "(expected an optional count and one of u d l r w)"
            )
        n = int(m.group(1)) if m.group(1) else 1
        if m.group(1) and n < 1:
            raise InputError(f"a run count must be at least 1, got {m.group(0)!r}")
        total += n
        if total > cap:
            raise InputError(f"the moves expand to more than {cap} steps (the plan-step limit)")
        out.append(m.group(2) * n)
        pos = m.end()
    return "".join(out)


def path_moves(graph: Graph, path: tuple[int, ...]) -> str:
    """The move letters of a path on a 2D grid (trailing waits dropped).

    Example
    -------
    >>> g = Graph.grid(3, 2)
    >>> path_moves(g, (0, 1, 4, 4, 3, 3))
    'rdwl'
    """

    out = []
    for a, b in zip(path[: path_cost(path) + 1], path[1 : path_cost(path) + 1], strict=False):
        (ax, ay), (bx, by) = grid_xy(graph, a), grid_xy(graph, b)
        letter = _LETTER.get((bx - ax, by - ay))
        if letter is None:
            raise InputError(
                f"the path jumps from {[ax, ay]} to {[bx, by]}; the tracker has no such move"
            )
        out.append(letter)
    return "".join(out)


# ---------------------------------------------------------------------- writing
def scenario_name(scen: str | Path) -> tuple[str, str, int]:
    """``(map_name, scen_type, type_id)`` from a benchmark scenario's file name.

    Example
    -------
    >>> scenario_name("instances/movingai/random-32-32-20-random-1.scen")
    ('random-32-32-20', 'random', 1)
    """
    stem = Path(str(scen)).name
    stem = stem[:-5] if stem.lower().endswith(".scen") else stem
    m = _SCEN.match(stem)
    if m is None:
        raise InputError(
            f"cannot tell the tracker's scenario type and id from {Path(str(scen)).name!r} "
            "(benchmark scenarios are named <map>-even-<id>.scen or <map>-random-<id>.scen)"
        )
    return m.group("map"), m.group("type"), int(m.group("id"))


def submission(
    instance: Instance,
    plan: Plan,
    *,
    lower_cost: int | None = None,
    map_name: str | None = None,
    scen_type: str | None = None,
    type_id: int | None = None,
) -> Submission:
    """The tracker submission of ``plan`` for a MovingAI ``instance``.

    The map name, scenario type and id come from the files the instance was read
    from (``instance.meta["scen"]``) unless given.

    Example
    -------
    >>> g = Graph.grid(3, 1)
    >>> inst = Instance.mapf(g, [(0, 0)], [(2, 0)])
    >>> s = submission(inst, Plan.from_paths([[0, 1, 2]]), lower_cost=2,
    ...                map_name="line", scen_type="even", type_id=1)
    >>> s.solution_plan, s.solution_cost
    (('2r',), 2)
    """
    graph = grid_2d(instance, "a MAPF Tracker submission")
    if instance.is_tapf:
        raise InputError("the MAPF Tracker takes MAPF plans only (this instance has teams)")
    if plan.num_agents != instance.num_agents:
        raise InputError(f"the plan has {plan.num_agents} paths for {instance.num_agents} agents")
    if map_name is None or scen_type is None or type_id is None:
        scen = instance.meta.get("scen")
        if scen is None:
            raise InputError(
                "the tracker needs the benchmark's map name, scenario type and id: read the "
                "instance from its .map and .scen files, or give them"
            )
        m, t, i = scenario_name(str(scen))
        map_name = map_name if map_name is not None else m
        scen_type = scen_type if scen_type is not None else t
        type_id = type_id if type_id is not None else i
    moves = tuple(encode_moves(path_moves(graph, p)) for p in plan.paths)
    return Submission(
        map_name,
        scen_type,
        int(type_id),
        instance.num_agents,
        moves,
        None if lower_cost is None else int(lower_cost),
        plan.sum_of_costs,
    )


def dumps(sub: Submission, fmt: str = "csv") -> str:
    """The submission as ``"csv"`` (header + one row), ``"json"`` or ``"yaml"`` text.

    Example
    -------
    >>> s = Submission("empty-8-8", "even", 1, 2, ("5r2d", "w3u"), None, 11)
    >>> print(dumps(s), end="")
    map_name,scen_type,type_id,agents,lower_cost,solution_cost,solution_plan
    empty-8-8,even,1,2,,11,"5r2d
    w3u"
    """
    row = sub.row()
    if fmt == "csv":
        buf = io.StringIO()
        w = csv.DictWriter(buf, fieldnames=FIELDS, lineterminator="\n")
        w.writeheader()
        w.writerow({k: "" if row[k] is None else row[k] for k in FIELDS})
        return buf.getvalue()
    if fmt == "json":
        return json.dumps(row, indent=1) + "\n"
    if fmt in ("yaml", "yml"):
        row["solution_plan"] = list(sub.solution_plan)
        return yaml.safe_dump(row, sort_keys=False, width=10**9)
    raise InputError(f"unknown tracker file format {fmt!r} (use csv, json or yaml)")


def save(path: str | Path, sub: Submission) -> None:
    """Write ``sub`` atomically; the extension picks JSON, YAML or (otherwise) CSV.

    Example
    -------
    >>> import os, tempfile
    >>> f = os.path.join(tempfile.mkdtemp(), "sub.json")
    >>> save(f, Submission("m", "even", 1, 1, ("r",), 1, 1))
    >>> json.load(open(f))["solution_plan"]
    'r'
    """

    write_text(path, dumps(sub, _fmt(Path(path))))


def _fmt(p: Path) -> str:
    return {".json": "json", ".yaml": "yaml", ".yml": "yaml"}.get(p.suffix.lower(), "csv")


# ---------------------------------------------------------------------- reading
def looks_like(text: str) -> bool:
    """Whether ``text`` looks like a tracker submission (it has ``solution_plan``, or is
    an older CSV export whose header names ``agents`` and ``path``).

    Example
    -------
    >>> looks_like("map_name,agents,solution_plan\\n"), looks_like("schedule:\\n")
    (True, False)
    >>> looks_like('\\ufeff"agents","lower_cost","solution_cost","path"\\n')
    True
    """
    if "solution_plan" in text[:4096]:
        return True
    header = text.lstrip("\ufeff").split("\n", 1)[0]
    cols = [c.strip().strip('"').lower() for c in header.split(",")]
    return "agents" in cols and "path" in cols


def parse(
    text: str, name: str, instance: Instance, y: str | None = None
) -> tuple[Plan, dict[str, Any]]:
    """The plan of the submission for ``instance`` in a tracker file, and its fields.

    A file with several submissions (a tracker download lists every agent count of
    every scenario of a map) gives the one whose ``agents`` is the instance's agent count
    and, for an instance read from MovingAI files, whose ``map_name``, ``scen_type`` and
    ``type_id`` match the map and scenario file names (fields a row lacks are not
    compared). ``y`` is the move convention (``"down"`` or ``"up"``, see the module
    text); None detects it. ``stats["tracker_y"]`` is the one used and
    ``stats["tracker_y_from"]`` ``"detected"`` or ``"given"``.

    Example
    -------
    >>> g = Graph.grid(3, 1)
    >>> inst = Instance.mapf(g, [(0, 0)], [(2, 0)])
    >>> text = "map_name,scen_type,type_id,agents,solution_plan\\nm,even,1,1,2r\\n"
    >>> parse(text, "s.csv", inst)[0].paths
    ((0, 1, 2),)
    """
    ctx = Ctx(name)
    if y is not None and y not in Y_CONVENTIONS:
        raise InputError(f"unknown tracker y convention {y!r} (use 'down' or 'up')")
    graph = grid_2d(instance, "a MAPF Tracker submission")
    rows = list(_rows(text.lstrip("\ufeff"), name))
    if not rows:
        raise ctx.error("no submission in the file")
    k = instance.num_agents
    want = _wanted(instance)
    found = []
    for line, row in rows:
        if "solution_plan" not in row and "path" in row:
            row["solution_plan"] = row.pop("path")  # the older export layout
        if "solution_plan" not in row:
            raise ctx.error("a submission without 'solution_plan'", line)
        agents = _int(ctx, row.get("agents"), "agents", line)
        if agents != k:
            continue
        if any(
            row.get(key) not in (None, "") and str(row[key]).strip().lower() != value
            for key, value in want.items()
        ):
            continue
        found.append((line, row))
    if not found:
        counts = sorted({str(r.get("agents")) for _, r in rows}, key=lambda c: (len(c), c))
        where = f" on map {want['map_name']!r}" if "map_name" in want else ""
        if "scen_type" in want:
            where += f", scenario {want['scen_type']}-{want['type_id']}"
        raise ctx.error(
            f"no submission for {k} agents{where} (the file has agents: {', '.join(counts)})"
        )
    line, row = found[0]
    flip = _bool(ctx, row.get("flip_up_down", False), "flip_up_down", line)
    plans = row["solution_plan"]
    strings = plans if isinstance(plans, list) else str(plans).replace("\r\n", "\n").split("\n")
    strings = [str(s) for s in strings]
    if len(strings) > k and all(not s.strip() for s in strings[k:]):
        strings = strings[:k]
    if len(strings) != k:
        raise ctx.error(f"solution_plan has {len(strings)} move strings for {k} agents", line)

    budget = limits().max_plan_steps
    decoded = []
    for i, s in enumerate(strings):
        try:
            moves = decode_moves(s, budget)
        except InputError as exc:
            raise ctx.error(f"agent {i}: {exc}", line) from None
        budget -= len(moves)
        decoded.append(moves)
    used = y
    if used is None:  # the convention under which the paths fit the scenario
        fits = [c for c in Y_CONVENTIONS if _fits(graph, instance, decoded, (c == "up") != flip)]
        used = fits[0] if fits else WRITE_Y
    up = (used == "up") != flip  # flip_up_down swaps u and d once more
    paths = [
        _walk(ctx, graph, instance.agents[i].start, moves, i, up, line)
        for i, moves in enumerate(decoded)
    ]
    stats: dict[str, Any] = {
        key: row.get(key)
        for key in ("map_name", "scen_type", "type_id", "lower_cost", "solution_cost")
        if row.get(key) not in (None, "")
    }
    stats["tracker_y"] = used
    stats["tracker_y_from"] = "detected" if y is None else "given"
    return Plan(tuple(paths)), stats


def _wanted(instance: Instance) -> dict[str, str]:
    """The row fields that must match an instance read from MovingAI files."""
    want: dict[str, str] = {}
    if instance.meta.get("map"):
        want["map_name"] = Path(str(instance.meta["map"])).stem.lower()
    if instance.meta.get("scen"):
        try:
            m, t, i = scenario_name(str(instance.meta["scen"]))
        except InputError:  # not a benchmark scenario name: nothing more to match
            return want
        want.update(map_name=m.lower(), scen_type=t, type_id=str(i))
    return want


def _fits(graph: Graph, instance: Instance, decoded: list[str], up: bool) -> bool:
    """Whether every move string, read with ``u`` as y + 1 when ``up``, stays on free
    cells and ends at its agent's goal."""
    assert graph.shape is not None
    width, height = graph.shape
    sign = -1 if up else 1
    for a, moves in zip(instance.agents, decoded, strict=True):
        x, yy = grid_xy(graph, a.start)
        for c in moves:
            dx, dy = MOVES[c]
            x, yy = x + dx, yy + sign * dy
            if not (0 <= x < width and 0 <= yy < height) or not graph.passable[x + width * yy]:
                return False
        if a.goal is not None and x + width * yy != a.goal:
            return False
    return True


def _walk(
    ctx: Ctx, graph: Graph, start: int, moves: str, agent: int, flip: bool, line: int | None
) -> tuple[int, ...]:
    assert graph.shape is not None
    width, height = graph.shape
    x, y = grid_xy(graph, start)
    path = [start]
    for t, c in enumerate(moves, start=1):
        dx, dy = MOVES[c]
        x, y = x + dx, y - dy if flip else y + dy
        if not (0 <= x < width and 0 <= y < height):
            raise ctx.error(
                f"agent {agent} leaves the {width}x{height} map at t={t} (at [{x}, {y}])", line
            )
        path.append(x + width * y)
    return tuple(path)


def _rows(text: str, name: str) -> Iterator[tuple[int | None, dict[str, Any]]]:
    stripped = text.lstrip()
    if stripped.startswith(("{", "[")):
        yield from _json_rows(text, name)
        return
    first = stripped.split("\n", 1)[0]
    if "," in first and ":" not in first:
        yield from _csv_rows(text, name)
        return
    yield from _yaml_rows(text, name)


def _json_rows(text: str, name: str) -> Iterator[tuple[int | None, dict[str, Any]]]:
    check_nesting(text, name)
    try:
        data = json.loads(text)
    except json.JSONDecodeError as exc:
        raise InputError(f"{name}:{exc.lineno}: JSON syntax error: {exc.msg}") from None
    except RecursionError:
        raise InputError(f"{name}: JSON nesting is too deep") from None
    for d in data if isinstance(data, list) else [data]:
        if not isinstance(d, dict):
            raise InputError(f"{name}: a submission must be an object, got {type(d).__name__}")
        yield None, d


def _yaml_rows(text: str, name: str) -> Iterator[tuple[int | None, dict[str, Any]]]:
    ctx = Ctx(name)
    docs = [d for d in re.split(r"(?m)^---[ \t]*$", text)]
    offset = 0
    for doc in docs:
        if doc.strip():
            data = read_yaml(name, "\n" * offset + doc)
            for d in data if isinstance(data, list) else [data]:
                line = getattr(d, "line", None) or None
                if not isinstance(d, dict):
                    raise ctx.error("a submission must be a mapping", line)
                yield line, d
        offset += doc.count("\n") + 1


@contextlib.contextmanager
def _csv_field_limit(n: int) -> Iterator[None]:
    old = csv.field_size_limit()
    csv.field_size_limit(max(old, n))
    try:
        yield
    finally:
        csv.field_size_limit(old)


def _csv_rows(text: str, name: str) -> Iterator[tuple[int | None, dict[str, Any]]]:
    with _csv_field_limit(limits().max_bytes):
        reader = csv.DictReader(io.StringIO(text, newline=""))
        fields = [f.strip() for f in reader.fieldnames or []]
        if "solution_plan" not in fields and "path" not in fields:
            raise InputError(f"{name}:1: the CSV header has no solution_plan (or path) column")
        reader.fieldnames = fields
        try:
            rows = [(reader.line_num, dict(r)) for r in reader]
        except csv.Error as exc:
            raise InputError(f"{name}:{reader.line_num}: CSV error: {exc}") from None
    for line, row in rows:
        if None in row:
            raise InputError(f"{name}:{line}: the row has more fields than the header")
        yield line, row


def _int(ctx: Ctx, value: Any, what: str, line: int | None) -> int:
    if isinstance(value, bool):
        raise ctx.error(f"{what} must be an integer, got {value!r}", line)
    try:
        return int(str(value).strip())
    except ValueError:
        raise ctx.error(f"{what} must be an integer, got {str(value)[:20]!r}", line) from None


def _bool(ctx: Ctx, value: Any, what: str, line: int | None) -> bool:
    if isinstance(value, bool):
        return value
    text = str(value).strip().lower()
    if text in ("", "0", "false"):
        return False
    if text in ("1", "true"):
        return True
    raise ctx.error(f"{what} must be TRUE or FALSE, got {str(value)[:20]!r}", line)


__all__ = [
    "FIELDS",
    "MOVES",
    "Submission",
    "decode_moves",
    "dumps",
    "encode_moves",
    "looks_like",
    "parse",
    "path_moves",
    "save",
    "scenario_name",
    "submission",
]
