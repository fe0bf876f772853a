"""League of Robot Runners (LoRR 2026, Start-Kit 3.x) problem files and output logs.

A problem is a JSON file naming three more files, relative to its own folder::

    {"mapFile": "maps/random-64-64-10.map", "agentFile": "agents/a.agents",
     "taskFile": "tasks/t.tasks", "teamSize": 400, "numTasksReveal": 1.5,
     "agentCounter": 3, "agentSize": 1.0,
     "delayConfig": {"seed": 0, "minDelay": 1, "maxDelay": 4, "eventModel": "bernoulli",
                     "pDelay": 0.01, "durationModel": "uniform",
                     "gaussMeanRatio": 0.5, "gaussStdRatio": 0.22}}

Locations are *linearised*: ``row * width + column``. The map is a MovingAI-style grid
(``@`` and ``T`` blocked; ``.``, ``E`` emitter, ``S`` service point and ``G`` free). The
agent file is a count and one start per line; the task file a count and one task per
line, each a comma-separated list of errand locations visited in order. Lines starting
with ``#`` are comments. Every problem with these files is refused with one line naming
the file and what is wrong (:class:`~hierplan_opt.core.errors.InputError`).

:func:`write_log` writes the JSON the Start-Kit's ``lifelong`` writes (``actionModel``,
``teamSize``, ``numTaskFinished``, ``makespan``, ``delayIntervals``, ``start``,
``actualPaths`` as compressed segment strings, ``events``, ``tasks``, ``plannerTimes``,
``errors``, ``actualSchedule``, ...), which the PlanViz viewer reads;
:func:`read_log` reads such a log back (ours or the Start-Kit's) for the replay check.
"""

from __future__ import annotations

import json
import math
import re
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from hierplan_opt.core.errors import InputError
from hierplan_opt.io.files import check_grid, read_text, write_text

#: Map characters: blocked and free (the Start-Kit treats every other character as free;
#: we refuse unknown ones so a wrong file is not read as an open field).
BLOCKED_CHARS = frozenset("@T")
FREE_CHARS = frozenset(".ESG")
#: Orientation codes of the Start-Kit: 0 east, 1 south, 2 west, 3 north.
ORIENT_NAMES = ("E", "S", "W", "N")
#: Action letters of the compressed path strings.
ACTION_LETTERS = {"F": "FW", "R": "CR", "C": "CCR", "W": "W", "T": "NA"}
EVENT_MODELS = ("bernoulli", "poisson")
DURATION_MODELS = ("uniform", "gaussian")


@dataclass(frozen=True)
class DelayConfig:
    """The ``delayConfig`` of a problem (defaults as the Start-Kit's ``DelayConfig``).

    Example
    -------
    >>> DelayConfig(p_delay=0.01).event_model
    'bernoulli'
    """

    seed: int = 0
    min_delay: int = 1
    max_delay: int = 1
    event_model: str = "bernoulli"
    p_delay: float = 0.0
    duration_model: str = "uniform"
    gauss_mean_ratio: float = 0.5
    gauss_std_ratio: float = 0.0

    def to_json(self) -> dict[str, Any]:
        """The ``delayConfig`` object as the problem file spells it."""
        return {
            "seed": self.seed,
            "minDelay": self.min_delay,
            "maxDelay": self.max_delay,
            "eventModel": self.event_model,
            "pDelay": self.p_delay,
            "durationModel": self.duration_model,
            "gaussMeanRatio": self.gauss_mean_ratio,
            "gaussStdRatio": self.gauss_std_ratio,
        }


