"""Plan files in the libMultiRobotPlanning output layout (YAML, or JSON by extension).

::

    statistics: {soc: 8, makespan: 4, objective: soc, cost: 8, lower_bound: 8, ...}
    schedule:
      agent0: [{x: 0, y: 0, t: 0}, {x: 1, y: 0, t: 1}]   # z: on 3D grids
      r1: [{v: A, t: 0}, {v: B, t: 1}]                   # roadmaps: vertex name v

``soc`` is the sum of costs and ``makespan`` the makespan of the written plan (trailing
waits do not count); with a solver result, ``cost`` is the plan's cost under the run's
``objective`` (one of the two) and ``lower_bound`` a proven bound on that. Times are
consecutive integers from 0 and the agent stays at its last entry afterwards.
"""

from __future__ import annotations

import json
import math
import re
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from hierplan_opt.core.errors import InputError
from hierplan_opt.core.instance import Instance
from hierplan_opt.core.plan import Plan
from hierplan_opt.core.result import Result
from hierplan_opt.io import eecbs, lacam, tracker
from hierplan_opt.io.files import write_text
from hierplan_opt.io.values import plain
from hierplan_opt.io.yaml import Ctx, LDict, LList, read_text, read_yaml, yaml_scalar

#: Solver statistics written under libMultiRobotPlanning's names.
_LMRP_NAMES = {
    "high_level_expanded": "highLevelExpanded",
    "low_level_expanded": "lowLevelExpanded",
}


#: Plan file formats: read by content, written by ``format=`` (or the extension).
PLAN_FORMATS = ("yaml", "json", "eecbs", "lacam", "tracker")


def plan_format(text: str) -> str:
    """Which plan format ``text`` is in: ``"eecbs"``, ``"lacam"``, ``"tracker"`` or
    ``"lmrp"`` (the libMultiRobotPlanning YAML/JSON layout, the default).

    Example
    -------
    >>> plan_format("Agent 0: (0,0)->"), plan_format("agents=1\\nsolution=\\n")
    ('eecbs', 'lacam')
    """

    if eecbs.looks_like(text):
        return "eecbs"
    if lacam.looks_like(text):
        return "lacam"
    if tracker.looks_like(text):
        return "tracker"
    return "lmrp"


def load_plan(path: str | Path, instance: Instance, *, tracker_y: str | None = None) -> Plan:
    """Read a plan file for ``instance``, in any of the formats of :func:`read_plan`.

    Example
    -------
    >>> import os, tempfile
    >>> from hierplan_opt.core.graph import Graph
    >>> inst = Instance.mapf(Graph.grid(3, 1), [(0, 0)], [(2, 0)])
    >>> f = os.path.join(tempfile.mkdtemp(), "plan.yaml")
    >>> save_plan(f, inst, Plan.from_paths([[0, 1, 2]]))
    >>> load_plan(f, inst).paths
    ((0, 1, 2),)
    """
    return read_plan(path, instance, tracker_y=tracker_y)[0]


