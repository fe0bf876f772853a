"""Schedule files that carry what they came from, and the one reader of them.

A schedule file written by ``hierplan post`` (:func:`~hierplan_opt.schedule.write_schedule`)
holds, next to its way-points, the **discrete plan** it was made from and the
**settings** that made it::

    statistics: {makespan: ..., margin: 0.1, ...}
    settings: {objective: makespan, method: graph, margin: 0.1, clearance: true,
               acceleration: true, epsilon: 0, radii: {agent0: 0.0, ...}, solver: ecbs}
    plan:                       # per robot its visits: location and the step it enters
      agent0: [[0, 0, 0], [1, 0, 1], [1, 1, 3]]     # grids: x, y[, z], step
      agent1: [[A, 0], [B, 2]]                      # roadmaps: vertex name, step
    schedule: {agent0: [{x: 0, y: 0, theta: 0.0, arrival: 0.0}, ...], ...}

(CSV files carry ``settings`` and ``plan`` as ``# key: json`` lines.) Waits are the
steps between two visits; a robot stays at its last location.

:func:`load_schedule` is the one reader every command uses (``simulate``, ``refine``,
``run``, ``validate``): it takes the carried plan (never a reconstruction), checks it with the
validator, rebuilds the temporal plan graph and STN with the file's settings, checks
that the file's way-points are that graph's and that its times keep every bound, and
returns a :class:`~hierplan_opt.schedule.Schedule` with the file's times and their
windows. A file of an earlier version (no ``plan``) is read by rebuilding the plan from
the order of the arrival times at every location (one log line says so).
"""

from __future__ import annotations

import logging
import math
from pathlib import Path
from typing import Any

import numpy as np

from hierplan_opt.core.errors import InputError
from hierplan_opt.core.instance import Instance
from hierplan_opt.core.plan import Plan
from hierplan_opt.core.validate import validate
from hierplan_opt.io.files import read_head
from hierplan_opt.schedule.output import Schedule, build_schedule, read_schedule
from hierplan_opt.schedule.post import postprocess
from hierplan_opt.schedule.replay import check_bounds
from hierplan_opt.schedule.solve_graph import critical_path, windows

log = logging.getLogger(__name__)

#: Tolerance (seconds, instance coordinates) for matching a file against its rebuilt graph.
MATCH_TOL = 1e-5
#: File times within this of the earliest schedule are that schedule (files round to 1e-9).
ROUND_TOL = 1e-8


class InvalidScheduleError(InputError):
    """A schedule file that belongs to the instance and reads, but is invalid: its plan
    breaks the rules, or its times break a bound of the plan's STN (or the timing of a
    turn in place). ``hierplan validate`` reports it as invalid (exit code 1); every
    other reader refuses it as bad input."""


# ---------------------------------------------------------------------- the plan
def plan_from_tree(instance: Instance, tree: Any, where: str) -> Plan:
    """The plan of a file's ``plan`` block (:func:`plan_tree`'s layout).

    Raises :class:`InputError` naming ``where`` when it does not fit ``instance``.

    Example
    -------
    >>> from hierplan_opt.core.graph import Graph
    >>> inst = Instance.mapf(Graph.grid(3, 2), [(0, 0)], [(2, 1)])
    >>> plan_from_tree(inst, {"agent0": [[0, 0, 0], [1, 0, 1], [1, 1, 3]]}, "s.yaml").paths
    ((0, 1, 1, 4),)
    """
    g = instance.graph
    if not isinstance(tree, dict):
        raise InputError(f"{where}: 'plan' must map agent names to visit lists")
    same_agents(where, "plan", tree, [a.name for a in instance.agents])
    paths: list[list[int]] = []
    for a in instance.agents:
        rows = tree[a.name]
        if not isinstance(rows, list) or not rows:
            raise InputError(f"{where}: the plan of {a.name!r} has no visits")
        path: list[int] = []
        for row in rows:
            if not isinstance(row, list) or len(row) < 2:
                raise InputError(f"{where}: plan of {a.name!r}: bad visit {row!r}")
            *loc, t = row
            if isinstance(t, bool) or not isinstance(t, int) or t < len(path):
                raise InputError(
                    f"{where}: plan of {a.name!r}: visit {row!r} does not come after the "
                    "previous one (steps must increase)"
                )
            try:
                v = g.vertex(loc[0] if len(loc) == 1 and isinstance(loc[0], str) else loc)
            except InputError as exc:
                raise InputError(f"{where}: plan of {a.name!r}: {exc}") from None
            if path:
                path.extend([path[-1]] * (t - len(path)))
            elif t != 0:
                raise InputError(f"{where}: plan of {a.name!r} does not start at step 0")
            path.append(v)
        paths.append(path)
    horizon = max(len(p) for p in paths)
    return Plan.from_paths([p + [p[-1]] * (horizon - len(p)) for p in paths])


