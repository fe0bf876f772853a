"""libMultiRobotPlanning YAML instances (Hönig et al.).

::

    map:
      dimensions: [5, 2]            # [W, H]
      obstacles: [[0, 1], [1, 1]]   # optional
    agents:
      - {name: agent0, start: [0, 0], goal: [4, 0]}
      - {name: agent1, start: [1, 0], potentialGoals: [[3, 0], [2, 0]]}

Roadmaps (``cbs_roadmap``) replace ``map`` with ``roadmap``; locations are vertex
names::

    roadmap:
      undirected: true              # default true
      allow_wait_actions: true      # default true; false needs a self-edge [v, v] at
                                    # every vertex (this toolkit always lets robots wait)
      vertices: {A: [0, 0], B: [1, 0], C: [2, 0]}   # optional positions
      edges: [[A, B], [B, C]]
    agents:
      - {name: agent0, start: A, goal: C}

Without ``vertices`` the vertices are the edges' ends, every edge has length 1 and
there are no positions (all coordinates 0): fine for planning, not for MAPF-POST.
Annotated roadmaps (``conflicts``: for each edge in file order, the edges no second
robot may traverse at the same time, as libMRP's ``annotate_roadmap.py`` writes them, with
self-edges for waits) are read; the pairs this toolkit's vertex and swap rules do not cover
go to ``instance.meta["edge_conflicts"]`` (vertex ids), which the ``cpsat`` and ``mip``
formulations honour (:func:`hierplan_opt.solve` refuses other solvers for them).

``potentialGoals`` (the target-assignment variant, ``cbs_ta``) becomes a TAPF
instance: agents with the same set of potential goals form one team whose targets are
that set. This toolkit's teams need disjoint target sets with as many targets as
robots, so sets that overlap without being equal, or that have more goals than the
agents sharing them, are refused. An agent with a plain ``goal`` next to agents with
``potentialGoals`` is a team of one. An agent with an empty ``potentialGoals`` is a
task-free robot (it ends anywhere, keeping out of the others' way): a team of one with a
placeholder target (its start where free), listed in ``instance.meta["free_agents"]``;
:func:`hierplan_opt.solve` and ``hierplan solve`` choose its end
(:mod:`hierplan_opt.search.libmrp`).
"""

from __future__ import annotations

import math
from dataclasses import replace
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from hierplan_opt.core.errors import InputError
from hierplan_opt.core.graph import Graph
from hierplan_opt.core.instance import DEFAULT_KINEMATICS, Agent, Instance, Team
from hierplan_opt.io._common import Unique, check_grid, location, wrap
from hierplan_opt.io.files import write_text
from hierplan_opt.io.values import plain
from hierplan_opt.io.yaml import Ctx, read_yaml, yaml_scalar

TOP_KEYS = ("map", "agents")
MAP_KEYS = ("dimensions", "obstacles")
ROADMAP_KEYS = ("undirected", "allow_wait_actions", "vertices", "edges", "conflicts")
AGENT_KEYS = ("name", "start", "goal", "potentialGoals")


def load(path: str | Path) -> Instance:
    """Read a libMultiRobotPlanning instance file.

    Example
    -------
    >>> import os, tempfile
    >>> f = os.path.join(tempfile.mkdtemp(), "corridor.yaml")
    >>> _ = open(f, "w").write('''
    ... map: {dimensions: [5, 2], obstacles: [[0, 1], [1, 1], [3, 1], [4, 1]]}
    ... agents:
    ...   - {name: agent0, start: [0, 0], goal: [4, 0]}
    ...   - {name: agent1, start: [1, 0], goal: [3, 0]}
    ... ''')
    >>> load(f).soc_lower_bound()
    6
    """
    return from_data(read_yaml(path), path)