def read_plan(
    path: str | Path, instance: Instance, text: str | None = None, *, tracker_y: str | None = None
) -> tuple[Plan, dict[str, Any]]:
    """A plan file's plan and statistics; the format is recognised by the content.

    - the libMultiRobotPlanning layout (YAML or JSON, as :func:`save_plan` writes):
      every agent of the instance appears under ``schedule`` by name, times run
      ``0, 1, 2, ...``; the statistics are its ``statistics`` block;
    - EECBS / CBSH2-RTC path files (``Agent 0: (r,c)->...``, :mod:`~hierplan_opt.io.eecbs`);
    - LaCAM result files (``solution=``, :mod:`~hierplan_opt.io.lacam`), statistics
      from its ``key=value`` lines;
    - MAPF Tracker submissions (:mod:`~hierplan_opt.io.tracker`; ``tracker_y``: its
      move convention, ``"down"`` or ``"up"``, detected when None).

    Every location must be on the map; other mistakes (blocked cells, jumps,
    conflicts) are left to :func:`hierplan_opt.validate`. ``text`` is the file's
    content when the caller has read it already.

    Example
    -------
    >>> import os, tempfile
    >>> from hierplan_opt.core.graph import Graph
    >>> inst = Instance.mapf(Graph.grid(3, 1), [(0, 0)], [(2, 0)])
    >>> f = os.path.join(tempfile.mkdtemp(), "paths.txt")
    >>> _ = open(f, "w").write("Agent 0: (0,0)->(0,1)->(0,2)->\\n")
    >>> read_plan(f, inst)
    (Plan(paths=((0, 1, 2),)), {})
    """

    if text is None:
        text = read_text(path)
    name = str(path)
    fmt = plan_format(text)
    if fmt == "eecbs":
        return eecbs.parse(text, name, instance), {}
    if fmt == "lacam":
        return lacam.parse(text, name, instance)
    if fmt == "tracker":
        return tracker.parse(text, name, instance, tracker_y)
    data = _fast_parse(text, name)
    if data is None:
        data = read_yaml(path, text)
    try:
        return _plan_from_data(data, path, instance), _statistics(data)
    except InputError:
        if isinstance(data, LDict):
            raise
        # parsed without line numbers (JSON): parse again with them for the message
        data = read_yaml(path, text)
        return _plan_from_data(data, path, instance), _statistics(data)


def _statistics(data: Any) -> dict[str, Any]:
    stats = data.get("statistics") if isinstance(data, dict) else None
    return dict(stats) if isinstance(stats, dict) else {}


def _plan_from_data(data: Any, path: str | Path, instance: Instance) -> Plan:
    ctx = Ctx(path)
    if data is None:
        raise ctx.error("empty file, expected 'schedule:'", 1)
    top = ctx.mapping(data, "a plan file", 1)
    ctx.check_keys(top, "the plan file", ("statistics", "schedule"), ("schedule",))
    if top.get("statistics") is not None:
        ctx.mapping(top["statistics"], "statistics", ctx.line_of(top, "statistics"))
    sched = ctx.mapping(top["schedule"], "schedule", ctx.line_of(top, "schedule"))
    g = instance.graph
    index = {a.name: i for i, a in enumerate(instance.agents)}
    paths: list[tuple[int, ...] | None] = [None] * instance.num_agents
    if g.kind == "roadmap":
        coord_keys: tuple[str, ...] = ("v",)
    else:
        assert g.shape is not None
        coord_keys = ("x", "y", "z")[: len(g.shape)]
    keys = (*coord_keys, "t")
    fast_grid = g.kind == "grid"
    for raw_name, entries in sched.items():
        name = str(raw_name)
        line = sched.key_lines.get(raw_name, sched.line)
        if name not in index:
            raise ctx.error(
                f"schedule names agent {name!r}, which the instance does not have", line
            )
        if paths[index[name]] is not None:
            raise ctx.error(f"schedule lists agent {name!r} twice", line)
        entries = ctx.sequence(entries, f"schedule of {name!r}", ctx.line_of(sched, raw_name))
        if not entries:
            raise ctx.error(f"schedule of {name!r} is empty", ctx.line_of(sched, raw_name))
        walk: list[int] = []
        for t, e in enumerate(entries):
            v = _quick_vertex(e, t, keys, g) if fast_grid else -1
            if v >= 0:
                walk.append(v)
                continue
            eline = ctx.line_of(entries, t)
            e = ctx.mapping(e, f"entry {t} of {name!r}", eline)
            ctx.check_keys(e, f"the schedule entry of {name!r}", keys, keys)
            et = ctx.integer(e["t"], f"t of {name!r}", eline)
            if et != t:
                want = "start at t: 0" if t == 0 else f"continue with t: {t} after t: {t - 1}"
                raise ctx.error(f"schedule of {name!r} must {want}, got t: {et}", eline)
            if g.kind == "roadmap":
                vname = ctx.string(e["v"], f"v of {name!r}", eline)
                try:
                    v = g.vertex(vname)
                except InputError:
                    raise ctx.error(f"{name!r} at t={t}: unknown vertex {vname!r}", eline) from None
            else:
                c = [ctx.integer(e[k], f"{k} of {name!r}", eline) for k in coord_keys]
                try:
                    v = g.vertex(tuple(c))
                except InputError as exc:
                    raise ctx.error(f"{name!r} at t={t}: {exc}", eline) from None
            walk.append(v)
        paths[index[name]] = tuple(walk)
    missing = [instance.agents[i].name for i, p in enumerate(paths) if p is None]
    if missing:
        more = f" (and {len(missing) - 3} more)" if len(missing) > 3 else ""
        raise ctx.error(
            f"schedule has no path for agent(s) {', '.join(map(repr, missing[:3]))}{more}",
            top.key_lines.get("schedule", sched.line),
        )
    return Plan(tuple(p for p in paths if p is not None))