def same_agents(
    where: str, block: str, tree: dict, names: list[str], kind: str = "schedule"
) -> None:
    """Refuse (one line naming ``where`` and ``block``) a mapping ``tree`` whose agent
    names are not exactly ``names``: a file of another instance (``kind``: what the
    file is, for the message). The check every reader of schedule files and execution
    reports makes (``simulate``, ``validate``, ``view``).

    Example
    -------
    >>> same_agents("r.yaml", "schedule", {"agent0": [], "agent9": []}, ["agent0"], "report")
    Traceback (most recent call last):
    ...
    hierplan_opt.core.errors.InputError: r.yaml: schedule: unknown agent 'agent9' (the report ...)
    """
    missing = [n for n in names if n not in tree]
    extra = [n for n in tree if n not in names]
    if missing or extra:
        what = f"no entry for {missing[0]!r}" if missing else f"unknown agent {extra[0]!r}"
        raise InputError(f"{where}: {block}: {what} (the {kind} does not belong to this instance)")


# ---------------------------------------------------------------------- way-points
def _read_rows(
    where: str, sched: Any, names: list[str], dim: int
) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """Way-point coordinates and arrival times of every robot of the file."""
    if not isinstance(sched, dict):
        raise InputError(f"{where}: 'schedule' must map agent names to way-point lists")
    same_agents(where, "schedule", sched, names)
    axes = ("x", "y", "z")[:dim]
    rows: list[np.ndarray] = []
    arrivals: list[np.ndarray] = []
    for name in names:
        wps = sched[name]
        if not isinstance(wps, list) or not wps:
            raise InputError(f"{where}: agent {name!r} has no way-points")
        try:
            c = np.array([[float(w[a]) for a in axes] for w in wps], dtype=float)
            t = np.array([float(w["arrival"]) for w in wps], dtype=float)
        except (KeyError, TypeError, ValueError) as exc:
            raise InputError(f"{where}: agent {name!r}: bad way-point ({exc})") from None
        if not (np.isfinite(c).all() and np.isfinite(t).all()):
            raise InputError(f"{where}: agent {name!r}: non-finite coordinate or time")
        rows.append(c)
        arrivals.append(t)
    return rows, arrivals


def _plan_from_order(
    instance: Instance, rows: list[np.ndarray], arrivals: list[np.ndarray], where: str
) -> Plan:
    """Files of earlier versions (no ``plan``): a plan whose visit order at every
    location is the order of the arrival times there (a precedence makes the later
    robot arrive strictly later), steps by longest paths over "one step per move" and
    "enter once the previous visitor has entered its next location"."""
    import networkx as nx  # heavy module: only for files of earlier versions

    g = instance.graph
    names = [a.name for a in instance.agents]
    lookup = {tuple(np.round(c, 6).tolist()): v for v, c in enumerate(g.coords)}
    visits: list[list[tuple[int, float]]] = []
    for name, c, t in zip(names, rows, arrivals, strict=True):
        if lookup.get(tuple(np.round(c[0], 6).tolist())) is None:
            raise InputError(
                f"{where}: the first way-point of {name!r} is not a vertex of the map "
                "(the schedule does not belong to this instance)"
            )
        seq: list[tuple[int, float]] = []
        for k in range(len(t)):
            v = lookup.get(tuple(np.round(c[k], 6).tolist()))
            if v is None or (seq and seq[-1][0] == v):
                continue  # a marker, the end of a turn in place, or a set-off
            seq.append((v, float(t[k])))
        visits.append(seq)
    G = nx.DiGraph()
    for j, seq in enumerate(visits):
        G.add_node((j, 0))
        for i in range(1, len(seq)):
            G.add_edge((j, i - 1), (j, i), w=1)
    at: dict[int, list[tuple[float, int, int]]] = {}
    for j, seq in enumerate(visits):
        for i, (v, t) in enumerate(seq):
            at.setdefault(v, []).append((t, j, i))
    for v, lst in at.items():
        lst.sort()
        for (_, j, i), (_, k, i2) in zip(lst[:-1], lst[1:], strict=True):
            if j == k:
                continue
            if i + 1 >= len(visits[j]):
                raise InputError(
                    f"{where}: {names[k]!r} reaches the goal of {names[j]!r} after it parked "
                    f"there ({g.label(v)})"
                )
            G.add_edge((j, i + 1), (k, i2), w=0)
    try:
        order = list(nx.topological_sort(G))
    except nx.NetworkXUnfeasible:
        raise InputError(f"{where}: the arrival times order the robots in a cycle") from None
    step = dict.fromkeys(G.nodes, 0)
    for u in order:
        for _, w, d in G.out_edges(u, data=True):
            step[w] = max(step[w], step[u] + d["w"])
    paths: list[list[int]] = []
    for j, seq in enumerate(visits):
        p: list[int] = []
        for i, (v, _) in enumerate(seq):
            while len(p) < step[(j, i)]:
                p.append(p[-1] if p else v)
            p.append(v)
        paths.append(p)
    horizon = max(len(p) for p in paths)
    return Plan.from_paths([p + [p[-1]] * (horizon - len(p)) for p in paths])


