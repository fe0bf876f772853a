"""The hierplan instance format (YAML): grids 2D/3D, roadmaps, teams, kinematics, highways.

The format is specified in ``docs/yaml-format.md``. In short::

    format: hierplan/1                 # optional
    name: corridor                     # optional (default: file stem)
    graph: {type: grid, dimensions: [5, 2], obstacles: [[0, 1], [1, 1]]}
    robot_types: {youbot: {drive: omni, v_max: 0.8}}
    agents: [{name: agent0, start: [0, 0], goal: [4, 0], type: youbot}]
    # or teams: [{name: t1, agents: [{start: [0, 0]}], targets: [[4, 0]]}]
    highways: [[[0, 0], [1, 0]]]

Unknown keys anywhere are refused; every error names ``file:line:``.
"""

from __future__ import annotations

import math
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np

from hierplan_opt.core.graph import Graph
from hierplan_opt.core.instance import DEFAULT_KINEMATICS, DRIVES, Agent, Instance, Kinematics, Team
from hierplan_opt.io._common import Unique, check_grid, location, wrap
from hierplan_opt.io.files import write_text
from hierplan_opt.io.movingai import blocked_cells, load_map
from hierplan_opt.io.yaml import Ctx, LDict, read_yaml, yaml_scalar

FORMAT_TAG = "hierplan/1"
TOP_KEYS = ("format", "name", "graph", "robot_types", "agents", "teams", "highways")
GRID_KEYS = ("type", "dimensions", "obstacles", "rows", "map", "cell_size")
ROADMAP_KEYS = ("type", "directed", "vertices", "edges")
TYPE_KEYS = ("drive", "v_max", "omega_max", "a_max", "radius")
AGENT_KEYS = ("name", "start", "goal", "type")
TEAM_KEYS = ("name", "type", "agents", "targets")
ROBOT_KEYS = ("name", "start", "type")


def load(path: str | Path) -> Instance:
    """Read a hierplan YAML instance file.

    Example
    -------
    >>> import os, tempfile
    >>> f = os.path.join(tempfile.mkdtemp(), "rm.yaml")
    >>> _ = open(f, "w").write('''
    ... graph:
    ...   type: roadmap
    ...   vertices: {A: [0, 0], B: [1, 0], C: [2, 0]}
    ...   edges: [[A, B], [B, C]]
    ... teams:
    ...   - {name: t, agents: [{start: A}, {start: B}], targets: [B, C]}
    ... ''')
    >>> inst = load(f)
    >>> inst.is_tapf, [a.name for a in inst.agents], inst.makespan_lower_bound()
    (True, ['agent0', 'agent1'], 1)
    """
    return from_data(read_yaml(path), path)


def looks_like(data: Any) -> bool:
    """Whether parsed YAML has this format's top-level ``graph:`` key.

    Example
    -------
    >>> looks_like({"graph": {}}), looks_like({"map": {}, "agents": []})
    (True, False)
    """
    return isinstance(data, dict) and "graph" in data


def from_data(data: Any, path: str | Path) -> Instance:
    """Build the instance from parsed YAML (``path`` names the file in errors).

    Example
    -------
    >>> data = {"graph": {"type": "grid", "dimensions": [3, 1]},
    ...         "agents": [{"start": [0, 0], "goal": [2, 0]}]}
    >>> from_data(data, "inline.yaml").name
    'inline'
    """
    ctx = Ctx(path)
    top = ctx.mapping(data, "a hierplan instance", 1)
    ctx.check_keys(top, "the instance", TOP_KEYS, ("graph",))
    if "format" in top and top["format"] != FORMAT_TAG:
        raise ctx.error(
            f"format must be {FORMAT_TAG!r}, got {top['format']!r}", ctx.line_of(top, "format")
        )
    name = (
        ctx.string(top["name"], "name", ctx.line_of(top, "name"))
        if "name" in top
        else Path(path).stem
    )
    graph = _graph(ctx, top["graph"], ctx.line_of(top, "graph"), Path(path))
    types = _robot_types(ctx, top.get("robot_types"), ctx.line_of(top, "robot_types"))
    has_agents, has_teams = "agents" in top, "teams" in top
    if has_agents == has_teams:
        raise ctx.error(
            "give either 'agents' (MAPF) or 'teams' (TAPF)" + (", not both" if has_agents else ""),
            top.key_lines.get("teams", top.line) if has_teams else top.line,
        )
    if has_agents:
        agents, teams = _agents(ctx, graph, types, top["agents"], ctx.line_of(top, "agents"))
    else:
        agents, teams = _teams(ctx, graph, types, top["teams"], ctx.line_of(top, "teams"))
    highways = None
    if "highways" in top and top["highways"] is not None:
        highways = _highways(ctx, graph, top["highways"], ctx.line_of(top, "highways"))
    inst = wrap(ctx, None, lambda: Instance(graph, agents, teams, highways, name))
    inst.meta.update({"format": "hierplan", "source": str(path)})
    free = [
        a.name for a, raw in zip(agents, top.get("agents") or [], strict=False) if "goal" not in raw
    ]
    if has_agents and free:  # task-free robots (hierplan_opt.search.libmrp)
        inst.meta["free_agents"] = free
    return inst