@dataclass(frozen=True, eq=False)
class LorrProblem:
    """A LoRR problem: the grid, the robots' starts, the task list and the parameters.

    ``blocked`` is a flat boolean array over linearised locations (``row * cols + col``);
    ``starts`` the robots' start locations (all facing east, as in the Start-Kit);
    ``tasks`` the task file's lines, each a tuple of errand locations.
    """

    name: str
    rows: int
    cols: int
    blocked: np.ndarray
    starts: tuple[int, ...]
    tasks: tuple[tuple[int, ...], ...]
    num_tasks_reveal: float = 1.0
    agent_size: float = 1.0
    agent_counter: int = 10
    delay: DelayConfig = field(default_factory=DelayConfig)
    map_name: str = ""

    @property
    def team_size(self) -> int:
        """Number of robots."""
        return len(self.starts)

    @property
    def reveal_count(self) -> int:
        """Tasks kept revealed at all times: ``int(numTasksReveal * teamSize)`` (C++ cast)."""
        return int(np.float32(self.num_tasks_reveal) * np.float32(self.team_size))

    def rc(self, loc: int) -> tuple[int, int]:
        """(row, column) of a linearised location."""
        return divmod(loc, self.cols)


# ------------------------------------------------------------------------ reading
def _comment_free_lines(text: str) -> list[tuple[int, str]]:
    return [
        (i + 1, ln.strip())
        for i, ln in enumerate(text.splitlines())
        if ln.strip() and not ln.lstrip().startswith("#")
    ]


def parse_lorr_map(text: str, name: str = "<map>") -> tuple[int, int, np.ndarray]:
    """Rows, columns and the flat ``blocked`` array of a LoRR ``.map`` text.

    Example
    -------
    >>> text = "type octile\\nheight 2\\nwidth 3\\nmap\\n.@.\\nES.\\n"
    >>> rows, cols, blocked = parse_lorr_map(text)
    >>> rows, cols, blocked.nonzero()[0].tolist()
    (2, 3, [1])
    """
    lines = text.splitlines()
    head: dict[str, int] = {}
    if not lines or lines[0].split()[:1] != ["type"]:
        raise InputError(f"{name}:1: expected the header line 'type octile'")
    for i in (1, 2):
        f = lines[i].split() if i < len(lines) else []
        if len(f) != 2 or f[0] not in ("height", "width") or not re.fullmatch(r"\d+", f[1]):
            raise InputError(f"{name}:{i + 1}: expected 'height H' or 'width W'")
        head[f[0]] = int(f[1])
    if len(head) != 2 or min(head.values()) < 1:
        raise InputError(f"{name}: the header needs a positive height and width")
    if len(lines) < 4 or lines[3].strip() != "map":
        raise InputError(f"{name}:4: expected the header line 'map'")
    rows, cols = head["height"], head["width"]
    check_grid([cols, rows], name)
    body = [ln.rstrip("\r\n ") for ln in lines[4:]]
    while body and not body[-1]:
        body.pop()
    if len(body) != rows:
        raise InputError(f"{name}: the header says height {rows} but the map has {len(body)} rows")
    blocked = np.zeros(rows * cols, dtype=bool)
    for r, row in enumerate(body):
        if len(row) != cols:
            raise InputError(f"{name}:{r + 5}: row {r} has {len(row)} cells, expected {cols}")
        bad = set(row) - BLOCKED_CHARS - FREE_CHARS
        if bad:
            ch = sorted(bad)[0]
            raise InputError(
                f"{name}:{r + 5}: unknown map character {ch!r} (free: . E S G; blocked: @ T)"
            )
        arr = np.frombuffer(row.encode("ascii"), dtype=np.uint8)
        blocked[r * cols : (r + 1) * cols] = (arr == ord("@")) | (arr == ord("T"))
    return rows, cols, blocked


def _int_fields(line: str, name: str, lineno: int) -> list[int]:
    out = []
    fields = line.split(",")
    if len(fields) > 1 and not fields[-1].strip():
        fields.pop()  # a trailing comma, as the Start-Kit's reader accepts
    for f in fields:
        f = f.strip()
        if not re.fullmatch(r"-?\d+", f):
            raise InputError(f"{name}:{lineno}: expected comma-separated integers, got {f!r}")
        out.append(int(f))
    return out