def from_data(data: Any, path: str | Path, *, shared_goals: bool = False) -> Instance:
    """Build the instance from parsed YAML (``path`` names the file in errors).

    Example
    -------
    >>> data = {"map": {"dimensions": [3, 1]},
    ...         "agents": [{"name": "a", "start": [0, 0], "goal": [2, 0]}]}
    >>> from_data(data, "inline.yaml").agents[0].name
    'a'
    """
    ctx = Ctx(path)
    top = ctx.mapping(data, "a libMultiRobotPlanning instance", 1)
    if "roadmap" in top:
        ctx.check_keys(top, "the instance", ("roadmap", "agents"), ("roadmap", "agents"))
        graph, annotated = _roadmap(ctx, top["roadmap"], ctx.line_of(top, "roadmap"))
    else:
        ctx.check_keys(top, "the instance", TOP_KEYS, TOP_KEYS)
        graph, annotated = _grid(ctx, top["map"], ctx.line_of(top, "map")), None

    agents_raw = ctx.sequence(top["agents"], "agents", ctx.line_of(top, "agents"))
    if not agents_raw:
        raise ctx.error("the instance has no agents", agents_raw.line or None)
    names: dict[str, int] = {}
    starts = Unique(ctx, graph, "start")
    goals = Unique(ctx, graph, "goal")
    rows: list[tuple[str, int, tuple[int, ...], bool, int | None]] = []
    free: list[int] = []  # rows of task-free robots (empty potentialGoals)
    for i, a in enumerate(agents_raw):
        aline = ctx.line_of(agents_raw, i)
        a = ctx.mapping(a, f"agent {i}", aline)
        ctx.check_keys(a, f"agent {i}", AGENT_KEYS, ("start",))
        name = (
            ctx.string(a["name"], "agent name", ctx.line_of(a, "name"))
            if "name" in a
            else f"agent{i}"
        )
        if name in names:
            raise ctx.error(f"agent name {name!r} is used twice", ctx.line_of(a, "name"))
        names[name] = i
        start = location(ctx, graph, a["start"], f"agent {name!r} start", ctx.line_of(a, "start"))
        starts.add(start, f"agent {name!r}", ctx.line_of(a, "start"))
        if "goal" in a and "potentialGoals" in a:
            raise ctx.error(f"agent {name!r} has both 'goal' and 'potentialGoals'", aline)
        if "goal" in a:
            gline = ctx.line_of(a, "goal")
            g = location(ctx, graph, a["goal"], f"agent {name!r} goal", gline)
            rows.append((name, start, (g,), False, gline))
        elif "potentialGoals" in a:
            pline = ctx.line_of(a, "potentialGoals")
            pg = ctx.sequence(a["potentialGoals"], f"potentialGoals of {name!r}", pline)
            if not pg:  # a task-free robot: its end is chosen by the solve
                free.append(len(rows))
                rows.append((name, start, (), True, pline))
                continue
            targets: list[int] = []
            for j, loc in enumerate(pg):
                v = location(ctx, graph, loc, f"agent {name!r} potential goal", ctx.line_of(pg, j))
                if v in targets:
                    raise ctx.error(
                        f"potentialGoals of agent {name!r} lists {graph.label(v)} twice",
                        ctx.line_of(pg, j),
                    )
                targets.append(v)
            rows.append((name, start, tuple(targets), True, pline))
        else:
            raise ctx.error(f"agent {name!r} needs 'goal' or 'potentialGoals'", aline)

    if free:
        _placeholders(ctx, graph, rows, free)
    if not any(r[3] for r in rows):  # plain MAPF
        for name, _s, (g,), _p, gline in rows:
            if not shared_goals:  # allowed for agents that disappear at their goals
                goals.add(g, f"agent {name!r}", gline)
        agents = tuple(Agent(n, s, gs[0]) for n, s, gs, _p, _l in rows)
        inst = wrap(ctx, None, lambda: Instance(graph, agents, name=Path(path).stem))
    else:
        inst = _tapf(ctx, graph, rows, Path(path).stem)
    inst.meta.update({"format": "lmrp", "source": str(path)})
    if annotated is not None:
        extra = extra_conflicts(graph, annotated)
        inst.meta["annotated_conflicts"] = len(annotated)
        inst.meta["edge_conflicts"] = extra
    if free:
        inst.meta["free_agents"] = [rows[i][0] for i in free]
    return inst


def extra_conflicts(
    graph: Graph, pairs: list[tuple[tuple[str, str], tuple[str, str]]]
) -> list[tuple[tuple[int, int], tuple[int, int]]]:
    """The conflicting move pairs (``(u, v)`` vertex ids, ``u == v`` a wait) that this
    toolkit's own rules (vertex and swap conflicts) do not already forbid.

    Example
    -------
    >>> g = Graph.roadmap({"A": (0, 0), "B": (1, 0), "C": (2, 0)}, [("A", "B"), ("B", "C")])
    >>> extra_conflicts(g, [(("A", "B"), ("B", "A")), (("A", "B"), ("B", "C"))])
    [((0, 1), (1, 2))]
    """
    out = []
    for (a, b), (c, d) in pairs:
        (u1, v1), (u2, v2) = (graph.vertex(a), graph.vertex(b)), (graph.vertex(c), graph.vertex(d))
        if u1 == u2 or v1 == v2 or (u1 == v2 and v1 == u2):
            continue  # one vertex at one time, or a swap: forbidden anyway
        out.append(((u1, v1), (u2, v2)))
    return out