# ---------------------------------------------------------------- graph
def _graph(ctx: Ctx, value: Any, line: int | None, path: Path) -> Graph:
    g = ctx.mapping(value, "graph", line)
    kind = g.get("type", "roadmap" if "vertices" in g else "grid")
    if kind == "grid":
        return _grid(ctx, g, path)
    if kind == "roadmap":
        return _roadmap(ctx, g)
    raise ctx.error(f"graph type must be 'grid' or 'roadmap', got {kind!r}", ctx.line_of(g, "type"))


def _grid(ctx: Ctx, g: LDict, path: Path) -> Graph:
    ctx.check_keys(g, "a grid graph", GRID_KEYS)
    given = [k for k in ("dimensions", "rows", "map") if k in g]
    if len(given) != 1:
        raise ctx.error(
            "a grid graph needs exactly one of 'dimensions', 'rows' or 'map'"
            + (f" (got {', '.join(given)})" if given else ""),
            g.line,
        )
    if "obstacles" in g and "dimensions" not in g:
        raise ctx.error("'obstacles' goes with 'dimensions', not with 'rows' or 'map'", g.line)
    cell = 1.0
    if "cell_size" in g:
        cell = ctx.number(g["cell_size"], "cell_size", ctx.line_of(g, "cell_size"), positive=True)
    if "dimensions" in g:
        dline = ctx.line_of(g, "dimensions")
        dims = ctx.sequence(g["dimensions"], "dimensions", dline)
        if len(dims) not in (2, 3):
            raise ctx.error(f"dimensions must be [W, H] or [W, H, D], got {list(dims)}", dline)
        size = [ctx.integer(d, "a grid dimension", dline, minimum=1) for d in dims]
        check_grid(ctx, size, dline)
        obstacles: list[tuple[int, ...]] = []
        if g.get("obstacles") is not None:
            oline = ctx.line_of(g, "obstacles")
            obs = ctx.sequence(g["obstacles"], "obstacles", oline)
            form = "[x, y]" if len(size) == 2 else "[x, y, z]"
            for i, o in enumerate(obs):
                line = ctx.line_of(obs, i)
                if not isinstance(o, list) or len(o) != len(size):
                    raise ctx.error(f"an obstacle must be {form}, got {o!r}", line)
                c = tuple(ctx.integer(x, "an obstacle coordinate", line) for x in o)
                if any(not 0 <= c[k] < size[k] for k in range(len(size))):
                    raise ctx.error(
                        f"obstacle {list(c)} is outside the {'x'.join(map(str, size))} grid", line
                    )
                obstacles.append(c)
        depth = size[2] if len(size) == 3 else None
        return Graph.grid(size[0], size[1], depth, obstacles=obstacles, cell_size=cell)
    if "rows" in g:
        rline = ctx.line_of(g, "rows")
        rows = ctx.sequence(g["rows"], "rows", rline)
        if not rows:
            raise ctx.error("rows must list at least one row", rline)
        texts = [ctx.string(r, "a row", ctx.line_of(rows, i)) for i, r in enumerate(rows)]
        width = len(texts[0])
        check_grid(ctx, [width, len(texts)], rline)
        blocked = np.zeros((len(texts), width), dtype=bool)
        for y, row in enumerate(texts):
            line = ctx.line_of(rows, y)
            if len(row) != width:
                raise ctx.error(f"row {y} has {len(row)} cells, but row 0 has {width}", line)
            blocked[y] = blocked_cells(row, y, ctx, line)
        return Graph.grid(width, len(texts), blocked=blocked, cell_size=cell)
    mline = ctx.line_of(g, "map")
    ref = ctx.string(g["map"], "map", mline)
    map_path = (path.parent / ref) if not Path(ref).is_absolute() else Path(ref)
    if not map_path.exists():
        raise ctx.error(f"map file {ref!r} not found (looked at {map_path})", mline)
    base = wrap(ctx, mline, lambda: load_map(map_path))
    if cell == 1.0:
        return base
    assert base.shape is not None
    w, h = base.shape
    return Graph.grid(w, h, blocked=~base.passable.reshape(h, w), cell_size=cell)