# ---------------------------------------------------------------------- settings
def _number(value: Any, what: str, where: str) -> float:
    if (
        isinstance(value, bool)
        or not isinstance(value, (int, float))
        or not math.isfinite(value)
        or value < 0
    ):
        raise InputError(f"{where}: {what} must be a number >= 0, got {value!r}")
    return float(value)


def _settings(data: dict[str, Any], where: str) -> dict[str, Any]:
    """The file's settings; files of earlier versions: from their statistics."""
    stats = data.get("statistics") or {}
    if not isinstance(stats, dict):
        stats = {}
    raw = data.get("settings")
    if raw is not None and not isinstance(raw, dict):
        raise InputError(f"{where}: 'settings' must be a mapping")
    s: dict[str, Any] = dict(raw or {})
    margin = s.get("margin", stats.get("margin", stats.get("delta")))
    if margin is None:
        raise InputError(f"{where}: the schedule's margin is missing (write it with hierplan post)")
    s["margin"] = _number(margin, "margin", where)
    if "clearance" not in s:  # earlier files: no pair marked "not guaranteed"
        rows = stats.get("clearance")
        s["clearance"] = not (
            isinstance(rows, list)
            and any(isinstance(r, dict) and r.get("guaranteed") is False for r in rows)
        )
    s.setdefault("objective", stats.get("objective", "makespan"))
    s.setdefault("method", stats.get("method", "graph"))
    s.setdefault("acceleration", True)
    s["epsilon"] = _number(s.get("epsilon", 0.0), "epsilon", where)
    for key in ("clearance", "acceleration"):
        if not isinstance(s[key], bool):
            raise InputError(f"{where}: settings.{key} must be true or false")
    return s


def _check_radii(instance: Instance, settings: dict[str, Any], where: str) -> None:
    radii = settings.get("radii")
    if radii is None:
        return
    if not isinstance(radii, dict):
        raise InputError(f"{where}: settings.radii must map agent names to radii")
    for a in instance.agents:
        r = radii.get(a.name)
        if r is None:
            continue
        if abs(_number(r, f"the radius of {a.name!r}", where) - a.kinematics.radius) > 1e-9:
            raise InputError(
                f"{where}: the schedule was made for {a.name!r} of radius {r:g} m but the "
                f"instance gives {a.kinematics.radius:g} m"
            )


# ---------------------------------------------------------------------- the reader
def is_schedule_file(path: str | Path) -> bool:
    """Whether ``path`` looks like a schedule file (way-points with ``arrival`` times),
    not a plan: a CSV file that starts with its ``# makespan:`` line, or ``arrival``
    and ``schedule`` in the first 64 kB (cheap: large YAML files take seconds to parse,
    and the reader parses them once).

    Raises :class:`InputError` for what no reader reads (a missing file, a directory,
    a FIFO, a device: :func:`~hierplan_opt.io.files.read_head`), at once: a FIFO is
    never waited on.

    Example
    -------
    >>> import os, tempfile
    >>> f = os.path.join(tempfile.mkdtemp(), "p.yaml")
    >>> _ = open(f, "w").write("schedule: {a: [{x: 0, y: 0, t: 0}]}")
    >>> is_schedule_file(f)
    False
    """
    p = Path(path)
    head = read_head(p, 1 << 16)
    if p.suffix.lower() == ".csv":  # statistics lines first, makespan the first of them
        return head.lstrip().startswith(b"# makespan:")
    return b"arrival" in head and b"schedule" in head