def _placeholders(
    ctx: Ctx,
    graph: Graph,
    rows: list[tuple[str, int, tuple[int, ...], bool, int | None]],
    free: list[int],
) -> None:
    """Give each task-free robot a team of its own with one placeholder target: its
    start, or the nearest vertex no other robot may end at. The solve chooses its real
    end (:mod:`hierplan_opt.search.libmrp`); the placeholder only keeps teams well-formed."""
    used = {t for i, r in enumerate(rows) if i not in free for t in r[2]}
    for i in free:
        name, start, _t, _p, line = rows[i]
        d = graph.dist_from(start)
        options = sorted(
            (int(d[v]), v) for v in range(graph.n) if graph.passable[v] and v not in used
        )
        if not options:
            raise ctx.error(f"task-free robot {name!r} has no vertex left to end at", line)
        v = start if start not in used else options[0][1]
        used.add(v)
        rows[i] = (name, start, (v,), True, line)


def _grid(ctx: Ctx, value: Any, line: int | None) -> Graph:
    m = ctx.mapping(value, "map", line)
    ctx.check_keys(m, "map", MAP_KEYS, ("dimensions",))
    dline = ctx.line_of(m, "dimensions")
    dims = ctx.sequence(m["dimensions"], "map dimensions", dline)
    if len(dims) != 2:
        raise ctx.error(f"map dimensions must be [W, H], got {list(dims)}", dline)
    width, height = (ctx.integer(d, "a map dimension", dline, minimum=1) for d in dims)
    check_grid(ctx, [width, height], dline)
    obstacles: list[tuple[int, int]] = []
    if m.get("obstacles") is not None:
        obs = ctx.sequence(m["obstacles"], "map obstacles", ctx.line_of(m, "obstacles"))
        for i, o in enumerate(obs):
            oline = ctx.line_of(obs, i)
            if not isinstance(o, list) or len(o) != 2:
                raise ctx.error(f"an obstacle must be [x, y], got {o!r}", oline)
            x, y = (ctx.integer(c, "an obstacle coordinate", oline) for c in o)
            if not (0 <= x < width and 0 <= y < height):
                raise ctx.error(f"obstacle [{x}, {y}] is outside the {width}x{height} map", oline)
            obstacles.append((x, y))
    return Graph.grid(width, height, obstacles=obstacles)


def _roadmap(
    ctx: Ctx, value: Any, line: int | None
) -> tuple[Graph, list[tuple[tuple[str, str], tuple[str, str]]] | None]:
    r = ctx.mapping(value, "roadmap", line)
    ctx.check_keys(r, "roadmap", ROADMAP_KEYS, ("edges",))
    undirected = True
    if "undirected" in r:
        undirected = ctx.boolean(r["undirected"], "undirected", ctx.line_of(r, "undirected"))
    waits = True
    if "allow_wait_actions" in r:
        waits = ctx.boolean(
            r["allow_wait_actions"], "allow_wait_actions", ctx.line_of(r, "allow_wait_actions")
        )
    coords: dict[str, list[float]] = {}
    positions = r.get("vertices") is not None
    if positions:
        vline = ctx.line_of(r, "vertices")
        verts = ctx.mapping(r["vertices"], "vertices", vline)
        for key, c in verts.items():
            vl = verts.lines.get(key, vline)
            vname = ctx.string(key, "a vertex name", vl)
            if not isinstance(c, list) or len(c) not in (2, 3):
                raise ctx.error(f"vertex {vname!r} needs [x, y] or [x, y, z], got {c!r}", vl)
            coords[vname] = [ctx.number(x, f"a coordinate of vertex {vname!r}", vl) for x in c]
    eline = ctx.line_of(r, "edges")
    elist = ctx.sequence(r["edges"], "edges", eline)
    edges: list[tuple[Any, ...]] = []
    self_loops: set[str] = set()
    listed: list[tuple[str, str]] = []  # every edge in file order (conflicts index them)
    for i, e in enumerate(elist):
        el = ctx.line_of(elist, i)
        if not isinstance(e, list) or len(e) != 2:
            raise ctx.error(f"an edge must be [u, v], got {e!r}", el)
        u, v = (ctx.string(x, "an edge end", el) for x in e)
        listed.append((u, v))
        for x in (u, v):
            if x not in coords:
                if positions:
                    raise ctx.error(f"edge [{u}, {v}] names unknown vertex {x!r}", el)
                coords[x] = [0.0, 0.0]
        if u == v:
            self_loops.add(u)  # a wait action
            continue
        edges.append((u, v) if positions else (u, v, 1.0))
    if not coords:
        raise ctx.error("a roadmap needs at least one vertex", eline)
    if not waits:
        missing = [x for x in coords if x not in self_loops]
        if missing:
            raise ctx.error(
                f"allow_wait_actions is false and vertex {missing[0]!r} has no self-edge; "
                "this toolkit always lets robots wait",
                ctx.line_of(r, "allow_wait_actions"),
            )
    graph = wrap(ctx, eline, lambda: Graph.roadmap(coords, edges, directed=not undirected))
    if r.get("conflicts") is None:
        return graph, None
    return graph, _conflicts(ctx, r["conflicts"], listed, ctx.line_of(r, "conflicts"))


