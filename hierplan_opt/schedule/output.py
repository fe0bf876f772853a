"""The :class:`Schedule` type and its file formats (YAML, JSON, CSV, Graphviz DOT).

A schedule lists, per robot, way-points in the instance's coordinates (grid cells,
or roadmap coordinates) with a heading ``theta`` (radians, x-y plane) and an arrival
time. Between consecutive way-points a robot moves in a straight line at constant
speed. Way-points are the STN's nodes (vertices and the safety markers that carry a
precedence) plus, for differential-drive robots, a "turn" way-point at the vertex
where the robot has finished turning in place.

YAML layout (JSON is the same tree; CSV has one row per way-point, and the
``statistics``, ``settings`` and ``plan`` blocks as ``# key: json`` lines)::

    statistics: {makespan: 4.0, safety_distance: 0.25, objective: makespan, ...}
    settings: {objective: makespan, method: graph, margin: 0.25, radii: {...}, ...}
    plan: {agent0: [[0, 0, 0], [1, 0, 1], ...]}               # the discrete plan
    schedule:
      agent0: [{x: 0, y: 0, theta: 0.0, arrival: 0.0}, ...]   # z: on 3D maps

``settings`` and ``plan`` say what the schedule came from; they are read back by
:func:`hierplan_opt.schedule.files.load_schedule`, the one reader of schedule files.
"""

from __future__ import annotations

import csv
import io
import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from hierplan_opt.core.errors import InputError
from hierplan_opt.core.instance import Instance
from hierplan_opt.core.plan import Plan
from hierplan_opt.core.reprs import short_repr
from hierplan_opt.io.files import read_text
from hierplan_opt.io.values import plain, to_json
from hierplan_opt.io.yaml import check_nesting, read_yaml, to_yaml
from hierplan_opt.schedule.clearance import PairClearance
from hierplan_opt.schedule.stn import MOVE, PIECE, PRECEDENCE, STN
from hierplan_opt.schedule.tpg import KIND_NAMES

#: Way-point kinds: STN node kinds plus the end of a turn in place.
TURN = "turn"


def plan_tree(instance: Instance, plan: Plan) -> dict[str, list[list[Any]]]:
    """The plan as a file carries it: per robot its visits ``[*location, step]``.

    Example
    -------
    >>> from hierplan_opt.core.graph import Graph
    >>> inst = Instance.mapf(Graph.grid(3, 2), [(0, 0)], [(2, 1)])
    >>> plan_tree(inst, Plan.from_paths([[0, 1, 1, 4, 5]]))
    {'agent0': [[0, 0, 0], [1, 0, 1], [1, 1, 3], [2, 1, 4]]}
    """
    g = instance.graph
    out: dict[str, list[list[Any]]] = {}
    for agent, path in zip(instance.agents, plan.paths, strict=True):
        rows: list[list[Any]] = []
        prev = None
        for t, v in enumerate(path):
            if v != prev:
                loc = g.plain_location(int(v))
                rows.append([loc, t] if isinstance(loc, str) else [*loc, t])
                prev = v
        out[agent.name] = rows
    return out


@dataclass(frozen=True, eq=False)
class Waypoints:
    """One robot's way-points (read-only arrays).

    ``coords`` (n, dim) instance coordinates; ``theta``, ``arrival``, ``earliest``,
    ``latest`` (n,); ``node`` the STN node id (-1 for turn way-points); ``kind`` the
    way-point kinds ("vertex", "leave", "enter", "marker", "turn"). ``earliest`` and
    ``latest`` bound the arrival in any schedule of the STN that finishes by this
    schedule's makespan; ``slack = latest - arrival`` is the delay the way-point absorbs.
    """

    __repr__ = short_repr  # arrays and long tuples summarised (core/reprs)

    coords: np.ndarray
    theta: np.ndarray
    arrival: np.ndarray
    earliest: np.ndarray
    latest: np.ndarray
    node: np.ndarray
    kind: tuple[str, ...]

    def __len__(self) -> int:
        return len(self.arrival)

    @property
    def slack(self) -> np.ndarray:
        return self.latest - self.arrival