def _quick_vertex(e: Any, t: int, keys: tuple[str, ...], g: Any) -> int:
    """The vertex of a well-formed grid entry, or -1 to take the checked slow path."""
    if not isinstance(e, dict) or len(e) != len(keys):
        return -1
    try:
        c = [e[k] for k in keys]
    except KeyError:
        return -1
    if c[-1] != t or any(type(x) is not int for x in c):
        return -1
    shape = g.shape
    idx, stride = 0, 1
    for x, d in zip(c[:-1], shape, strict=True):
        if not 0 <= x < d:
            return -1
        idx += x * stride
        stride *= d
    return idx


_NAME_LINE = re.compile(r"^  ([A-Za-z_][A-Za-z0-9_.\-]*|\"[^\"\\]*\"):\s*$")
_ENTRY_LINE = re.compile(r"^    - \{([^{}\[\]\"']*)\}\s*$")
_INT = re.compile(r"-?(?:0|[1-9][0-9]*)")
_PLAIN = re.compile(r"[A-Za-z_][A-Za-z0-9_.\-]*")


def _fast_parse(text: str, name: str) -> LDict | dict | None:
    """Parse the layout :func:`save_plan` writes without a YAML parser (which is slow
    on plans with 10^5 entries). Returns None for anything else; the caller then uses
    the YAML parser. JSON files are read with :func:`json.loads` (no line numbers).
    """
    if name.lower().endswith(".json"):
        try:
            return json.loads(text)
        except (json.JSONDecodeError, RecursionError):
            return None
    lines = text.splitlines()
    i = 0
    n = len(lines)
    top = LDict()
    top.line, top.lines, top.key_lines = 1, {}, {}
    plain_ok: dict[str, bool] = {}
    while i < n:
        ln = lines[i]
        if not ln.strip() or ln.lstrip().startswith("#"):
            i += 1
            continue
        if ln.startswith("statistics:"):
            j = i + 1
            while j < n and (not lines[j].strip() or lines[j].startswith((" ", "#"))):
                j += 1
            if "statistics" in top:
                return None
            try:
                stats = yaml.safe_load("\n".join(lines[i:j]))
            except yaml.YAMLError:
                return None
            if not isinstance(stats, dict):
                return None
            top["statistics"] = stats.get("statistics")
            top.lines["statistics"] = top.key_lines["statistics"] = i + 1
            i = j
            continue
        if ln.rstrip() != "schedule:" or "schedule" in top:
            return None
        sched = LDict()
        sched.line, sched.lines, sched.key_lines = i + 2, {}, {}
        top["schedule"] = sched
        top.lines["schedule"], top.key_lines["schedule"] = i + 2, i + 1
        i += 1
        current: LList | None = None
        while i < n:
            ln = lines[i]
            if not ln.strip():
                i += 1
                continue
            m = _ENTRY_LINE.match(ln)
            if m is not None and current is not None:
                e = LDict()
                e.line = i + 1
                for part in m.group(1).split(","):
                    # YAML needs ": " between key and value (a plain "y:-0" is one key)
                    key, sep, val = part.strip().partition(": ")
                    key, val = key.strip(), val.strip()
                    if not sep or key in e or not _PLAIN.fullmatch(key):
                        return None
                    if _INT.fullmatch(val):
                        e[key] = int(val)
                    elif _PLAIN.fullmatch(val):
                        ok = plain_ok.get(val)
                        if ok is None:
                            ok = plain_ok[val] = yaml_scalar(val) == val
                        if not ok:
                            return None
                        e[key] = val
                    else:
                        return None
                e.lines = dict.fromkeys(e, i + 1)
                e.key_lines = e.lines
                current.append(e)
                current.lines.append(i + 1)
                i += 1
                continue
            m = _NAME_LINE.match(ln)
            if m is None:
                break
            agent = m.group(1)
            if agent.startswith('"'):
                agent = json.loads(agent)
            elif not plain_ok.setdefault(agent, yaml_scalar(agent) == agent):
                return None
            if agent in sched:
                return None  # duplicate: let the YAML reader report it
            current = LList()
            current.line, current.lines = i + 2, []
            sched[agent] = current
            sched.lines[agent], sched.key_lines[agent] = i + 2, i + 1
            i += 1
        if i < n and lines[i].startswith(" "):
            return None
    return top if "schedule" in top else None