def _conflicts(
    ctx: Ctx, value: Any, listed: list[tuple[str, str]], line: int | None
) -> list[tuple[tuple[str, str], tuple[str, str]]]:
    """The ``conflicts`` of an annotated roadmap (libMRP's ``annotate_roadmap.py``): for
    edge ``i`` in file order, the edges ``j`` that no two robots may traverse at once."""
    rows = ctx.sequence(value, "conflicts", line)
    if len(rows) != len(listed):
        raise ctx.error(
            f"conflicts has {len(rows)} entries for {len(listed)} edges (one list per edge)", line
        )
    pairs: set[tuple[int, int]] = set()
    for i, row in enumerate(rows):
        rl = ctx.line_of(rows, i)
        for j in ctx.sequence(row, f"conflicts of edge {i}", rl):
            jj = ctx.integer(j, f"an edge index in the conflicts of edge {i}", rl, minimum=0)
            if jj >= len(listed):
                raise ctx.error(
                    f"conflicts of edge {i} name edge {jj} (there are {len(listed)})", rl
                )
            pairs.add((min(i, jj), max(i, jj)))
    return [(listed[i], listed[j]) for i, j in sorted(pairs)]


def _tapf(
    ctx: Ctx,
    graph: Graph,
    rows: list[tuple[str, int, tuple[int, ...], bool, int | None]],
    stem: str,
) -> Instance:
    groups: dict[frozenset[int], list[int]] = {}
    owner: dict[int, frozenset[int]] = {}
    for i, (name, _s, targets, _p, line) in enumerate(rows):
        key = frozenset(targets)
        for t in targets:
            other = owner.get(t)
            if other is not None and other != key:
                first = rows[groups[other][0]][0]
                raise ctx.error(
                    f"agent {name!r} shares the goal {graph.label(t)} with agent {first!r} "
                    "but their goal sets differ; this toolkit's teams need equal or "
                    "disjoint goal sets",
                    line,
                )
            owner[t] = key
        groups.setdefault(key, []).append(i)
    agents: list[Agent] = []
    teams: list[Team] = []
    order = [i for members in groups.values() for i in members]
    new_index = {old: new for new, old in enumerate(order)}
    for ti, (key, members) in enumerate(groups.items()):
        if len(key) != len(members):
            first = rows[members[0]]
            who = ", ".join(repr(rows[i][0]) for i in members[:3])
            more = " ..." if len(members) > 3 else ""
            raise ctx.error(
                f"agents {who}{more} share {len(key)} potential goals but are "
                f"{len(members)} agents; this toolkit's teams need as many goals as robots",
                first[4],
            )
        targets = rows[members[0]][2]  # in the file order of the first member
        for i in members:
            agents.append(Agent(rows[i][0], rows[i][1], None, ti))
        teams.append(Team(f"team{ti}", tuple(new_index[i] for i in members), targets))
    return wrap(ctx, None, lambda: Instance(graph, tuple(agents), tuple(teams), name=stem))