def _roadmap(ctx: Ctx, g: LDict) -> Graph:
    ctx.check_keys(g, "a roadmap graph", ROADMAP_KEYS, ("vertices",))
    directed = False
    if "directed" in g:
        directed = ctx.boolean(g["directed"], "directed", ctx.line_of(g, "directed"))
    vline = ctx.line_of(g, "vertices")
    verts = ctx.mapping(g["vertices"], "vertices", vline)
    if not verts:
        raise ctx.error("a roadmap needs at least one vertex", vline)
    coords: dict[str, list[float]] = {}
    ndim: int | None = None
    for key, c in verts.items():
        line = verts.lines.get(key, vline)
        name = ctx.string(key, "a vertex name", line)
        if name in coords:
            raise ctx.error(f"vertex {name!r} is listed twice", line)
        if not isinstance(c, list) or len(c) not in (2, 3):
            raise ctx.error(f"vertex {name!r} needs [x, y] or [x, y, z], got {c!r}", line)
        if ndim is not None and len(c) != ndim:
            raise ctx.error(f"vertex {name!r} has {len(c)} coordinates, others have {ndim}", line)
        ndim = len(c)
        coords[name] = [ctx.number(x, f"a coordinate of vertex {name!r}", line) for x in c]
    edges: list[tuple[Any, ...]] = []
    seen: dict[tuple[str, str], int | None] = {}
    if g.get("edges") is not None:
        eline = ctx.line_of(g, "edges")
        elist = ctx.sequence(g["edges"], "edges", eline)
        for i, e in enumerate(elist):
            line = ctx.line_of(elist, i)
            if not isinstance(e, list) or len(e) not in (2, 3):
                raise ctx.error(f"an edge must be [u, v] or [u, v, length], got {e!r}", line)
            u, v = (ctx.string(x, "an edge end", line) for x in e[:2])
            for x in (u, v):
                if x not in coords:
                    raise ctx.error(f"edge [{u}, {v}] names unknown vertex {x!r}", line)
            if u == v:
                raise ctx.error(f"edge [{u}, {v}] is a self-loop (waiting is implicit)", line)
            key = (u, v) if directed else (min(u, v), max(u, v))
            if key in seen:
                raise ctx.error(
                    f"edge [{u}, {v}] is listed twice (first on line {seen[key]})", line
                )
            seen[key] = line
            if len(e) == 3:
                length = ctx.number(e[2], f"length of edge [{u}, {v}]", line, positive=True)
                edges.append((u, v, length))
            else:
                if math.dist(coords[u], coords[v]) <= 0:
                    raise ctx.error(
                        f"edge [{u}, {v}] joins two vertices at one position; give its length",
                        line,
                    )
                edges.append((u, v))
    return wrap(ctx, g.line, lambda: Graph.roadmap(coords, edges, directed=directed))


# ---------------------------------------------------------------- robots
def _robot_types(ctx: Ctx, value: Any, line: int | None) -> dict[str, Kinematics]:
    if value is None:
        return {}
    types = ctx.mapping(value, "robot_types", line)
    out: dict[str, Kinematics] = {}
    for key, spec in types.items():
        tline = types.lines.get(key, line)
        tname = ctx.string(key, "a robot type name", tline)
        spec = ctx.mapping(spec, f"robot type {tname!r}", tline)
        ctx.check_keys(spec, f"robot type {tname!r}", TYPE_KEYS)
        kw: dict[str, Any] = {"robot_type": tname}
        if "drive" in spec:
            drive = spec["drive"]
            if drive not in DRIVES:
                raise ctx.error(
                    f"robot type {tname!r}: drive must be one of {list(DRIVES)}, got {drive!r}",
                    ctx.line_of(spec, "drive"),
                )
            kw["drive"] = drive
        for k in ("v_max", "omega_max", "a_max"):
            if k in spec:
                kw[k] = ctx.number(
                    spec[k], f"robot type {tname!r}: {k}", ctx.line_of(spec, k), positive=True
                )
        if "radius" in spec:
            kw["radius"] = ctx.number(
                spec["radius"],
                f"robot type {tname!r}: radius",
                ctx.line_of(spec, "radius"),
                nonnegative=True,
            )
        out[tname] = wrap(ctx, tline, lambda kw=kw: Kinematics(**kw))
    return out