def plan_document(instance: Instance, result_or_plan: Result | Plan) -> dict[str, Any]:
    """The plan file content as plain data (``statistics`` and ``schedule``).

    Example
    -------
    >>> from hierplan_opt.core.graph import Graph
    >>> inst = Instance.mapf(Graph.grid(2, 1), [(0, 0)], [(1, 0)])
    >>> plan_document(inst, Plan.from_paths([[0, 1]]))["schedule"]["agent0"][1]
    {'x': 1, 'y': 0, 't': 1}
    """
    result, plan = _result_and_plan(result_or_plan)
    if plan.num_agents != instance.num_agents:
        raise InputError(f"the plan has {plan.num_agents} paths for {instance.num_agents} agents")
    stats: dict[str, Any] = {"soc": plan.sum_of_costs, "makespan": plan.makespan}
    if result is not None:
        stats["objective"] = result.objective
        stats["cost"] = plan.cost(result.objective)
        stats["runtime"] = round(float(result.runtime), 6)
        if result.solver:
            stats["solver"] = result.solver
        stats["status"] = str(result.status)
        stats["objective"] = result.objective
        if result.lower_bound is not None:
            stats["lower_bound"] = _plain(result.lower_bound)
        for k, v in result.stats.items():
            key = _LMRP_NAMES.get(str(k), str(k))
            val = _plain(v)
            if key not in stats and val is not _SKIP:
                stats[key] = val
    g = instance.graph
    schedule: dict[str, list[dict[str, Any]]] = {}
    for a, path in zip(instance.agents, plan.paths, strict=True):
        entries = []
        for t, v in enumerate(path):
            if g.kind == "roadmap":
                entries.append({"v": g.location(v), "t": t})
            else:
                loc = g.location(v)
                e: dict[str, Any] = dict(zip(("x", "y", "z"), loc, strict=False))
                e["t"] = t
                entries.append(e)
        schedule[a.name] = entries
    return {"statistics": stats, "schedule": schedule}


def _result_and_plan(result_or_plan: Result | Plan) -> tuple[Result | None, Plan]:
    """``(result, plan)`` of a solver result, or ``(None, plan)``; a result needs a plan."""
    if isinstance(result_or_plan, Result):
        if result_or_plan.plan is None:
            raise InputError(f"the result has no plan to write (status {result_or_plan.status})")
        return result_or_plan, result_or_plan.plan
    return None, result_or_plan