# ---------------------------------------------------------------- writing
def without_extras(instance: Instance) -> tuple[Instance, list[str]]:
    """``instance`` without what the libMultiRobotPlanning format cannot carry (highways,
    robot kinematics), and one phrase per thing left out (empty: nothing is lost).

    Example
    -------
    >>> g = Graph.grid(2, 1)
    >>> inst = Instance.mapf(g, [(0, 0)], [(1, 0)], highways=[((0, 0), (1, 0))])
    >>> plain, lost = without_extras(inst)
    >>> plain.highways, lost
    (None, ['highways (1 preferred directed edges)'])
    """
    lost: list[str] = []
    if instance.highways is not None:
        lost.append(f"highways ({len(instance.highways)} preferred directed edges)")
        instance = replace(instance, highways=None)
    moved = [a for a in instance.agents if a.kinematics != DEFAULT_KINEMATICS]
    if moved:
        lost.append(f"robot kinematics (of {len(moved)} robots)")
        agents = tuple(replace(a, kinematics=DEFAULT_KINEMATICS) for a in instance.agents)
        instance = replace(instance, agents=agents)
    return instance, lost


def dumps(instance: Instance) -> str:
    """The libMultiRobotPlanning YAML text of an instance on a 2D grid or a roadmap.

    TAPF teams become ``potentialGoals`` (every robot lists its team's targets).
    Refuses what the format cannot hold: 3D grids, highways, kinematics, a cell size
    other than 1, roadmap edges whose length is not the distance of their ends.

    Example
    -------
    >>> g = Graph.grid(2, 1)
    >>> print(dumps(Instance.mapf(g, [(0, 0)], [(1, 0)])), end="")
    map:
      dimensions: [2, 1]
      obstacles: []
    agents:
      - name: agent0
        start: [0, 0]
        goal: [1, 0]
    """
    g = instance.graph
    if g.kind == "grid" and (g.shape is None or len(g.shape) != 2):
        raise InputError("the libMultiRobotPlanning format holds 2D grids and roadmaps, not 3D")
    if instance.highways is not None:
        raise InputError(
            "the libMultiRobotPlanning format has no highways; use the hierplan format"
        )
    if any(a.kinematics != DEFAULT_KINEMATICS for a in instance.agents):
        raise InputError(
            "the libMultiRobotPlanning format has no robot kinematics; use the hierplan format"
        )
    loc = partial(g.label, quote=yaml_scalar)  # reads back as the same location
    lines = _roadmap_lines(g) if g.kind == "roadmap" else _map_lines(g)
    lines.append("agents:")
    free = set(instance.meta.get("free_agents", ()))
    for a in instance.agents:
        lines.append(f"  - name: {yaml_scalar(a.name)}")
        lines.append(f"    start: {loc(a.start)}")
        if a.name in free:  # a task-free robot (its goal is a placeholder)
            lines.append("    potentialGoals: []")
        elif a.team is None:
            assert a.goal is not None
            lines.append(f"    goal: {loc(a.goal)}")
        else:
            targets = instance.teams[a.team].targets
            lines.append(f"    potentialGoals: [{', '.join(loc(t) for t in targets)}]")
    return "\n".join(lines) + "\n"


def _map_lines(g: Graph) -> list[str]:
    if g.cell_size != 1.0:
        raise InputError(
            "the libMultiRobotPlanning format has no cell_size; use the hierplan format"
        )
    assert g.shape is not None
    width, height = g.shape
    lines = ["map:", f"  dimensions: [{width}, {height}]"]
    blocked = [v for v in range(g.n) if not g.passable[v]]
    if blocked:
        lines.append("  obstacles:")
        lines += [f"    - {g.label(v)}" for v in blocked]
    else:
        lines.append("  obstacles: []")
    return lines


def _roadmap_lines(g: Graph) -> list[str]:
    assert g.names is not None
    lines = [
        "roadmap:",
        f"  undirected: {'false' if g.directed else 'true'}",
        "  allow_wait_actions: true",
        "  vertices:",
    ]
    for v, vname in enumerate(g.names):
        c = ", ".join(repr(float(x)) for x in g.coords[v])
        lines.append(f"    {yaml_scalar(vname)}: [{c}]")
    edges = []
    for u, v in g.edges():
        if not g.directed and u > v:
            continue
        euclid = math.dist(g.coords[u].tolist(), g.coords[v].tolist())
        if abs(g.edge_length(u, v) - euclid) > 1e-12 * max(1.0, euclid):
            raise InputError(
                f"edge [{g.names[u]}, {g.names[v]}] has a length other than the distance of "
                "its ends; the libMultiRobotPlanning format has no edge lengths"
            )
        edges.append(f"    - [{yaml_scalar(g.names[u])}, {yaml_scalar(g.names[v])}]")
    return [*lines, "  edges:", *edges] if edges else [*lines, "  edges: []"]