def _check_loc(loc: int, blocked: np.ndarray, cols: int, what: str, name: str, ln: int) -> None:
    if not 0 <= loc < len(blocked):
        raise InputError(f"{name}:{ln}: {what} location {loc} is outside the map")
    if blocked[loc]:
        r, c = divmod(loc, cols)
        raise InputError(f"{name}:{ln}: {what} location {loc} (row {r}, column {c}) is blocked")


def _count_header(lines: list[tuple[int, str]], name: str) -> int:
    if not lines:
        raise InputError(f"{name}: empty file, expected a count on the first line")
    ln, first = lines[0]
    fields = _int_fields(first, name, ln)
    if fields[0] < 0:
        raise InputError(f"{name}:{ln}: negative count {fields[0]}")
    return fields[0]


def _key(data: dict[str, Any], key: str, kind: type | tuple[type, ...], name: str) -> Any:
    if key not in data:
        raise InputError(f"{name}: missing property {key!r}")
    v = data[key]
    if isinstance(v, bool) or not isinstance(v, kind):
        raise InputError(f"{name}: {key} must be {_kind_name(kind)}, got {v!r}")
    return v


def _kind_name(kind: type | tuple[type, ...]) -> str:
    if kind is str:
        return "a string"
    if kind is int:
        return "an integer"
    return "a number"


def _opt(data: dict[str, Any], key: str, kind: type | tuple[type, ...], default: Any, name: str):
    return _key(data, key, kind, name) if key in data else default


def parse_delay_config(obj: Any, name: str = "<problem>") -> DelayConfig:
    """Check a ``delayConfig`` object as the Start-Kit does; one line per problem.

    Example
    -------
    >>> parse_delay_config({"minDelay": 0})
    Traceback (most recent call last):
    ...
    hierplan_opt.core.errors.InputError: <problem>: delayConfig.minDelay must be > 0, got 0
    """
    if obj is None:
        return DelayConfig()
    if not isinstance(obj, dict):
        raise InputError(f"{name}: delayConfig must be an object, got {type(obj).__name__}")
    where = f"{name}: delayConfig"
    num = (int, float)
    seed = _opt(obj, "seed", int, 0, where)
    lo = _opt(obj, "minDelay", int, 1, where)
    hi = _opt(obj, "maxDelay", int, 1, where)
    ev = _opt(obj, "eventModel", str, "bernoulli", where)
    p = float(_opt(obj, "pDelay", num, 0.0, where))
    dur = _opt(obj, "durationModel", str, "uniform", where)
    mean = float(_opt(obj, "gaussMeanRatio", num, 0.5, where))
    std = float(_opt(obj, "gaussStdRatio", num, 0.0, where))
    if not 0 <= seed < 2**32:
        raise InputError(f"{where}.seed must be in [0, 2^32), got {seed}")
    if lo <= 0:
        raise InputError(f"{where}.minDelay must be > 0, got {lo}")
    if hi < lo:
        raise InputError(f"{where}.maxDelay must be >= minDelay ({lo}), got {hi}")
    if ev.lower() not in EVENT_MODELS:
        raise InputError(f"{where}.eventModel must be 'bernoulli' or 'poisson', got {ev!r}")
    if dur.lower() not in DURATION_MODELS:
        raise InputError(f"{where}.durationModel must be 'uniform' or 'gaussian', got {dur!r}")
    if not (math.isfinite(p) and 0.0 <= p <= 1.0):
        raise InputError(f"{where}.pDelay must be in [0, 1], got {p}")
    if dur.lower() == "gaussian":
        if not 0.0 <= mean <= 1.0:
            raise InputError(f"{where}.gaussMeanRatio must be in [0, 1], got {mean}")
        if not (math.isfinite(std) and std >= 0.0):
            raise InputError(f"{where}.gaussStdRatio must be >= 0, got {std}")
    return DelayConfig(seed, lo, hi, ev.lower(), p, dur.lower(), mean, std)


