"""Result files of LaCAM / LaCAM3 / PIBT (Keisuke Okumura's solvers, ``-o result.txt``).

``key=value`` lines, then the solution as one configuration per timestep, cells as
``(x,y)`` (x = column, y = row, like MovingAI)::

    agents=2
    map_file=random-32-32-20.map
    solver=planner
    solved=1
    soc=7
    ...
    starts=(0,0),(5,3),
    goals=(4,0),(5,6),
    solution=
    0:(0,0),(5,3),
    1:(1,0),(5,4),
    ...

Every configuration lists every agent, in scenario order; agent ``i``'s path is the
``i``-th cell of each line. Only 2D grids have this format.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

from hierplan_opt.core.errors import InputError
from hierplan_opt.core.graph import Graph
from hierplan_opt.core.instance import Instance
from hierplan_opt.core.plan import Plan
from hierplan_opt.io._common import grid_2d, grid_cell, grid_xy
from hierplan_opt.io.files import write_text
from hierplan_opt.io.yaml import Ctx

_KEY = re.compile(r"([A-Za-z_][A-Za-z0-9_]*)=(.*)$")
_STEP = re.compile(r"\s*(\d+)\s*:(.*)$")
_CELL = re.compile(r"\(\s*(-?\d+)\s*,\s*(-?\d+)\s*\)\s*,?\s*")


def looks_like(text: str) -> bool:
    """Whether ``text`` looks like a LaCAM result file (``agents=`` or ``solution=`` lines).

    Example
    -------
    >>> looks_like("agents=2\\nsolution=\\n0:(0,0),(1,0),\\n"), looks_like("Agent 0: (0,0)->")
    (True, False)
    """
    head = [ln.strip() for ln in text.splitlines()[:50] if ln.strip()]
    return bool(head) and head[0].split("=", 1)[0] in ("agents", "map_file", "solver", "solution")


def parse(text: str, name: str, instance: Instance) -> tuple[Plan, dict[str, Any]]:
    """The plan and the ``key=value`` statistics of a LaCAM result text.

    The file must be for as many agents as the instance has (``agents=``); a file
    with ``solved=0`` has no plan and is refused. Blocked cells, jumps, conflicts and
    starts or goals that differ from the instance are left to the validator.

    Example
    -------
    >>> from hierplan_opt.core.graph import Graph
    >>> inst = Instance.mapf(Graph.grid(3, 1), [(0, 0), (2, 0)], [(1, 0), (2, 0)])
    >>> plan, stats = parse("agents=2\\nsoc=1\\nsolution=\\n0:(0,0),(2,0),\\n1:(1,0),(2,0),\\n",
    ...                     "r.txt", inst)
    >>> plan.paths, stats["soc"]
    (((0, 1), (2, 2)), 1)
    """
    ctx = Ctx(name)
    graph = grid_2d(instance, "a LaCAM result file")
    lines = text.splitlines()
    stats: dict[str, Any] = {}
    first_step = None
    for lineno, raw in enumerate(lines, start=1):
        line = raw.strip()
        if not line:
            continue
        if line == "solution=":
            first_step = lineno
            break
        m = _KEY.match(line)
        if m is None:
            raise ctx.error(f"expected 'key=value' or 'solution=', got {line[:40]!r}", lineno)
        stats[m.group(1)] = _value(m.group(2).strip())
    k = instance.num_agents
    if "agents" in stats and stats["agents"] != k:
        raise ctx.error(
            f"the file is for agents={stats['agents']} but the instance has {k} agents "
            "(read the scenario with as many --agents as the solver had)",
            _line_of(lines, "agents="),
        )
    if stats.get("solved") == 0:
        raise ctx.error("the file says solved=0: the solver found no plan")
    if first_step is None:
        raise ctx.error("no 'solution=' line (was the solver run with the short log?)")
    configs: list[list[int]] = []
    for lineno in range(first_step + 1, len(lines) + 1):
        line = lines[lineno - 1]
        if not line.strip():
            continue
        m = _STEP.match(line)
        if m is None:
            raise ctx.error(f"expected '<t>:(x,y),(x,y),...', got {line.strip()[:40]!r}", lineno)
        t = int(m.group(1))
        if t != len(configs):
            raise ctx.error(f"timestep {t} where {len(configs)} was expected", lineno)
        configs.append(_config(ctx, graph, m.group(2), k, t, lineno))
    if not configs:
        raise ctx.error("the solution has no timesteps", first_step)
    span = stats.get("makespan")
    if isinstance(span, int) and not isinstance(span, bool) and span >= len(configs):
        raise ctx.error(
            f"the file says makespan={span} but its solution stops at timestep "
            f"{len(configs) - 1} (a truncated file?)",
            len(lines),
        )
    paths = [tuple(c[i] for c in configs) for i in range(k)]
    return Plan(tuple(paths)), stats


def _config(ctx: Ctx, graph: Graph, text: str, k: int, t: int, line: int) -> list[int]:
    out: list[int] = []
    pos = 0
    text = text.rstrip()
    while pos < len(text):
        m = _CELL.match(text, pos)
        if m is None:
            raise ctx.error(f"t={t}: expected '(x,y),' at {text[pos : pos + 20]!r}", line)
        x, y = int(m.group(1)), int(m.group(2))
        out.append(grid_cell(ctx, graph, x, y, f"t={t}: agent {len(out)} cell ({x},{y})", line))
        pos = m.end()
    if len(out) != k:
        raise ctx.error(f"t={t} lists {len(out)} agents, expected {k}", line)
    return out


def _value(text: str) -> Any:
    for conv in (int, float):
        try:
            return conv(text)
        except ValueError:
            pass
    return text


def _line_of(lines: list[str], prefix: str) -> int | None:
    for i, ln in enumerate(lines, start=1):
        if ln.strip().startswith(prefix):
            return i
    return None


def dumps(
    instance: Instance,
    plan: Plan,
    *,
    map_file: str | None = None,
    stats: dict[str, Any] | None = None,
) -> str:
    """The LaCAM result text of ``plan`` (configurations up to the makespan).

    ``map_file`` defaults to the instance's map file name; ``stats`` may give
    ``soc_lb``, ``makespan_lb`` and ``comp_time`` (milliseconds).

    Example
    -------
    >>> from hierplan_opt.core.graph import Graph
    >>> inst = Instance.mapf(Graph.grid(2, 1), [(0, 0)], [(1, 0)], name="tiny")
    >>> print(dumps(inst, Plan.from_paths([[0, 1]])), end="")
    agents=1
    map_file=tiny.map
    solver=hierplan
    solved=1
    soc=1
    soc_lb=1
    makespan=1
    makespan_lb=1
    starts=(0,0),
    goals=(1,0),
    solution=
    0:(0,0),
    1:(1,0),
    """
    graph = grid_2d(instance, "a LaCAM result file")
    if plan.num_agents != instance.num_agents:
        raise InputError(f"the plan has {plan.num_agents} paths for {instance.num_agents} agents")
    stats = dict(stats or {})
    if map_file is None:
        map_file = Path(str(instance.meta.get("map", f"{instance.name}.map"))).name

    def cell(v: int) -> str:
        x, y = grid_xy(graph, v)
        return f"({x},{y}),"

    head = {
        "agents": instance.num_agents,
        "map_file": map_file,
        "solver": stats.pop("solver", "hierplan"),
        "solved": 1,
        "soc": plan.sum_of_costs,
        "soc_lb": stats.pop("soc_lb", instance.soc_lower_bound()),
        "makespan": plan.makespan,
        "makespan_lb": stats.pop("makespan_lb", instance.makespan_lower_bound()),
    }
    if "comp_time" in stats:
        head["comp_time"] = stats.pop("comp_time")
    out = [f"{k}={v}" for k, v in head.items()]
    out.append("starts=" + "".join(cell(p[0]) for p in plan.paths))
    out.append("goals=" + "".join(cell(p[-1]) for p in plan.paths))
    out.append("solution=")
    for t in range(plan.makespan + 1):
        out.append(f"{t}:" + "".join(cell(plan.position(i, t)) for i in range(plan.num_agents)))
    return "\n".join(out) + "\n"


def save(path: str | Path, instance: Instance, plan: Plan, **kw: Any) -> None:
    """Write ``plan`` as a LaCAM result file (atomically); ``kw`` as for :func:`dumps`.

    Example
    -------
    >>> import os, tempfile
    >>> from hierplan_opt.core.graph import Graph
    >>> inst = Instance.mapf(Graph.grid(2, 1), [(0, 0)], [(1, 0)])
    >>> f = os.path.join(tempfile.mkdtemp(), "result.txt")
    >>> save(f, inst, Plan.from_paths([[0, 1]]))
    >>> parse(open(f).read(), f, inst)[0].paths
    ((0, 1),)
    """

    write_text(path, dumps(instance, plan, **kw))


__all__ = ["dumps", "looks_like", "parse", "save"]