def _kin(
    ctx: Ctx, types: dict[str, Kinematics], d: LDict, default: Kinematics, who: str
) -> Kinematics:
    if "type" not in d:
        return default
    line = ctx.line_of(d, "type")
    tname = ctx.string(d["type"], f"type of {who}", line)
    if tname not in types:
        known = ", ".join(types) or "none defined under robot_types"
        raise ctx.error(f"{who} has unknown robot type {tname!r} (known: {known})", line)
    return types[tname]


def _agent_name(ctx: Ctx, d: LDict, index: int, names: dict[str, int | None]) -> str:
    if "name" in d:
        line = ctx.line_of(d, "name")
        name = ctx.string(d["name"], "agent name", line)
    else:
        line = d.line or None
        name = f"agent{index}"
    if name in names:
        raise ctx.error(f"agent name {name!r} is used twice (first on line {names[name]})", line)
    names[name] = line
    return name


def _agents(
    ctx: Ctx, graph: Graph, types: dict[str, Kinematics], value: Any, line: int | None
) -> tuple[tuple[Agent, ...], tuple[Team, ...]]:
    lst = ctx.sequence(value, "agents", line)
    if not lst:
        raise ctx.error("the instance has no agents", line)
    names: dict[str, int | None] = {}
    starts = Unique(ctx, graph, "start")
    goals = Unique(ctx, graph, "goal")
    out: list[Agent] = []
    for i, a in enumerate(lst):
        aline = ctx.line_of(lst, i)
        a = ctx.mapping(a, f"agent {i}", aline)
        ctx.check_keys(a, f"agent {i}", AGENT_KEYS, ("start",))
        name = _agent_name(ctx, a, i, names)
        sline, gline = ctx.line_of(a, "start"), ctx.line_of(a, "goal")
        s = location(ctx, graph, a["start"], f"agent {name!r} start", sline)
        starts.add(s, f"agent {name!r}", sline)
        g = -1  # no goal: a task-free robot, given a placeholder below
        if "goal" in a:
            g = location(ctx, graph, a["goal"], f"agent {name!r} goal", gline)
            goals.add(g, f"agent {name!r}", gline)
        kin = _kin(ctx, types, a, DEFAULT_KINEMATICS, f"agent {name!r}")
        out.append(Agent(name, s, g, None, kin))
    used = {a.goal for a in out if a.goal != -1}
    for i, a in enumerate(out):
        if a.goal == -1:  # ends anywhere; the placeholder (its start where free) keeps
            # the instance well-formed, the solve picks the end (hierplan_opt.search.libmrp)
            d = graph.dist_from(a.start)
            free = sorted(
                (int(d[v]), v) for v in range(graph.n) if graph.passable[v] and v not in used
            )
            if not free:
                raise ctx.error(f"task-free agent {a.name!r} has no vertex left to end at", line)
            v = a.start if a.start not in used else free[0][1]
            used.add(v)
            out[i] = Agent(a.name, a.start, v, None, a.kinematics)
    return tuple(out), ()