#: Tasks revealed at once beyond which a problem is refused (memory: each is an object).
MAX_REVEALED = 100_000


def load_problem(path: str | Path) -> LorrProblem:
    """Read a LoRR problem JSON and the map, agent and task files it names.

    Example
    -------
    >>> import os, json, tempfile
    >>> d = tempfile.mkdtemp()
    >>> m = "type octile\\nheight 1\\nwidth 4\\nmap\\n....\\n"
    >>> _ = open(os.path.join(d, "m.map"), "w").write(m)
    >>> _ = open(os.path.join(d, "a.agents"), "w").write("2\\n0\\n3\\n")
    >>> _ = open(os.path.join(d, "t.tasks"), "w").write("2\\n1,2\\n2\\n")
    >>> _ = open(os.path.join(d, "p.json"), "w").write(json.dumps({"mapFile": "m.map",
    ...     "agentFile": "a.agents", "taskFile": "t.tasks", "teamSize": 2}))
    >>> p = load_problem(os.path.join(d, "p.json"))
    >>> p.team_size, p.tasks, p.agent_counter, p.reveal_count
    (2, ((1, 2), (2,)), 10, 2)
    """
    path = Path(path)
    name = str(path)
    try:
        data = json.loads(read_text(path))
    except json.JSONDecodeError as exc:
        raise InputError(f"{name}:{exc.lineno}: not valid JSON ({exc.msg})") from None
    if not isinstance(data, dict):
        raise InputError(f"{name}: expected a JSON object with mapFile, agentFile, taskFile")
    base = path.parent
    map_file = _key(data, "mapFile", str, name)
    agent_file = _key(data, "agentFile", str, name)
    task_file = _key(data, "taskFile", str, name)
    team = _key(data, "teamSize", int, name)
    if team < 1:
        raise InputError(f"{name}: teamSize must be at least 1, got {team}")
    reveal = float(_opt(data, "numTasksReveal", (int, float), 1.0, name))
    if not (math.isfinite(reveal) and reveal > 0):
        raise InputError(f"{name}: numTasksReveal must be a positive number, got {reveal}")
    if reveal * team > MAX_REVEALED:
        raise InputError(
            f"{name}: numTasksReveal {reveal:g} x teamSize {team} keeps "
            f"{reveal * team:.3g} tasks revealed at once; at most {MAX_REVEALED:,} are "
            "supported (the Start-Kit's problems use 1 to 1.5)"
        )
    size = float(_opt(data, "agentSize", (int, float), 1.0, name))
    if not (math.isfinite(size) and size > 0):
        raise InputError(f"{name}: agentSize must be a positive number, got {size}")
    if size > 1.0:
        raise InputError(
            f"{name}: agentSize {size:g} > 1: footprints reach into neighbouring cells, "
            "which the cell-based executor does not guard"
        )
    counter = _opt(data, "agentCounter", int, 10, name)
    if counter < 1:
        raise InputError(f"{name}: agentCounter must be at least 1, got {counter}")
    delay = parse_delay_config(data.get("delayConfig"), name)

    mpath = base / map_file
    rows, cols, blocked = parse_lorr_map(read_text(mpath), str(mpath))

    apath = base / agent_file
    alines = _comment_free_lines(read_text(apath))
    n_avail = _count_header(alines, str(apath))
    if n_avail < team:
        raise InputError(f"{apath}: teamSize is {team} but the file has only {n_avail} agents")
    if len(alines) - 1 < team:
        raise InputError(f"{apath}: the count says {n_avail} but there are {len(alines) - 1} lines")
    starts: list[int] = []
    seen: dict[int, int] = {}
    for ln, line in alines[1 : team + 1]:
        loc = _int_fields(line, str(apath), ln)[0]
        _check_loc(loc, blocked, cols, "start", str(apath), ln)
        if loc in seen:
            raise InputError(f"{apath}:{ln}: start location {loc} is taken by line {seen[loc]}")
        seen[loc] = ln
        starts.append(loc)

    tpath = base / task_file
    tlines = _comment_free_lines(read_text(tpath))
    n_tasks = _count_header(tlines, str(tpath))
    if n_tasks < 1:
        raise InputError(f"{tpath}: the task file has no tasks")
    if len(tlines) - 1 < n_tasks:
        raise InputError(f"{tpath}: the count says {n_tasks} but there are {len(tlines) - 1} lines")
    tasks: list[tuple[int, ...]] = []
    for ln, line in tlines[1 : n_tasks + 1]:
        locs = _int_fields(line, str(tpath), ln)
        for loc in locs:
            _check_loc(loc, blocked, cols, "errand", str(tpath), ln)
        tasks.append(tuple(locs))
    return LorrProblem(
        name=path.stem,
        rows=rows,
        cols=cols,
        blocked=blocked,
        starts=tuple(starts),
        tasks=tuple(tasks),
        num_tasks_reveal=reveal,
        agent_size=size,
        agent_counter=counter,
        delay=delay,
        map_name=Path(map_file).name,
    )