@dataclass(frozen=True, eq=False)
class Schedule:
    """An execution schedule: way-points with arrival times for every robot.

    Attributes
    ----------
    agent_names : tuple of str
    waypoints : tuple of :class:`Waypoints`, one per robot
    makespan, flowtime : float
        Latest and summed arrival times at the robots' final way-points.
    safety_distance : float
        Guaranteed lower bound on the distance between any two robots' centres: the
        smallest ``r_i + r_j + margin`` over all pairs (0 without a clearance
        guarantee). Every pair ``i, j`` keeps its own ``r_i + r_j + margin``
        (see :attr:`clearance`) in any motion that passes the way-points in order.
    objective, method : str
    delta : float
        Deprecated alias of :attr:`margin` (earlier a marker distance).
    earliest, latest : (N,) float
        Earliest and latest time of every STN node in any schedule of the STN that
        finishes by this schedule's makespan; ``slack = latest - times``.
    times : (N,) float
        The scheduled time of every STN node.
    critical_path : tuple of int
        STN node ids of a critical path (zero slack) to the robot that finishes last.
    scale : float
        Metres per instance coordinate unit (the grid's cell size; 1 on roadmaps).
    stats : dict
    stn : STN
    margin : float
        Extra clearance beyond the radii (metres).
    clearance : tuple of PairClearance
        Per pair of robot types: the required distance ``r_a + r_b + margin`` and
        whether the schedule guarantees it.
    plan : Plan or None
        The discrete plan the schedule was made from.
    settings : dict
        What made it: ``objective``, ``method``, ``margin``, ``clearance``,
        ``acceleration``, ``epsilon``, ``deadlines``, ``radii`` (per robot) and the
        ``solver`` of the plan when known.
    plan_rows : dict or None
        The plan as its file carries it (:func:`plan_tree`).
    """

    __repr__ = short_repr  # arrays and long tuples summarised (core/reprs)

    agent_names: tuple[str, ...]
    waypoints: tuple[Waypoints, ...]
    makespan: float
    flowtime: float
    safety_distance: float
    objective: str
    method: str
    delta: float
    earliest: np.ndarray
    latest: np.ndarray
    times: np.ndarray
    critical_path: tuple[int, ...]
    scale: float
    stats: dict[str, Any] = field(default_factory=dict)
    stn: STN | None = field(default=None, repr=False)
    margin: float = 0.0
    clearance: tuple[PairClearance, ...] = ()
    plan: Plan | None = field(default=None, repr=False)
    settings: dict[str, Any] = field(default_factory=dict)
    plan_rows: dict[str, list[list[Any]]] | None = field(default=None, repr=False)

    @property
    def slack(self) -> np.ndarray:
        """Slack of every STN node: how much later than scheduled it may happen
        without delaying the last arrival (``latest - times``)."""
        return self.latest - self.times

    @property
    def num_agents(self) -> int:
        return len(self.agent_names)

    @property
    def dim(self) -> int:
        return int(self.waypoints[0].coords.shape[1]) if self.waypoints else 2

    def arrival_times(self, agent: int | str) -> np.ndarray:
        """Arrival times of one robot's way-points (index or name)."""
        return self.waypoints[self._index(agent)].arrival

    def _index(self, agent: int | str) -> int:
        if isinstance(agent, str):
            try:
                return self.agent_names.index(agent)
            except ValueError:
                raise InputError(f"no agent named {agent!r} in the schedule") from None
        return int(agent)

    def critical_waypoints(self) -> list[tuple[str, int]]:
        """The critical path as ``(agent name, way-point index)`` pairs."""
        where = {}
        for j, wp in enumerate(self.waypoints):
            for k, v in enumerate(wp.node.tolist()):
                if v >= 0:
                    where[v] = (self.agent_names[j], k)
        return [where[v] for v in self.critical_path]

    def statistics(self) -> dict[str, Any]:
        """The ``statistics`` block of the output files (plain Python values)."""
        out: dict[str, Any] = {
            "makespan": _num(self.makespan),
            "flowtime": _num(self.flowtime),
            "safety_distance": _num(self.safety_distance),
            "objective": self.objective,
            "method": self.method,
            "margin": _num(self.margin),
            "clearance": [c.as_dict() for c in self.clearance],
        }
        for k, v in self.stats.items():
            out[k] = _num(v)
        return plain(out)

    def to_dict(self) -> dict[str, Any]:
        """``{statistics: {...}, schedule: {agent: [{x, y, [z,] theta, arrival}, ...]}}``."""
        axes = ("x", "y", "z")[: self.dim]
        sched: dict[str, list[dict[str, Any]]] = {}
        for name, wp in zip(self.agent_names, self.waypoints, strict=True):
            rows = []
            for k in range(len(wp)):
                row: dict[str, Any] = {a: _num(c) for a, c in zip(axes, wp.coords[k], strict=True)}
                row["theta"] = round(float(wp.theta[k]), 9)
                row["arrival"] = round(float(wp.arrival[k]), 9)
                rows.append(row)
            sched[name] = rows
        out: dict[str, Any] = {"statistics": self.statistics()}
        out.update(self.provenance())
        out["schedule"] = sched
        return out

    def provenance(self) -> dict[str, Any]:
        """The ``settings`` and ``plan`` blocks of the files (those known)."""
        out: dict[str, Any] = {}
        if self.settings:
            out["settings"] = _num(self.settings)
        if self.plan_rows is not None:
            out["plan"] = self.plan_rows
        return out