def _teams(
    ctx: Ctx, graph: Graph, types: dict[str, Kinematics], value: Any, line: int | None
) -> tuple[tuple[Agent, ...], tuple[Team, ...]]:
    lst = ctx.sequence(value, "teams", line)
    if not lst:
        raise ctx.error("'teams' lists no team", line)
    names: dict[str, int | None] = {}
    team_names: dict[str, int | None] = {}
    starts = Unique(ctx, graph, "start")
    targets_seen: dict[int, str] = {}
    agents: list[Agent] = []
    teams: list[Team] = []
    for ti, t in enumerate(lst):
        tline = ctx.line_of(lst, ti)
        t = ctx.mapping(t, f"team {ti}", tline)
        ctx.check_keys(t, f"team {ti}", TEAM_KEYS, ("agents", "targets"))
        if "name" in t:
            nline = ctx.line_of(t, "name")
            tname = ctx.string(t["name"], "team name", nline)
        else:
            nline, tname = tline, f"team{ti}"
        if tname in team_names:
            raise ctx.error(f"team name {tname!r} is used twice", nline)
        team_names[tname] = nline
        team_kin = _kin(ctx, types, t, DEFAULT_KINEMATICS, f"team {tname!r}")
        rl = ctx.sequence(t["agents"], f"agents of team {tname!r}", ctx.line_of(t, "agents"))
        if not rl:
            raise ctx.error(f"team {tname!r} has no robots", ctx.line_of(t, "agents"))
        members: list[int] = []
        for ri, r in enumerate(rl):
            rline = ctx.line_of(rl, ri)
            r = ctx.mapping(r, f"robot {ri} of team {tname!r}", rline)
            ctx.check_keys(r, f"robot {ri} of team {tname!r}", ROBOT_KEYS, ("start",))
            name = _agent_name(ctx, r, len(agents), names)
            sline = ctx.line_of(r, "start")
            s = location(ctx, graph, r["start"], f"agent {name!r} start", sline)
            starts.add(s, f"agent {name!r}", sline)
            kin = _kin(ctx, types, r, team_kin, f"agent {name!r}")
            members.append(len(agents))
            agents.append(Agent(name, s, None, ti, kin))
        gline = ctx.line_of(t, "targets")
        tl = ctx.sequence(t["targets"], f"targets of team {tname!r}", gline)
        targets: list[int] = []
        for k, loc in enumerate(tl):
            kline = ctx.line_of(tl, k)
            v = location(ctx, graph, loc, f"target of team {tname!r}", kline)
            if v in targets_seen:
                raise ctx.error(
                    f"target {graph.label(v)} of team {tname!r} is also a target of "
                    f"team {targets_seen[v]!r}",
                    kline,
                )
            targets_seen[v] = tname
            targets.append(v)
        if len(targets) != len(members):
            raise ctx.error(
                f"team {tname!r} has {len(members)} robots but {len(targets)} targets", gline
            )
        teams.append(Team(tname, tuple(members), tuple(targets)))
    return tuple(agents), tuple(teams)


def _highways(ctx: Ctx, graph: Graph, value: Any, line: int | None) -> frozenset[tuple[int, int]]:
    lst = ctx.sequence(value, "highways", line)
    out: set[tuple[int, int]] = set()
    for i, h in enumerate(lst):
        hline = ctx.line_of(lst, i)
        if not isinstance(h, list) or len(h) != 2:
            raise ctx.error(f"a highway must be [from, to], got {h!r}", hline)
        u = location(ctx, graph, h[0], "highway start", hline)
        v = location(ctx, graph, h[1], "highway end", hline)
        if not graph.has_edge(u, v):
            raise ctx.error(
                f"highway {graph.label(u)} -> {graph.label(v)} is not an edge of the graph",
                hline,
            )
        out.add((u, v))
    return frozenset(out)


# ---------------------------------------------------------------- writing
#: 2D grids with more obstacles than this are written as ``rows``.
ROWS_THRESHOLD = 40


def _num(x: float) -> str:
    """A float as YAML 1.1 reads it back as the same float (PyYAML needs a dot)."""
    if float(x).is_integer() and abs(x) < 1e15:
        return f"{float(x):.1f}"
    r = repr(float(x))
    if "e" in r and "." not in r.split("e")[0]:
        m, e = r.split("e")
        r = f"{m}.0e{e}"
    return r