# ------------------------------------------------------------------------ the log
def encode_path(
    actions: Sequence[str], snapshots: Sequence[tuple[int, int, int, int]], segment: int
) -> str:
    """One robot's compressed path string: segments of ``segment`` ticks, each
    ``[(t,row,col,ori,counter):(A d,A d,...)]`` with the state at the segment's start.

    ``actions`` are one letter per tick (``F R C W T``); ``snapshots[k]`` is the
    ``(row, col, ori, counter)`` at the start of segment ``k``.

    Example
    -------
    >>> encode_path("FFFW", [(0, 0, 0, 0), (1, 0, 0, 0)], 3)
    '[(0,0,0,0,0):(F 3)][(3,1,0,0,0):(W 1)]'
    """
    out = []
    for k, start in enumerate(range(0, len(actions), segment)):
        chunk = actions[start : start + segment]
        runs: list[list[Any]] = []
        for a in chunk:
            if runs and runs[-1][0] == a:
                runs[-1][1] += 1
            else:
                runs.append([a, 1])
        r, c, o, cnt = snapshots[k]
        body = ",".join(f"{a} {d}" for a, d in runs)
        out.append(f"[({start},{r},{c},{o},{cnt}):({body})]")
    return "".join(out)


_SEG = re.compile(r"\[\((-?\d+),(-?\d+),(-?\d+),(-?\d+),(-?\d+)\):\(([^)]*)\)\]")


#: Ticks a recorded path may expand to (run-length counts are refused beyond it).
MAX_PATH_TICKS = 1 << 25


def decode_path(
    text: str, where: str = "path", max_ticks: int = MAX_PATH_TICKS
) -> tuple[tuple[int, int, int, int], str]:
    """The first snapshot ``(row, col, ori, counter)`` and the per-tick action letters
    (at most ``max_ticks``: a log's run-length counts are refused beyond it).

    Example
    -------
    >>> decode_path("[(0,2,1,0,0):(F 3,W 2)]")
    ((2, 1, 0, 0), 'FFFWW')
    """
    pos = 0
    total = 0
    letters: list[str] = []
    first: tuple[int, int, int, int] | None = None
    while pos < len(text):
        m = _SEG.match(text, pos)
        if m is None:
            raise InputError(f"{where}: bad segment at character {pos}: {text[pos : pos + 30]!r}")
        if first is None:
            first = (int(m[2]), int(m[3]), int(m[4]), int(m[5]))
        for run in filter(None, (s.strip() for s in m[6].split(","))):
            parts = run.split()
            if len(parts) != 2 or parts[0] not in ACTION_LETTERS or not parts[1].isdigit():
                raise InputError(f"{where}: bad action run {run!r}")
            total += int(parts[1])
            if total > max_ticks:
                raise InputError(
                    f"{where}: the action runs add up to more than {max_ticks:,} ticks (at {run!r})"
                )
            letters.append(parts[0] * int(parts[1]))
        pos = m.end()
    if first is None:
        raise InputError(f"{where}: empty path string")
    return first, "".join(letters)


