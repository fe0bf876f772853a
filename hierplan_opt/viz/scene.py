"""What the viewer and the animations draw: a :class:`Scene` (map, robots, motion, events).

A scene is built from any of the toolkit's outputs:

* a discrete plan (:func:`scene_from_plan`): one vertex per robot and timestep, drawn
  moving in a straight line over each step (``steps`` motion, compact for 10,000 robots);
* a schedule (:func:`scene_from_schedule`): way-points with arrival times and their slack
  (``latest - arrival``), and the schedule's guaranteed clearance;
* refined trajectories (:func:`scene_from_trajectories`): the exact motion sampled;
* an execution report (:func:`scene_from_report`, ``hierplan simulate/run --out``): the
  executed way-points, the disturbances and the layer that handled each one;
* a lifelong log in the LoRR (League of Robot Runners) output format
  (:func:`scene_from_lorr`): ``start`` and ``actualPaths`` actions ``F``/``R``/``C``/``W``/``T``.

Positions are in instance coordinates (grid cells, ``y`` down; roadmap units);
distances in metres (``scale`` metres per unit). :func:`positions_at` is the reference
that the browser viewer and the animations must agree with.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from hierplan_opt.core.errors import InputError
from hierplan_opt.core.graph import Graph
from hierplan_opt.core.instance import Instance
from hierplan_opt.core.plan import Plan
from hierplan_opt.core.progress import tick
from hierplan_opt.io.lorr import (
    MAX_PATH_TICKS,
    decode_path,
    is_lorr,
    parse_delay_intervals,
    read_log,
)

#: Colour of each layer of the hierarchy that handles a disturbance.
LAYER_COLORS = {
    "slack": "#2ca02c",
    "stn": "#ff7f0e",
    "reorder": "#9467bd",
    "replan": "#d62728",
    "none": "#7f7f7f",
}


@dataclass(eq=False)
class Scene:
    """Everything a picture of a fleet needs (see the module docstring).

    ``steps`` (T+1, K) vertex ids one ``dt`` apart, or ``keys``: per robot an
    ``(n, 1 + dim)`` array of ``(time, x, y[, z])`` way-points (straight lines between
    them, resting at the last). ``slack`` (per robot, one value per key) is how much
    later the robot could pass that way-point without delaying the makespan.
    ``events`` are dicts ``{time, agent, kind, layer, delay, detail}``.
    ``guaranteed`` is the schedule's guaranteed centre distance (metres), ``margin``
    the extra clearance beyond ``r_i + r_j``.
    """

    title: str
    source: str
    graph: Graph
    names: list[str]
    radius: np.ndarray
    goals: np.ndarray
    team: np.ndarray
    team_names: list[str]
    steps: np.ndarray | None = None
    dt: float = 1.0
    keys: list[np.ndarray] | None = None
    slack: list[np.ndarray] | None = None
    events: list[dict[str, Any]] = field(default_factory=list)
    targets: np.ndarray | None = None
    target_team: np.ndarray | None = None
    guaranteed: float | None = None
    margin: float = 0.0
    stats: dict[str, Any] = field(default_factory=dict)

    @property
    def num_agents(self) -> int:
        return len(self.names)

    @property
    def dim(self) -> int:
        return int(self.graph.dim)

    @property
    def scale(self) -> float:
        return float(self.graph.scale)

    @property
    def end(self) -> float:
        """The time of the last move (seconds)."""
        if self.steps is not None:
            return float((len(self.steps) - 1) * self.dt)
        assert self.keys is not None
        return max((float(k[-1, 0]) for k in self.keys if len(k)), default=0.0)


def positions_at(scene: Scene, t: float) -> np.ndarray:
    """``(K, dim)`` positions of every robot at time ``t`` (instance coordinates).

    Example
    -------
    >>> from hierplan_opt.core.graph import Graph
    >>> inst = Instance.mapf(Graph.grid(3, 1), [(0, 0)], [(2, 0)])
    >>> positions_at(scene_from_plan(inst, Plan.from_paths([[0, 1, 2]])), 1.25).tolist()
    [[1.25, 0.0]]
    """
    coords = scene.graph.coords
    if scene.steps is not None:
        T = len(scene.steps) - 1
        s = min(max(t / scene.dt, 0.0), float(T))
        i = min(int(math.floor(s)), max(T - 1, 0))
        f = s - i if T > 0 else 0.0
        a = coords[scene.steps[i]]
        b = coords[scene.steps[min(i + 1, T)]]
        return a + (b - a) * f
    assert scene.keys is not None
    out = np.empty((scene.num_agents, scene.dim))
    for k, key in enumerate(scene.keys):
        for d in range(scene.dim):
            out[k, d] = np.interp(t, key[:, 0], key[:, 1 + d])
    return out


def _instance_scene(instance: Instance, **fields: Any) -> Scene:
    """A :class:`Scene` of ``instance``'s robots (names, radii in cells, goals, teams)
    and, for TAPF, its teams' targets (drawn in team colours; robots have no own goal);
    ``fields`` are the rest of the scene (title, source, motion, ...)."""
    g = instance.graph
    goals = np.full((instance.num_agents, g.dim), np.nan)
    for k, a in enumerate(instance.agents):
        if a.goal is not None:
            goals[k] = g.coords[int(a.goal)]
    if instance.is_tapf and len(instance.teams) > 1:
        team = np.array([a.team if a.team is not None else 0 for a in instance.agents])
        team_names = [t.name for t in instance.teams]
    else:
        team = np.full(instance.num_agents, -1)
        team_names = []
    scene = Scene(
        graph=g,
        names=[a.name for a in instance.agents],
        radius=np.array([a.kinematics.radius / g.scale for a in instance.agents], dtype=float),
        goals=goals,
        team=team,
        team_names=team_names,
        **fields,
    )
    if instance.is_tapf and instance.teams:
        tg = [(int(v), t) for t, team in enumerate(instance.teams) for v in team.targets]
        if tg:
            scene.targets = g.coords[[v for v, _ in tg]].astype(float)
            scene.target_team = np.array([t for _, t in tg], dtype=np.int64)
    return scene


def scene_from_plan(instance: Instance, plan: Plan, title: str = "") -> Scene:
    """A discrete plan: one step per second, robots resting at their last vertex.

    Example
    -------
    >>> from hierplan_opt.core.graph import Graph
    >>> inst = Instance.mapf(Graph.grid(3, 1), [(0, 0)], [(2, 0)])
    >>> scene_from_plan(inst, Plan.from_paths([[0, 1, 2]])).steps.tolist()
    [[0], [1], [2]]
    """
    if plan.num_agents != instance.num_agents:
        raise InputError(
            f"the plan has {plan.num_agents} paths but the instance {instance.num_agents} agents"
        )
    H = plan.horizon
    K = plan.num_agents
    dtype = np.uint16 if instance.graph.n < 65536 else np.uint32
    steps = np.empty((H + 1, K), dtype=dtype)
    for k, p in enumerate(plan.paths):
        arr = np.asarray(p, dtype=np.int64)
        steps[: len(arr), k] = arr
        steps[len(arr) :, k] = arr[-1]
    return _instance_scene(
        instance,
        title=title or f"{instance.name}: plan, {K} robots, makespan {plan.makespan}",
        source="plan",
        steps=steps,
        stats={"sum_of_costs": plan.sum_of_costs, "makespan": plan.makespan},
    )


def scene_from_schedule(instance: Instance, schedule: Any, title: str = "") -> Scene:
    """A :class:`~hierplan_opt.schedule.Schedule`: way-points, their slack, its clearance.

    Example
    -------
    >>> from hierplan_opt.core.graph import Graph
    >>> from hierplan_opt.schedule import postprocess
    >>> inst = Instance.mapf(Graph.grid(3, 1), [(0, 0)], [(2, 0)])
    >>> sc = scene_from_schedule(inst, postprocess(inst, Plan.from_paths([[0, 1, 2]])))
    >>> sc.keys[0][:, 0].tolist(), sc.slack[0].tolist()
    ([0.0, 1.0, 2.0], [0.0, 0.0, 0.0])
    """
    keys, slack = [], []
    for wp in schedule.waypoints:
        keys.append(np.column_stack([wp.arrival, wp.coords]).astype(float))
        slack.append(np.asarray(wp.latest - wp.arrival, dtype=float))
    return _instance_scene(
        instance,
        title=title
        or f"{instance.name}: {schedule.objective} schedule ({schedule.method}), "
        f"{len(keys)} robots, makespan {schedule.makespan:.4g} s",
        source="schedule",
        keys=keys,
        slack=slack,
        guaranteed=float(schedule.safety_distance) or None,
        margin=float(schedule.margin),
        stats={"makespan": float(schedule.makespan), "flowtime": float(schedule.flowtime)},
    )


def _rows_to_keys(
    path: str | Path, sched: Mapping[str, Any], instance: Instance, kind: str
) -> list[np.ndarray]:
    """Per robot its way-points as rows (arrival, x, y[, z]); a file of another
    instance (other robots, or a robot that does not start at its start) is refused
    as ``simulate`` refuses it."""
    from hierplan_opt.schedule.files import same_agents  # loads MAPF-POST: only here

    same_agents(str(path), "schedule", dict(sched), [a.name for a in instance.agents], kind)
    axes = ("x", "y", "z")[: instance.graph.dim]
    g = instance.graph
    keys = []
    for a in instance.agents:
        rows = sched.get(a.name)
        if not isinstance(rows, list) or not rows:
            raise InputError(f"{path}: no way-points for robot {a.name!r}")
        try:
            arr = np.array([[float(r["arrival"])] + [float(r[c]) for c in axes] for r in rows])
        except (KeyError, TypeError, ValueError):
            raise InputError(
                f"{path}: a way-point of {a.name!r} lacks {', '.join(axes)} or arrival"
            ) from None
        if not np.isfinite(arr).all() or (np.diff(arr[:, 0]) < -1e-9).any():
            raise InputError(f"{path}: the way-points of {a.name!r} are not in time order")
        if not np.allclose(arr[0, 1:], g.coords[a.start], atol=1e-6):
            raise InputError(
                f"{path}: the first way-point of {a.name!r} is not its start "
                f"{g.label(a.start)} (the {kind} does not belong to this instance)"
            )
        keys.append(arr)
    return keys


def _scene_from_rows(
    instance: Instance,
    path: str | Path,
    data: Mapping[str, Any],
    *,
    what: str,
    source: str,
    guarantee_key: str,
    title: str,
    events: list[dict[str, Any]] | None = None,
    with_margin: bool = False,
) -> Scene:
    """The scene of a file whose ``schedule`` mapping holds way-point rows per robot (a
    schedule file or an execution report); ``guarantee_key`` names the statistic that
    holds its guaranteed distance."""
    sched = data.get("schedule")
    if not isinstance(sched, dict):
        raise InputError(f"{path}: not {what} (no 'schedule' mapping)")
    stats = data.get("statistics") or {}
    if not isinstance(stats, dict):
        stats = {}
    keys = _rows_to_keys(path, sched, instance, "report" if source == "execution" else source)
    g = stats.get(guarantee_key)
    return _instance_scene(
        instance,
        title=title or f"{Path(path).name}: {source}, {len(keys)} robots",
        source=source,
        keys=keys,
        events=events if events is not None else [],
        guaranteed=float(g) if isinstance(g, (int, float)) and g > 0 else None,
        margin=float(stats.get("margin", 0.0) or 0.0) if with_margin else 0.0,
        stats={k: v for k, v in stats.items() if isinstance(v, (int, float, str))},
    )


def scene_from_schedule_file(
    instance: Instance, path: str | Path, data: Mapping[str, Any], title: str = ""
) -> Scene:
    """A schedule file as written (arrival times only: no slack without its STN)."""
    return _scene_from_rows(
        instance,
        path,
        data,
        what="a schedule file",
        source="schedule",
        guarantee_key="safety_distance",
        title=title,
        with_margin=True,
    )


def scene_from_report(
    instance: Instance, path: str | Path, data: Mapping[str, Any], title: str = ""
) -> Scene:
    """An execution report (``hierplan simulate/run --out``): the executed way-points,
    the disturbances and the layer that handled each; extra fields are ignored.

    Example
    -------
    >>> from hierplan_opt.core.graph import Graph
    >>> inst = Instance.mapf(Graph.grid(3, 1), [(0, 0)], [(2, 0)])
    >>> rows = [{"x": 0, "y": 0, "arrival": 0.0}, {"x": 2, "y": 0, "arrival": 3.0}]
    >>> ev = [{"time": 1.0, "agent": "agent0", "kind": "stop", "layer": "slack", "new": 1}]
    >>> sc = scene_from_report(inst, "r.yaml", {"schedule": {"agent0": rows}, "events": ev})
    >>> positions_at(sc, 1.5).tolist(), sc.events[0]["layer"]
    ([[1.0, 0.0]], 'slack')
    """
    events = []
    raw = data.get("events") or []
    for e in raw if isinstance(raw, list) else []:
        if not isinstance(e, dict):
            continue
        try:
            t = float(e.get("time", 0.0))
        except (TypeError, ValueError):
            continue
        delay = e.get("delay", 0.0)
        events.append(
            {
                "time": t,
                "agent": str(e.get("agent", "-")),
                "kind": str(e.get("kind", "?")),
                "layer": str(e.get("layer", "none")),
                "delay": float(delay) if isinstance(delay, (int, float)) else 0.0,
                "detail": str(e.get("detail", "")),
            }
        )
    return _scene_from_rows(
        instance,
        path,
        data,
        what="an execution report",
        source="execution",
        guarantee_key="guaranteed_distance",
        title=title,
        events=events,
    )


def scene_from_execution(instance: Instance, ex: Any, title: str = "") -> Scene:
    """An :class:`~hierplan_opt.execution.simulate.Execution` (its executed way-points and
    events), like :func:`scene_from_report` without the file.

    Example
    -------
    >>> from hierplan_opt.core.graph import Graph
    >>> from hierplan_opt.execution import simulate
    >>> from hierplan_opt.schedule import postprocess
    >>> inst = Instance.mapf(Graph.grid(3, 1), [(0, 0)], [(2, 0)])
    >>> ex = simulate(inst, postprocess(inst, Plan.from_paths([[0, 1, 2]])))
    >>> positions_at(scene_from_execution(inst, ex), 0.5).tolist()
    [[0.5, 0.0]]
    """
    keys = [np.asarray(tr, dtype=float) for tr in ex.trajectories]
    st = ex.statistics
    g = st.get("guaranteed_distance")
    scene = _instance_scene(
        instance,
        title=title or f"{instance.name}: execution ({ex.policy}), {len(keys)} robots",
        source="execution",
        keys=keys,
        events=[e.as_dict() for e in ex.log],
        guaranteed=float(g) if isinstance(g, (int, float)) and g > 0 else None,
        margin=float(ex.schedule.margin),
    )
    if len(ex.agent_names) == len(keys):
        scene.names = list(ex.agent_names)
    return scene


def scene_from_trajectories(
    instance: Instance, traj: Any, title: str = "", dt: float = 0.1
) -> Scene:
    """Refined trajectories (:func:`~hierplan_opt.trajectory.result.read_trajectories`),
    sampled every ``dt`` seconds (metres turned back into instance coordinates)."""
    if traj.num_agents != instance.num_agents:
        raise InputError(
            f"the trajectories have {traj.num_agents} robots but the instance "
            f"{instance.num_agents} agents"
        )
    s = traj.sample(dt)
    scale = instance.graph.scale
    keys = [np.column_stack([s["t"], s["pos"][k] / scale]) for k in range(traj.num_agents)]
    return _instance_scene(
        instance,
        title=title or f"{instance.name}: refined trajectories ({traj.mode}), {len(keys)} robots",
        source="trajectories",
        keys=keys,
        guaranteed=float(traj.safety_distance) or None,
        stats={"makespan": float(traj.makespan)},
    )


#: LoRR headings: E, S, W, N (x right, y down); "R" turns clockwise.
_HEADINGS = {"E": (1, 0), "S": (0, 1), "W": (-1, 0), "N": (0, -1)}
_ORDER = "ESWN"
_MOVES = {"U": (0, -1), "D": (0, 1), "L": (-1, 0), "R": (1, 0)}


#: (d_row, d_col) of the LoRR orientation codes 0 E, 1 S, 2 W, 3 N.
_DRC = {0: (0, 1), 1: (1, 0), 2: (0, -1), 3: (-1, 0)}


def _segment_keys(
    graph: Graph, path: str | Path, paths: list[Any], counter: int, max_ticks: int
) -> list[np.ndarray]:
    """Per robot ``(t, x, y)`` keys of Start-Kit 3.x paths: an action takes ``counter``
    ticks (a forward move advances ``1 / counter`` of a cell per tick, a wait pauses it;
    at most ``max_ticks`` ticks, the log's makespan);
    only the ticks where the motion changes are kept."""
    assert graph.shape is not None
    W, H = graph.shape[0], graph.shape[1]
    keys = []
    for i, text in enumerate(paths):
        where = f"{path}: actualPaths[{i}]"
        (r, c, o, cnt), acts = decode_path(str(text), where, max_ticks)
        cur = "T"
        xy = np.empty((len(acts) + 1, 2))
        xy[0] = (c, r)
        for t, a in enumerate(acts):
            if cnt > 0 and cur != "T" and a not in ("W", cur):
                a = cur  # an action in progress finishes first
            if not (cnt > 0 and cur != "T" and a == "W"):
                if a == "F":
                    dr, dc = _DRC[o % 4]
                    nr, nc = r + dr, c + dc
                    if not (0 <= nr < H and 0 <= nc < W) or not graph.passable[nr * W + nc]:
                        raise InputError(
                            f"{path}: robot {i} leaves the free cells at tick {t + 1} "
                            f"(row {nr}, column {nc})"
                        )
                    cnt += 1
                    if cnt >= counter:
                        r, c, cnt, cur = nr, nc, 0, "T"
                    else:
                        cur = "F"
                elif a in ("R", "C"):
                    cnt += 1
                    if cnt >= counter:
                        o, cnt, cur = (o + (1 if a == "R" else 3)) % 4, 0, "T"
                    else:
                        cur = a
            frac = cnt / counter if cur == "F" else 0.0
            dr, dc = _DRC[o % 4]
            xy[t + 1] = (c + dc * frac, r + dr * frac)
        ts = np.arange(len(xy), dtype=float)
        keep = [0]
        if len(xy) > 2:
            v = np.diff(xy, axis=0)
            keep += (np.flatnonzero(np.abs(np.diff(v, axis=0)).max(axis=1) > 1e-12) + 1).tolist()
        keep.append(len(xy) - 1)
        idx = np.unique(np.array(keep, dtype=int))
        keys.append(np.column_stack([ts[idx], xy[idx]]))
    return keys


def scene_from_lorr(
    graph: Graph,
    path: str | Path,
    data: Mapping[str, Any],
    title: str = "",
    counter: int | None = None,
) -> Scene:
    """A LoRR output JSON (``start`` ``[[row, col, heading], ...]``, ``actualPaths`` one
    comma-separated action string per robot): one timestep per second.

    Action model ``MAPF_T`` (the default): ``F`` forward, ``R``/``C`` clockwise /
    counter-clockwise turn, ``W``/``T`` wait; action model ``MAPF``: ``U``/``D``/``L``/
    ``R`` moves and ``W``. The robots' current task location (from ``tasks`` and the
    ``assigned`` events, when present in a form this reader knows) is drawn as the goal.

    Example
    -------
    >>> g = Graph.grid(3, 2)
    >>> log = {"start": [[0, 0, "E"]], "actualPaths": ["F,R,F"], "teamSize": 1}
    >>> scene_from_lorr(g, "log.json", log).steps[:, 0].tolist()
    [0, 1, 1, 4]
    """
    if g_shape := graph.shape:
        if len(g_shape) != 2:
            raise InputError(f"{path}: LoRR logs are for 2D grids")
    else:
        raise InputError(f"{path}: LoRR logs need a grid map (.map)")
    W, H = g_shape
    paths = data.get("actualPaths")
    if isinstance(paths, list) and paths and str(paths[0]).startswith("[("):
        k = counter
        for key in ("agentCounter", "agentMaxCounter"):
            v = data.get(key)
            if k is None and v is not None:
                if not isinstance(v, int) or isinstance(v, bool) or v < 1:
                    raise InputError(f"{path}: {key} must be a positive whole number, got {v!r}")
                k = v
        k = k or 1
        start = data.get("start")
        if isinstance(start, list) and len(start) != len(paths):
            raise InputError(
                f"{path}: 'start' lists {len(start)} robots but 'actualPaths' {len(paths)}"
            )
        span = data.get("makespan")
        cap = span if isinstance(span, int) and not isinstance(span, bool) and span > 0 else 0
        keys = _segment_keys(graph, path, paths, k, cap or MAX_PATH_TICKS)
        n = len(keys)
        plain = {a: b for a, b in data.items() if isinstance(b, (int, float, str))}
        delays = []  # the Start-Kit's delay intervals [start, end) per robot, as disturbances
        given = data.get("delayIntervals")
        for i, ivs in enumerate(parse_delay_intervals(given, n, str(path)) if given else []):
            for s0, e0 in ivs:
                delays.append(
                    {"time": float(s0), "agent": f"r{i}", "kind": "delay", "layer": "none",
                     "delay": float(e0 - s0), "detail": f"held for ticks {s0}..{e0}"}
                )  # fmt: skip
        return Scene(
            title=title or f"{Path(path).name}: lifelong (LoRR 3.x), {n} robots",
            source="lifelong",
            graph=graph,
            names=[f"r{i}" for i in range(n)],
            radius=np.full(n, 0.4),
            goals=np.full((n, 2), np.nan),
            team=np.full(n, -1),
            team_names=[],
            keys=keys,
            events=delays,
            stats=plain,
        )
    starts = data.get("start")
    if not isinstance(starts, list) or not isinstance(paths, list) or len(starts) != len(paths):
        raise InputError(f"{path}: 'start' and 'actualPaths' must be lists of the same length")
    model = str(data.get("actionModel", "MAPF_T"))
    K = len(starts)
    seqs = [str(p).split(",") if str(p) else [] for p in paths]
    T = max((len(s) for s in seqs), default=0)
    dtype = np.uint16 if graph.n < 65536 else np.uint32
    steps = np.empty((T + 1, K), dtype=dtype)
    for k, (st, acts) in enumerate(zip(starts, seqs, strict=True)):
        try:
            row, col = int(st[0]), int(st[1])
            head = _ORDER.index(str(st[2])) if len(st) > 2 else 0
        except (TypeError, ValueError, IndexError):
            raise InputError(f"{path}: start {k} is not [row, col, E|S|W|N]") from None
        x, y = col, row
        if not (0 <= x < W and 0 <= y < H) or not graph.passable[y * W + x]:
            raise InputError(f"{path}: robot {k} starts at row {row}, column {col}, not free")
        steps[0, k] = y * W + x
        for t, a in enumerate(acts):
            a = a.strip()
            if model == "MAPF" and a in _MOVES:
                dx, dy = _MOVES[a]
                x, y = x + dx, y + dy
            elif a == "F":
                dx, dy = _HEADINGS[_ORDER[head]]
                x, y = x + dx, y + dy
            elif a == "R":
                head = (head + 1) % 4
            elif a == "C":
                head = (head - 1) % 4
            elif a not in ("W", "T", ""):
                raise InputError(f"{path}: robot {k}, step {t}: unknown action {a!r}")
            if not (0 <= x < W and 0 <= y < H) or not graph.passable[y * W + x]:
                raise InputError(
                    f"{path}: robot {k} leaves the free cells at step {t + 1} (row {y}, column {x})"
                )
            steps[t + 1, k] = y * W + x
        steps[len(acts) + 1 :, k] = steps[len(acts), k]
    goals = np.full((K, 2), np.nan)
    goals_known = _lorr_goals(data, W, goals)
    events = [
        {
            "time": float(e[2]) if len(e) > 2 else 0.0,
            "agent": str(e[0]),
            "kind": "error",
            "layer": "none",
            "delay": 0.0,
            "detail": str(e[3]) if len(e) > 3 else "",
        }
        for e in data.get("errors") or []
        if isinstance(e, list) and e
    ]
    stats = {
        k: data[k]
        for k in ("numTaskFinished", "sumOfCost", "makespan", "AllValid", "actionModel")
        if k in data and isinstance(data[k], (int, float, str))
    }
    return Scene(
        title=title or f"{Path(path).name}: lifelong (LoRR), {K} robots, {T} steps",
        source="lifelong",
        graph=graph,
        names=[f"r{k}" for k in range(K)],
        radius=np.full(K, 0.4),
        goals=goals if goals_known else np.full((K, 2), np.nan),
        team=np.full(K, -1),
        team_names=[],
        steps=steps,
        events=events,
        stats=stats,
    )


def _lorr_goals(data: Mapping[str, Any], W: int, goals: np.ndarray) -> bool:
    """Fill ``goals`` with each robot's last assigned task location (tasks ``[id, row,
    col]`` or ``[id, loc, ...]``, events per robot ``[task, t, "assigned"]``)."""
    tasks = data.get("tasks")
    events = data.get("events")
    if not isinstance(tasks, list) or not isinstance(events, list) or len(events) != len(goals):
        return False
    where: dict[int, tuple[int, int]] = {}
    for task in tasks:
        if isinstance(task, list) and len(task) >= 3 and all(isinstance(v, int) for v in task[:3]):
            where[task[0]] = (task[2], task[1])  # (x, y) from [id, row, col]
        elif isinstance(task, list) and len(task) == 2 and all(isinstance(v, int) for v in task):
            where[task[0]] = (task[1] % W, task[1] // W)
    found = False
    for k, evs in enumerate(events):
        if not isinstance(evs, list):
            continue
        for e in evs:
            if (
                isinstance(e, list)
                and len(e) >= 3
                and isinstance(e[0], int)
                and e[2] == "assigned"
                and e[0] in where
            ):
                goals[k] = where[e[0]]
                found = True
    return found


def read_lorr(path: str | Path) -> dict[str, Any]:
    """Parse a LoRR output JSON (one-line errors for anything else): :func:`hierplan_opt.
    io.lorr.read_log`, the one reader of the layout."""
    return read_log(path)


def closest_pairs(scene: Scene, samples: int = 300) -> dict[str, list[float] | list[int]]:
    """At ``samples`` times: the pair of robots with the least clearance left
    (centre distance minus ``r_i + r_j + margin``), its distance and required distance
    (metres). KD-tree on each sample, so 10,000 robots stay fast.

    Example
    -------
    >>> from hierplan_opt.core.graph import Graph
    >>> inst = Instance.mapf(Graph.grid(3, 2), [(0, 0), (0, 1)], [(2, 0), (2, 1)])
    >>> c = closest_pairs(scene_from_plan(inst, Plan.from_paths([[0, 1, 2], [3, 4, 5]])), 3)
    >>> c["distance"], c["i"], c["j"]
    ([1.0, 1.0, 1.0], [0, 0, 0], [1, 1, 1])
    """
    from scipy.spatial import cKDTree  # heavy module: scipy

    K = scene.num_agents
    out: dict[str, list[Any]] = {"time": [], "distance": [], "required": [], "i": [], "j": []}
    if K < 2:
        return out
    times = np.linspace(0.0, max(scene.end, 1e-9), max(2, samples))
    rad = scene.radius * scene.scale
    kq = min(K, 6)

    for n, t in enumerate(times):
        tick("clearance samples", n, len(times))
        p = positions_at(scene, float(t)) * scene.scale
        dq, iq = cKDTree(p).query(p, k=kq)
        d, idx = np.asarray(dq)[:, 1:], np.asarray(iq)[:, 1:]
        req = rad[:, None] + rad[idx] + scene.margin
        left = d - req
        a = int(np.argmin(left.min(axis=1)))
        b = int(np.argmin(left[a]))
        j = int(idx[a, b])
        out["time"].append(round(float(t), 6))
        out["distance"].append(round(float(d[a, b]), 6))
        out["required"].append(round(float(req[a, b]), 6))
        out["i"].append(min(a, j))
        out["j"].append(max(a, j))
    return out


__all__ = [
    "LAYER_COLORS",
    "Scene",
    "closest_pairs",
    "is_lorr",
    "positions_at",
    "read_lorr",
    "scene_from_lorr",
    "scene_from_plan",
    "scene_from_execution",
    "scene_from_report",
    "scene_from_schedule",
    "scene_from_schedule_file",
    "scene_from_trajectories",
]