def _num(x: Any) -> Any:
    """Floats rounded to 9 decimals, whole ones written as ints (``2`` not ``2.0``)."""
    return plain(x, digits=9, integral=True)


# ---------------------------------------------------------------------- building
def build_schedule(
    stn: STN,
    times: np.ndarray,
    earliest: np.ndarray,
    latest: np.ndarray,
    critical_path: tuple[int, ...],
    *,
    objective: str,
    method: str,
    scale: float,
    safety_distance: float = 0.0,
    margin: float = 0.0,
    clearance: tuple[PairClearance, ...] = (),
    stats: dict[str, Any] | None = None,
    plan: Plan | None = None,
    settings: dict[str, Any] | None = None,
    plan_rows: dict[str, list[list[Any]]] | None = None,
) -> Schedule:
    """Way-points of every robot from STN node times (adds turn way-points).

    Raises :class:`InputError` when a time is not a finite number (a schedule file
    never holds one).
    """
    tpg = stn.tpg
    N = tpg.num_nodes
    times = np.array(times, dtype=float)
    earliest = np.array(earliest, dtype=float)
    latest = np.array(latest, dtype=float)
    for name, x in (("time", times), ("earliest time", earliest), ("latest time", latest)):
        bad = np.flatnonzero(~np.isfinite(x))
        if len(bad):
            raise InputError(
                f"the {name} of {tpg.label(int(bad[0]))} is not a finite number; "
                "MAPF-POST cannot represent this schedule"
            )
    turn_after = np.zeros(N)
    piece = stn.arc_kind == PIECE
    turn_after[stn.arc_src[piece]] = stn.arc_turn[piece]
    # Heading on arrival: the previous node's leaving heading (a robot's first node:
    # its own, i.e. it starts facing its first move).
    first = np.zeros(N, dtype=bool)
    first[tpg.agent_ptr[:-1]] = True
    heading = tpg.node_heading
    head_in = heading.copy()
    head_in[~first] = heading[np.flatnonzero(~first) - 1]
    # Every node gives a way-point; a turn in place adds a second one at its end.
    has_turn = turn_after > 0
    rep = 1 + has_turn.astype(np.int64)
    src = np.repeat(np.arange(N), rep)
    ends = np.cumsum(rep)
    is_turn = np.zeros(len(src), dtype=bool)
    is_turn[ends[has_turn] - 1] = True
    shift = np.where(is_turn, turn_after[src], 0.0)
    all_coords = tpg.node_coord[src]
    all_theta = np.where(is_turn, heading[src], head_in[src])
    all_arr = times[src] + shift
    all_ear = earliest[src] + shift
    all_lat = latest[src] + shift
    all_node = np.where(is_turn, -1, src)
    names = np.array([*KIND_NAMES, TURN], dtype=object)
    all_kind = names[np.where(is_turn, len(KIND_NAMES), tpg.node_kind[src])].tolist()
    for x in (all_coords, all_theta, all_arr, all_ear, all_lat, all_node):
        x.setflags(write=False)
    wp_ptr = np.concatenate(([0], ends))[tpg.agent_ptr].tolist()
    wps = []
    for j in range(tpg.num_agents):
        a, b = wp_ptr[j], wp_ptr[j + 1]
        wps.append(
            Waypoints(
                all_coords[a:b],
                all_theta[a:b],
                all_arr[a:b],
                all_ear[a:b],
                all_lat[a:b],
                all_node[a:b],
                tuple(all_kind[a:b]),
            )
        )
    finals = tpg.final_nodes()
    for x in (times, earliest, latest):
        x.setflags(write=False)
    return Schedule(
        agent_names=tpg.agent_names,
        waypoints=tuple(wps),
        makespan=float(times[finals].max()),
        flowtime=float(times[finals].sum()),
        safety_distance=float(safety_distance),
        objective=objective,
        method=method,
        delta=float(margin),
        earliest=earliest,
        latest=latest,
        times=times,
        critical_path=tuple(int(v) for v in critical_path),
        scale=float(scale),
        stats=dict(stats or {}),
        stn=stn,
        margin=float(margin),
        clearance=tuple(clearance),
        plan=plan,
        settings=dict(settings or {}),
        plan_rows=plan_rows,
    )