def parse_delay_intervals(obj: Any, robots: int, where: str) -> list[list[tuple[int, int]]]:
    """A log's ``delayIntervals``: per robot a list of ``[start, end]`` ticks (whole
    numbers, ``0 <= start <= end``); one line naming ``where`` for anything else.

    Example
    -------
    >>> parse_delay_intervals([[[3, 5]], []], 2, "log.json")
    [[(3, 5)], []]
    >>> parse_delay_intervals([[["a", "b"]], []], 2, "log.json")
    Traceback (most recent call last):
    ...
    hierplan_opt.core.errors.InputError: log.json: delayIntervals[0][0] must be ... got ['a', 'b']
    """
    if not isinstance(obj, list) or len(obj) != robots:
        got = f"{len(obj)} entries" if isinstance(obj, list) else type(obj).__name__
        raise InputError(f"{where}: delayIntervals must list {robots} robots, got {got}")
    out: list[list[tuple[int, int]]] = []
    for i, ivs in enumerate(obj):
        if not isinstance(ivs, list):
            raise InputError(f"{where}: delayIntervals[{i}] must be a list of [start, end]")
        row = []
        for k, iv in enumerate(ivs):
            ok = isinstance(iv, list) and len(iv) == 2
            ok = ok and all(isinstance(x, int) and not isinstance(x, bool) for x in iv)
            if not ok or not 0 <= iv[0] <= iv[1]:
                raise InputError(
                    f"{where}: delayIntervals[{i}][{k}] must be [start, end] ticks (whole "
                    f"numbers, 0 <= start <= end), got {iv!r}"
                )
            row.append((int(iv[0]), int(iv[1])))
        out.append(row)
    return out


def is_lorr(data: Any) -> bool:
    """Whether a parsed JSON document is a LoRR output (an ``actualPaths`` list).

    Example
    -------
    >>> is_lorr({"start": [], "actualPaths": []}), is_lorr({"schedule": {}})
    (True, False)
    """
    return isinstance(data, dict) and isinstance(data.get("actualPaths"), list)


def write_log(path: str | Path, log: dict[str, Any]) -> Path:
    """Write a run's log (a dict in the Start-Kit's layout) atomically as one-line JSON.

    Example
    -------
    >>> import os, tempfile
    >>> f = write_log(os.path.join(tempfile.mkdtemp(), "o.json"), {"actualPaths": []})
    >>> read_log(f)
    {'actualPaths': []}
    """
    return write_text(path, json.dumps(log, separators=(",", ":")))


def read_log(path: str | Path) -> dict[str, Any]:
    """Read a LoRR output log (ours or the Start-Kit's); one line if it is not one.

    Example
    -------
    >>> import os, tempfile
    >>> f = os.path.join(tempfile.mkdtemp(), "o.json")
    >>> _ = open(f, "w").write("[]")
    >>> read_log(f)
    Traceback (most recent call last):
    ...
    hierplan_opt.core.errors.InputError: ...o.json: not a LoRR log (expected ...)
    """
    name = str(path)
    try:
        data = json.loads(read_text(path))
    except json.JSONDecodeError as exc:
        raise InputError(f"{name}:{exc.lineno}: not valid JSON ({exc.msg})") from None
    if not is_lorr(data):
        raise InputError(f"{name}: not a LoRR log (expected an object with an actualPaths list)")
    return data


__all__ = [
    "DelayConfig",
    "LorrProblem",
    "decode_path",
    "encode_path",
    "is_lorr",
    "load_problem",
    "parse_delay_config",
    "parse_lorr_map",
    "read_log",
    "write_log",
]