def save(path: str | Path, instance: Instance) -> None:
    """Write ``instance`` as a libMultiRobotPlanning YAML file.

    Example
    -------
    >>> import os, tempfile
    >>> f = os.path.join(tempfile.mkdtemp(), "x.yaml")
    >>> save(f, Instance.mapf(Graph.grid(2, 1), [(0, 0)], [(1, 0)]))
    >>> load(f).num_agents
    1
    """
    write_text(path, dumps(instance))


def looks_like(data: Any) -> bool:
    """Whether parsed YAML has the top-level keys of this format.

    Example
    -------
    >>> looks_like({"map": {}, "agents": []}), looks_like({"graph": {}})
    (True, False)
    >>> looks_like({"roadmap": {}, "agents": []})
    True
    """
    if not isinstance(data, dict) or "agents" not in data:
        return False
    return "map" in data or "roadmap" in data


# ---------------------------------------------------------------- schedules
def schedule_document(schedule: Any) -> dict[str, Any]:
    """A MAPF-POST schedule in the layout libMultiRobotPlanning's ``visualize.py`` animates.

    ``schedule`` is a :class:`~hierplan_opt.schedule.Schedule` (anything with
    ``to_dict()``) or the plain data of a schedule file
    (:func:`~hierplan_opt.schedule.read_schedule`). Every way-point becomes
    ``{x, y, [z,] t}`` with ``t`` its arrival time in seconds; the visualiser moves a
    robot in a straight line between consecutive way-points, as the schedule means.

    Example
    -------
    >>> doc = {"statistics": {"makespan": 2.5},
    ...        "schedule": {"a": [{"x": 0, "y": 0, "theta": 0.0, "arrival": 0.0},
    ...                           {"x": 1, "y": 0, "theta": 0.0, "arrival": 2.5}]}}
    >>> schedule_document(doc)["schedule"]["a"][1]
    {'x': 1, 'y': 0, 't': 2.5}
    """
    data = schedule.to_dict() if hasattr(schedule, "to_dict") else schedule
    if not isinstance(data, dict) or not isinstance(data.get("schedule"), dict):
        raise InputError("not a schedule: expected {statistics: ..., schedule: {agent: [...]}}")
    out: dict[str, list[dict[str, Any]]] = {}
    for name, points in data["schedule"].items():
        if not isinstance(points, list):
            raise InputError(f"schedule of {name!r} must be a list of way-points")
        rows = []
        for k, p in enumerate(points):
            if not isinstance(p, dict) or "arrival" not in p or "x" not in p or "y" not in p:
                raise InputError(f"way-point {k} of {name!r} needs x, y and arrival")
            row = {a: p[a] for a in ("x", "y", "z") if a in p}
            row["t"] = p["arrival"]
            rows.append(row)
        out[str(name)] = rows
    stats = data.get("statistics") or {}
    return {"statistics": dict(stats), "schedule": out}


def save_schedule(path: str | Path, schedule: Any) -> None:
    """Write :func:`schedule_document` of ``schedule`` as YAML (atomically).

    Example
    -------
    >>> import os, tempfile
    >>> f = os.path.join(tempfile.mkdtemp(), "anim.yaml")
    >>> save_schedule(f, {"schedule": {"a": [{"x": 0, "y": 0, "arrival": 0.0}]}})
    >>> print(open(f).read(), end="")
    statistics: {}
    schedule:
      a:
      - {x: 0, y: 0, t: 0.0}
    """
    doc = schedule_document(schedule)
    stats = {"statistics": plain(doc["statistics"])}
    lines = [yaml.safe_dump(stats, sort_keys=False).rstrip()]
    lines.append("schedule:")
    for name, rows in doc["schedule"].items():
        lines.append(f"  {yaml_scalar(name)}:")
        for r in rows:
            lines.append("  - {" + ", ".join(f"{k}: {_number(v)}" for k, v in r.items()) + "}")
    write_text(path, "\n".join(lines) + "\n")


def _number(v: Any) -> str:
    if isinstance(v, bool) or not isinstance(v, (int, float, np.integer, np.floating)):
        raise InputError(f"a way-point coordinate or time must be a number, got {v!r}")
    if isinstance(v, (int, np.integer)):
        return str(int(v))
    f = float(v)
    if not math.isfinite(f):
        raise InputError(f"a way-point coordinate or time is not finite: {f!r}")
    return repr(f)