def load_schedule(path: str | Path, instance: Instance) -> Schedule:
    """Read a schedule file written by ``hierplan post`` for ``instance``: the one reader.

    The returned :class:`Schedule` has the file's times, their windows, the STN rebuilt
    from the file's plan and settings (``schedule.stn``), and ``schedule.plan`` /
    ``schedule.settings``. Raises :class:`InputError` with one line naming the file when
    it cannot be read or does not belong to ``instance``, and its subclass
    :class:`InvalidScheduleError` when its plan is invalid or its times break a bound.

    Example
    -------
    >>> import os, tempfile
    >>> from hierplan_opt.core.graph import Graph
    >>> from hierplan_opt.schedule import postprocess, write_schedule
    >>> inst = Instance.mapf(Graph.grid(4, 1), [(1, 0), (0, 0)], [(3, 0), (2, 0)])
    >>> plan = Plan.from_paths([[1, 2, 3], [0, 1, 2]])
    >>> f = write_schedule(postprocess(inst, plan), os.path.join(tempfile.mkdtemp(), "s.yaml"))
    >>> s = load_schedule(f, inst)
    >>> s.plan == plan, s.margin, round(s.makespan, 6)
    (True, 0.1, 2.1)
    """
    where = str(path)
    data = read_schedule(path)
    g = instance.graph
    names = [a.name for a in instance.agents]
    rows, arrivals = _read_rows(where, data["schedule"], names, g.dim)
    settings = _settings(data, where)
    _check_radii(instance, settings, where)
    if "plan" in data:
        plan = plan_from_tree(instance, data["plan"], where)
    else:
        log.warning(
            "%s carries no plan (a file of an earlier version): the plan is rebuilt from "
            "the order of its arrival times",
            where,
        )
        plan = _plan_from_order(instance, rows, arrivals, where)
    bad = validate(instance, plan)
    if bad:
        more = f" (and {len(bad) - 1} more)" if len(bad) > 1 else ""
        raise InvalidScheduleError(f"{where}: the schedule's plan is invalid: {bad[0]}{more}")
    try:
        rebuilt = postprocess(
            instance,
            plan,
            "makespan",
            margin=settings["margin"],
            clearance=settings["clearance"],
            epsilon=settings["epsilon"],
            acceleration=settings["acceleration"],
            deadlines=settings.get("deadlines"),
            check_plan=False,
        )
    except InputError as exc:
        raise InputError(f"{where}: {exc}") from None
    stn = rebuilt.stn
    assert stn is not None
    times = np.zeros(stn.num_nodes)
    for name, c, t, wp in zip(names, rows, arrivals, rebuilt.waypoints, strict=True):
        if len(c) != len(wp) or not np.allclose(c, wp.coords, atol=MATCH_TOL):
            raise InputError(
                f"{where}: the way-points of {name!r} are not those of its plan with margin "
                f"{settings['margin']:g} m (was the file written by hierplan post for this "
                "instance?)"
            )
        node = np.asarray(wp.node)
        keep = np.flatnonzero(node >= 0)
        times[node[keep]] = t[keep]
    if np.allclose(times, rebuilt.times, rtol=0.0, atol=ROUND_TOL):
        times = np.array(rebuilt.times)  # the earliest schedule: exact, not rounded
    broken = check_bounds(stn, times)
    if broken:
        more = f" (and {len(broken) - 1} more)" if len(broken) > 1 else ""
        raise InvalidScheduleError(
            f"{where}: the times break a bound of the plan's STN: {broken[0]}{more}"
        )
    early, late = windows(stn, times)
    req = stn.tpg.requirement
    stats = data.get("statistics")
    out = build_schedule(
        stn,
        times,
        early,
        late,
        critical_path(stn, times),
        objective=str(settings["objective"]),
        method=str(settings["method"]),
        scale=g.scale,
        safety_distance=req.guaranteed_distance(),
        margin=req.margin,
        clearance=req.report(),
        stats=dict(stats) if isinstance(stats, dict) else {},
        plan=plan,
        settings=settings,
    )
    for name, t, wp in zip(names, arrivals, out.waypoints, strict=True):
        if not np.allclose(t, wp.arrival, atol=MATCH_TOL):
            k = int(np.argmax(np.abs(t - wp.arrival)))
            raise InvalidScheduleError(
                f"{where}: way-point {k} of {name!r} arrives at {t[k]:g} s but its turn in "
                f"place makes it {wp.arrival[k]:g} s"
            )
    return out