# ---------------------------------------------------------------------- files
FORMATS = (".yaml", ".yml", ".json", ".csv")


def schedule_text(schedule: Schedule, fmt: str = "yaml") -> str:
    """The schedule as text: ``fmt`` is ``"yaml"``, ``"json"`` or ``"csv"``."""
    if fmt in ("yaml", "yml"):
        return to_yaml(schedule.to_dict())
    if fmt == "json":
        return to_json(schedule.to_dict(), indent=1) + "\n"
    if fmt == "csv":
        buf = io.StringIO()
        for k, v in schedule.statistics().items():
            buf.write(f"# {k}: {to_json(v)}\n")
        for k, v in schedule.provenance().items():
            buf.write(f"# {k}: {to_json(v, separators=(',', ':'))}\n")
        axes = ["x", "y", "z"][: schedule.dim]
        w = csv.writer(buf, lineterminator="\n")
        w.writerow(
            ["agent", "index", *axes, "theta", "arrival", "earliest", "latest", "slack", "kind"]
        )
        for name, wp in zip(schedule.agent_names, schedule.waypoints, strict=True):
            for k in range(len(wp)):
                w.writerow(
                    [
                        name,
                        k,
                        *[repr(_num(c)) for c in wp.coords[k]],
                        repr(round(float(wp.theta[k]), 9)),
                        repr(round(float(wp.arrival[k]), 9)),
                        repr(round(float(wp.earliest[k]), 9)),
                        repr(round(float(wp.latest[k]), 9)),
                        repr(round(float(wp.latest[k] - wp.arrival[k]), 9)),
                        wp.kind[k],
                    ]
                )
        return buf.getvalue()
    raise InputError(f"unknown schedule format {fmt!r} (use yaml, json or csv)")


def write_schedule(schedule: Schedule, path: str | Path) -> Path:
    """Write ``schedule`` to ``path``; the extension picks YAML (default), JSON or CSV.

    Example
    -------
    >>> import tempfile, os
    >>> from hierplan_opt import Graph, Instance, Plan
    >>> from hierplan_opt.schedule import postprocess
    >>> inst = Instance.mapf(Graph.grid(3, 1), [(0, 0)], [(2, 0)])
    >>> s = postprocess(inst, Plan.from_paths([[0, 1, 2]]))
    >>> with tempfile.TemporaryDirectory() as d:
    ...     p = write_schedule(s, os.path.join(d, "s.yaml"))
    ...     [w["arrival"] for w in read_schedule(p)["schedule"]["agent0"]]
    [0.0, 1.0, 2.0]
    """
    path = Path(path)
    ext = path.suffix.lower()
    fmt = {".yaml": "yaml", ".yml": "yaml", ".json": "json", ".csv": "csv"}.get(ext, "yaml")
    path.write_text(schedule_text(schedule, fmt))
    return path