def save_plan(
    path: str | Path,
    instance: Instance,
    result_or_plan: Result | Plan,
    format: str | None = None,
) -> None:
    """Write a plan (or a solver result's plan with its statistics) to ``path``.

    ``format`` is one of :data:`PLAN_FORMATS`; by default YAML in the
    libMultiRobotPlanning output layout, or JSON with the same structure when
    ``path`` ends in ``.json``. ``"eecbs"`` writes an EECBS / CBSH2-RTC path file,
    ``"lacam"`` a LaCAM result file and ``"tracker"`` a MAPF Tracker submission (CSV,
    or JSON/YAML by extension; the lower bound of a sum-of-costs result becomes
    ``lower_cost``). The file is written atomically.

    Example
    -------
    >>> import os, tempfile
    >>> from hierplan_opt.core.graph import Graph
    >>> inst = Instance.mapf(Graph.grid(2, 1), [(0, 0)], [(1, 0)])
    >>> f = os.path.join(tempfile.mkdtemp(), "p.yaml")
    >>> save_plan(f, inst, Plan.from_paths([[0, 1]]))
    >>> print(open(f).read(), end="")
    statistics:
      soc: 1
      makespan: 1
    schedule:
      agent0:
        - {x: 0, y: 0, t: 0}
        - {x: 1, y: 0, t: 1}
    """

    p = Path(path)
    fmt = format or ("json" if p.suffix.lower() == ".json" else "yaml")
    if fmt not in PLAN_FORMATS:
        raise InputError(f"unknown plan format {format!r} (use {', '.join(PLAN_FORMATS)})")
    if fmt in ("yaml", "json"):
        doc = plan_document(instance, result_or_plan)
        text = json.dumps(doc, indent=1) + "\n" if fmt == "json" else plan_yaml(doc)
        write_text(p, text)
        return
    result, plan = _result_and_plan(result_or_plan)
    if fmt == "eecbs":
        eecbs.save(p, instance, plan)
    elif fmt == "lacam":
        stats: dict[str, Any] = {}
        if result is not None:
            stats["comp_time"] = round(float(result.runtime) * 1000)
            if result.lower_bound is not None:
                stats[f"{result.objective}_lb"] = _plain(result.lower_bound)
        lacam.save(p, instance, plan, stats=stats)
    else:
        lower = None
        if result is not None and result.objective == "soc" and result.lower_bound is not None:
            lower = int(math.ceil(float(result.lower_bound) - 1e-9))
        tracker.save(p, tracker.submission(instance, plan, lower_cost=lower))


def plan_yaml(doc: dict[str, Any]) -> str:
    """YAML text of a plan document: one flow-style line per schedule entry.

    Example
    -------
    >>> doc = {"statistics": {"cost": 0}, "schedule": {"r": [{"v": "A", "t": 0}]}}
    >>> print(plan_yaml(doc), end="")
    statistics:
      cost: 0
    schedule:
      r:
        - {v: A, t: 0}
    """
    lines = ["statistics:"]
    for key, value in doc["statistics"].items():
        # one key at a time: block style at the top, flow style inside nested values
        if isinstance(value, (list, dict)):
            flow = yaml.safe_dump(value, default_flow_style=True, width=10**9).strip()
            lines.append(f"  {yaml_scalar(key)}: {flow}")
        else:
            text = yaml.safe_dump({key: value}, default_flow_style=False, width=10**9)
            lines += ["  " + ln for ln in text.splitlines()]
    lines.append("schedule:")
    for name, entries in doc["schedule"].items():
        lines.append(f"  {yaml_scalar(name)}:")
        for e in entries:
            parts = ", ".join(
                f"{k}: {yaml_scalar(v) if isinstance(v, str) else v}" for k, v in e.items()
            )
            lines.append(f"    - {{{parts}}}")
    return "\n".join(lines) + "\n"


class _Skip:
    pass


_SKIP: Any = _Skip()


def _plain(v: Any) -> Any:
    """A statistic as a file value (:func:`~hierplan_opt.io.values.plain`, 6 significant
    digits), or ``_SKIP`` when it has no short plain form (arrays, objects, deep nesting)."""
    if _has_array(v):
        return _SKIP
    try:
        return plain(v, significant=6, strict=True, max_depth=4)
    except TypeError:
        return _SKIP


def _has_array(v: Any) -> bool:
    if isinstance(v, np.ndarray):
        return True
    if isinstance(v, (list, tuple)):
        return any(_has_array(x) for x in v)
    return isinstance(v, dict) and any(_has_array(x) for x in v.values())


__all__ = [
    "PLAN_FORMATS",
    "load_plan",
    "plan_document",
    "plan_format",
    "plan_yaml",
    "read_plan",
    "save_plan",
]
