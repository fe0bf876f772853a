"""Path files of EECBS and CBSH2-RTC (Jiaoyang Li's solvers, option ``--outputPaths``).

One line per agent, agents in scenario order, cells as ``(row,column)``::

    Agent 0: (3,5)->(3,6)->(4,6)->
    Agent 1: (0,0)->(1,0)->

Row is the MovingAI y and column the x, so ``(r,c)`` is the cell ``[x, y] = [c, r]``.
The solvers end each path when the agent reaches its goal; the agent stays there.
Only 2D grids (MovingAI maps) have this format.
"""

from __future__ import annotations

import re
from pathlib import Path

from hierplan_opt.core.errors import InputError
from hierplan_opt.core.instance import Instance
from hierplan_opt.core.plan import Plan
from hierplan_opt.io._common import grid_2d, grid_cell, grid_xy
from hierplan_opt.io.files import write_text
from hierplan_opt.io.yaml import Ctx

_AGENT = re.compile(r"\s*Agent\s+(\d+)\s*:(.*)$")
_CELL = re.compile(r"\(\s*(-?\d+)\s*,\s*(-?\d+)\s*\)")
_SEP = re.compile(r"\s*(?:->)?\s*")


def looks_like(text: str) -> bool:
    """Whether ``text`` starts like an EECBS / CBSH2-RTC path file.

    Example
    -------
    >>> looks_like("Agent 0: (0,0)->(0,1)->\\n"), looks_like("schedule:\\n")
    (True, False)
    """
    for line in text.splitlines():
        if line.strip():
            return _AGENT.match(line) is not None
    return False


def parse(text: str, name: str, instance: Instance) -> Plan:
    """The plan in an EECBS path text for ``instance`` (``name`` names the file in errors).

    Every agent of the instance must have exactly one line; cells must be on the map.
    Blocked cells, jumps and conflicts are left to the validator.

    Example
    -------
    >>> from hierplan_opt.core.graph import Graph
    >>> inst = Instance.mapf(Graph.grid(3, 2), [(0, 0)], [(2, 1)])
    >>> parse("Agent 0: (0,0)->(0,1)->(1,1)->(1,2)->\\n", "p.txt", inst).paths
    ((0, 1, 4, 5),)
    """
    ctx = Ctx(name)
    graph = grid_2d(instance, "an EECBS path file")
    paths: list[tuple[int, ...] | None] = [None] * instance.num_agents
    for lineno, line in enumerate(text.splitlines(), start=1):
        if not line.strip():
            continue
        m = _AGENT.match(line)
        if m is None:
            raise ctx.error(f"expected 'Agent <i>: (row,col)->...', got {line.strip()!r}", lineno)
        i = int(m.group(1))
        if i >= instance.num_agents:
            raise ctx.error(
                f"agent {i} but the instance has {instance.num_agents} agents "
                "(read the scenario with as many --agents as the solver had)",
                lineno,
            )
        if paths[i] is not None:
            raise ctx.error(f"agent {i} has a second line", lineno)
        rest, pos, path = m.group(2), 0, []
        while True:
            sep = _SEP.match(rest, pos)
            pos = sep.end() if sep else pos
            if pos >= len(rest):
                break
            cell = _CELL.match(rest, pos)
            if cell is None:
                raise ctx.error(
                    f"agent {i}: expected '(row,col)' at {rest[pos : pos + 20]!r}", lineno
                )
            r, c = int(cell.group(1)), int(cell.group(2))
            path.append(grid_cell(ctx, graph, c, r, f"agent {i} cell (row {r}, col {c})", lineno))
            pos = cell.end()
        if not path:
            raise ctx.error(f"agent {i} has an empty path", lineno)
        paths[i] = tuple(path)
    missing = [i for i, p in enumerate(paths) if p is None]
    if missing:
        few = ", ".join(map(str, missing[:5])) + (" ..." if len(missing) > 5 else "")
        raise ctx.error(f"no path for agent(s) {few} of the {instance.num_agents} agents")
    return Plan(tuple(p for p in paths if p is not None))


def dumps(instance: Instance, plan: Plan) -> str:
    """The EECBS path text of ``plan`` (each path ends when its agent arrives).

    Example
    -------
    >>> from hierplan_opt.core.graph import Graph
    >>> inst = Instance.mapf(Graph.grid(3, 2), [(0, 0)], [(2, 1)])
    >>> print(dumps(inst, Plan.from_paths([[0, 1, 4, 5, 5]])), end="")
    Agent 0: (0,0)->(0,1)->(1,1)->(1,2)->
    """
    graph = grid_2d(instance, "an EECBS path file")
    if plan.num_agents != instance.num_agents:
        raise InputError(f"the plan has {plan.num_agents} paths for {instance.num_agents} agents")
    out = []
    for i, path in enumerate(plan.trimmed().paths):
        cells = []
        for v in path:
            x, y = grid_xy(graph, v)
            cells.append(f"({y},{x})->")
        out.append(f"Agent {i}: " + "".join(cells))
    return "\n".join(out) + "\n"


def save(path: str | Path, instance: Instance, plan: Plan) -> None:
    """Write ``plan`` as an EECBS path file (atomically).

    Example
    -------
    >>> import os, tempfile
    >>> from hierplan_opt.core.graph import Graph
    >>> inst = Instance.mapf(Graph.grid(2, 1), [(0, 0)], [(1, 0)])
    >>> f = os.path.join(tempfile.mkdtemp(), "paths.txt")
    >>> save(f, inst, Plan.from_paths([[0, 1]]))
    >>> open(f).read()
    'Agent 0: (0,0)->(0,1)->\\n'
    """

    write_text(path, dumps(instance, plan))


__all__ = ["dumps", "looks_like", "parse", "save"]