def read_schedule(path: str | Path) -> dict[str, Any]:
    """Parse a schedule file back into ``{statistics: {...}, schedule: {agent: [...]}}``.

    CSV rows come back with the same keys as YAML (``x, y, [z,] theta, arrival``) plus
    ``earliest, latest, slack, kind``.
    """

    path = Path(path)
    text = read_text(path)  # regular files within the size limit only
    ext = path.suffix.lower()
    if ext == ".json":
        check_nesting(text, str(path))
        data = json.loads(text)
    elif ext == ".csv":
        stats: dict[str, Any] = {}
        lines = []
        for line in text.splitlines():
            if line.startswith("# "):
                k, _, v = line[2:].partition(": ")
                stats[k] = json.loads(v)
            elif line:
                lines.append(line)
        sched: dict[str, list[dict[str, Any]]] = {}
        for row in csv.DictReader(lines):
            name = row.pop("agent")
            row.pop("index")
            kind = row.pop("kind")
            rec: dict[str, Any] = {k: float(v) for k, v in row.items()}
            rec["kind"] = kind
            sched.setdefault(name, []).append(rec)
        data = {"statistics": stats}
        for key in ("settings", "plan"):  # blocks of their own in YAML and JSON
            if key in stats:
                data[key] = stats.pop(key)
        data["schedule"] = sched
    else:
        data = read_yaml(path, text)  # nesting and alias limits
    if not isinstance(data, dict) or "schedule" not in data:
        raise InputError(f"{path}: not a schedule file (no 'schedule' key)")
    return data


# ---------------------------------------------------------------------- DOT
def to_dot(stn: STN, schedule: Schedule | None = None, *, max_nodes: int = 20000) -> str:
    """The STN (its TPG with bounds) as Graphviz DOT text.

    One cluster per robot; pieces are solid arcs labelled with their lower bound,
    Type-2 precedences dashed, acceleration (move) arcs dotted. With a schedule, nodes
    show their time and slack, and the critical path is red.
    """
    tpg = stn.tpg
    if tpg.num_nodes > max_nodes:
        raise InputError(f"the STN has {tpg.num_nodes} nodes; DOT output is limited to {max_nodes}")
    crit = set(schedule.critical_path) if schedule is not None else set()
    crit_arcs = set()
    if schedule is not None:
        cp = schedule.critical_path
        crit_arcs = set(zip(cp[:-1], cp[1:], strict=True))
    out = ["digraph STN {", "  rankdir=LR;", "  node [shape=box, fontsize=10];"]
    for j in range(tpg.num_agents):
        out.append(f"  subgraph cluster_{j} {{")
        out.append(f'    label="{_esc(tpg.agent_names[j])}";')
        for v in tpg.agent_nodes(j):
            label = tpg.label(v)
            if schedule is not None:
                label += f"\\nt={schedule.times[v]:.3g} slack={schedule.slack[v]:.3g}"
            color = ", color=red" if v in crit else ""
            out.append(f'    n{v} [label="{_esc(label)}"{color}];')
        out.append("  }")
    for u, v, lo, hi, kind in zip(
        stn.arc_src.tolist(),
        stn.arc_dst.tolist(),
        stn.lb.tolist(),
        stn.ub.tolist(),
        stn.arc_kind.tolist(),
        strict=True,
    ):
        bound = f"[{lo:.3g}, {hi:.3g}]" if math.isfinite(hi) else f"{lo:.3g}"
        style = {PRECEDENCE: "dashed", MOVE: "dotted"}.get(kind, "solid")
        color = ", color=red" if (u, v) in crit_arcs else ""
        out.append(f'  n{u} -> n{v} [label="{bound}", style={style}{color}];')
    out.append("}")
    return "\n".join(out) + "\n"


def _esc(s: str) -> str:
    return s.replace('"', '\\"')
