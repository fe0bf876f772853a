"""Readable and YAML reports of executions, and plans recovered from schedule files."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

from hierplan_opt.core.instance import Instance
from hierplan_opt.core.plan import Plan
from hierplan_opt.execution.state import Execution
from hierplan_opt.io.files import write_text
from hierplan_opt.io.yaml import to_yaml
from hierplan_opt.schedule.files import load_schedule


def text_report(ex: Execution, title: str = "") -> str:
    """A few readable lines: statistics, then the events and the layer of each."""
    st = ex.statistics
    lines = []
    if title:
        lines.append(title)
    lines.append(
        f"execution ({ex.policy}, {ex.mode} mode): makespan {_makespan(st)} "
        f"(planned {_f(st['planned_makespan'])} s), {_arrivals(st)}"
    )
    kept = "kept" if st["distance_kept"] else "NOT kept"
    lines.append(
        f"safety: {st['collisions']} collisions, min distance {_min_distance(st)} m "
        f"vs guaranteed {_f(st['guaranteed_distance'])} m ({kept})"
    )
    if st.get("acceleration_checked") == 0:
        lines.append("dynamics: accelerations not checked (no robot type gives a_max)")
    elif "acceleration_violations" in st:
        n = st["acceleration_violations"]
        worst = st.get("worst_acceleration")
        how = "measured" if worst and "measured" in worst else "needed"
        more = (
            f" (worst: {worst['agent']} at t={worst['time']:.2f} s {how} {worst[how]:.3g} m/s^2)"
            if worst
            else ""
        )
        lines.append(
            f"dynamics: max |a| / a_max {_f(st['max_acceleration_ratio'])}, "
            f"{n} acceleration violation(s){more}"
        )
    h = st["handled"]
    rt = st["runtime"]
    lines.append(
        f"layers: {st['disturbances']} disturbances; slack {h['slack']}, reorder "
        f"{h['reorder']} ({st['reorders']} switches, {rt['reorder'] * 1e3:.3g} ms), stn "
        f"{h['stn']} ({st['stn_resolves']} re-solves, {rt['stn'] * 1e3:.3g} ms), replan "
        f"{h['replan']} ({st['replans']} re-plans, {rt['replan']:.3g} s), unhandled {h['none']}"
    )
    shown = [e for e in ex.log if e.kind != "random"][:12]
    randoms = sum(e.kind == "random" for e in ex.log)
    for e in shown:
        delay = f", {e.delay:.3g} s late" if math.isfinite(e.delay) and e.delay > 0 else ""
        lines.append(
            f"  t={e.time:7.2f} {e.agent:>10} {e.kind:<9} -> {e.layer:<6} {e.detail}{delay}"
        )
    if randoms:
        lines.append(f"  ({randoms} random delays: see the report's events)")
    for name in st["unfinished"]:
        lines.append(f"  not at its goal: {name}: {st['why_unfinished'][name]}")
    lines.append(outcome_line(ex))
    return "\n".join(lines)


def _min_distance(st: dict) -> str:
    above = st.get("min_distance_above")
    return f"> {_f(above)}" if above is not None else _f(st["min_distance"])


def outcome_line(ex: Execution) -> str:
    """The summary line: robots at their own goals, the broken ones apart, the working
    robots that are not at their goals (a failed run), collisions."""
    st = ex.statistics
    K = len(ex.agent_names)
    parts = [f"{st['finished']}/{K} robots at their own goals"]
    if st["broken"]:
        parts.append(f"{len(st['broken'])} broke down ({', '.join(st['broken'])})")
    if st["stranded"]:
        names = ", ".join(st["stranded"][:5]) + (" ..." if len(st["stranded"]) > 5 else "")
        parts.append(f"FAILED: {len(st['stranded'])} working robot(s) not at their goals ({names})")
    parts.append(f"{st['collisions']} collisions")
    return "; ".join(parts)


def _makespan(st: dict[str, Any]) -> str:
    m = st["makespan"]
    if isinstance(m, (int, float)) and math.isfinite(m):
        return f"{m:.4g} s"
    return f"not reached ({len(st['stranded'])} working robot(s) never at their goals)"


def _arrivals(st: dict[str, Any]) -> str:
    """``arrivals avg A s max M s``, or that no robot arrived (no mean of nothing)."""
    avg, top = st["arrival_avg"], st["arrival_max"]
    if isinstance(avg, (int, float)) and math.isfinite(avg):
        return f"arrivals avg {_f(avg)} s max {_f(top)} s"
    return "no robot arrived at its goal"


def _f(x: Any) -> str:
    return f"{x:.4g}" if isinstance(x, (int, float)) and math.isfinite(x) else str(x)


def write_report(path: str | Path, data: dict[str, Any]) -> Path:
    """Write YAML atomically (a temporary file renamed): never a half-written file;
    numbers through the one converter (a non-finite float is null)."""
    return write_text(path, to_yaml(data))


def plan_from_schedule(instance: Instance, path: str | Path, data: dict[str, Any]) -> Plan:
    """The discrete plan a ``hierplan post`` schedule file carries (read by the one
    reader, :func:`hierplan_opt.schedule.files.load_schedule`; ``data`` is not used).

    Example
    -------
    >>> import tempfile, os
    >>> from hierplan_opt import Graph
    >>> from hierplan_opt.schedule import postprocess, read_schedule, write_schedule
    >>> inst = Instance.mapf(Graph.grid(4, 1), [(1, 0), (0, 0)], [(3, 0), (2, 0)])
    >>> f = os.path.join(tempfile.mkdtemp(), "s.yaml")
    >>> _ = write_schedule(postprocess(inst, Plan.from_paths([[1, 2, 3], [0, 1, 2]])), f)
    >>> plan_from_schedule(inst, f, read_schedule(f)).paths
    ((1, 2, 3), (0, 1, 2))
    """

    plan = load_schedule(path, instance).plan
    assert plan is not None
    return plan