def dumps(instance: Instance, *, rows: bool | None = None) -> str:
    """The hierplan YAML text of ``instance``.

    2D grids are written with ``rows`` when they have many obstacles (or when
    ``rows=True``), otherwise with ``dimensions``/``obstacles``.

    Example
    -------
    >>> g = Graph.grid(3, 1, obstacles=[(1, 0)])
    >>> print(dumps(Instance.mapf(g, [(0, 0)], [(2, 0)], name="t")), end="")
    format: hierplan/1
    name: t
    graph:
      type: grid
      dimensions: [3, 1]
      obstacles: [[1, 0]]
    agents:
      - {name: agent0, start: [0, 0], goal: [2, 0]}
    """
    g = instance.graph
    out = [f"format: {FORMAT_TAG}", f"name: {yaml_scalar(instance.name)}", "graph:"]
    if g.kind == "grid":
        assert g.shape is not None
        out.append("  type: grid")
        blocked = [v for v in range(g.n) if not g.passable[v]]
        use_rows = rows if rows is not None else len(blocked) > ROWS_THRESHOLD
        if use_rows and len(g.shape) == 2:
            w, h = g.shape
            free = g.passable.reshape(h, w)
            out.append("  rows:")
            out += ['    - "' + "".join("." if f else "@" for f in r) + '"' for r in free]
        else:
            out.append(f"  dimensions: [{', '.join(map(str, g.shape))}]")
            if blocked:
                out.append(f"  obstacles: [{', '.join(g.label(v) for v in blocked)}]")
        if g.cell_size != 1.0:
            out.append(f"  cell_size: {_num(g.cell_size)}")
    else:
        assert g.names is not None
        out.append("  type: roadmap")
        if g.directed:
            out.append("  directed: true")
        out.append("  vertices:")
        for v, name in enumerate(g.names):
            c = ", ".join(_num(x) for x in g.coords[v])
            out.append(f"    {yaml_scalar(name)}: [{c}]")
        edges = []
        for u, v in g.edges():
            if not g.directed and u > v:
                continue
            length = g.edge_length(u, v)
            a, b = yaml_scalar(g.names[u]), yaml_scalar(g.names[v])
            euclid = math.dist(g.coords[u].tolist(), g.coords[v].tolist())
            if abs(length - euclid) > 1e-12 * max(1.0, euclid):
                edges.append(f"    - [{a}, {b}, {_num(length)}]")
            else:
                edges.append(f"    - [{a}, {b}]")
        if edges:
            out.append("  edges:")
            out += edges
        else:
            out.append("  edges: []")

    loc = partial(g.label, quote=yaml_scalar)  # reads back as the same location
    type_names = _type_names(instance)
    if type_names:
        out.append("robot_types:")
        for kin, tname in type_names.items():
            parts = [f"drive: {kin.drive}", f"v_max: {_num(kin.v_max)}"]
            if kin.omega_max is not None:
                parts.append(f"omega_max: {_num(kin.omega_max)}")
            if kin.a_max is not None:
                parts.append(f"a_max: {_num(kin.a_max)}")
            parts.append(f"radius: {_num(kin.radius)}")
            out.append(f"  {yaml_scalar(tname)}: {{{', '.join(parts)}}}")

    free = set(instance.meta.get("free_agents", ()))

    def robot(a: Agent, with_goal: bool) -> str:
        parts = [f"name: {yaml_scalar(a.name)}", f"start: {loc(a.start)}"]
        if with_goal and a.name not in free:  # a task-free robot has no goal
            assert a.goal is not None
            parts.append(f"goal: {loc(a.goal)}")
        if a.kinematics != DEFAULT_KINEMATICS:
            parts.append(f"type: {yaml_scalar(type_names[a.kinematics])}")
        return "{" + ", ".join(parts) + "}"

    if instance.is_tapf:
        out.append("teams:")
        for team in instance.teams:
            out.append(f"  - name: {yaml_scalar(team.name)}")
            out.append("    agents:")
            out += [f"      - {robot(instance.agents[i], False)}" for i in team.agents]
            out.append(f"    targets: [{', '.join(loc(t) for t in team.targets)}]")
    else:
        out.append("agents:")
        out += [f"  - {robot(a, True)}" for a in instance.agents]
    if instance.highways is not None:
        hw = sorted(instance.highways)
        if hw:
            out.append("highways:")
            out += [f"  - [{loc(u)}, {loc(v)}]" for u, v in hw]
        else:
            out.append("highways: []")
    return "\n".join(out) + "\n"


def _type_names(instance: Instance) -> dict[Kinematics, str]:
    """A unique robot-type name for every non-default kinematics in ``instance``."""
    names: dict[Kinematics, str] = {}
    used: set[str] = set()
    for a in instance.agents:
        k = a.kinematics
        if k == DEFAULT_KINEMATICS or k in names:
            continue
        base = k.robot_type or "type"
        name, n = base, 2
        while name in used:
            name, n = f"{base}_{n}", n + 1
        used.add(name)
        names[k] = name
    return names


def save(path: str | Path, instance: Instance, *, rows: bool | None = None) -> None:
    """Write ``instance`` as a hierplan YAML file.

    Example
    -------
    >>> import os, tempfile
    >>> f = os.path.join(tempfile.mkdtemp(), "x.yaml")
    >>> save(f, Instance.mapf(Graph.grid(2, 1, 2), [(0, 0, 0)], [(1, 0, 1)]))
    >>> load(f).graph.shape
    (2, 1, 2)
    """
    write_text(path, dumps(instance, rows=rows))


__all__ = ["FORMAT_TAG", "dumps", "from_data", "load", "looks_like", "save"]
