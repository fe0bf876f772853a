"""Disturbances of an execution: data, buildable in code and readable from YAML.

Four kinds (times in seconds, robots by name):

* :class:`Stop`: robot ``agent`` halts for ``duration`` at time ``at_time`` (wherever it
  is) or when it reaches its ``at_waypoint``-th way-point of the schedule;
* :class:`Breakdown`: robot ``agent`` stops for good at ``at_time``;
* :class:`Slow`: moves on the given ``cells`` (a move touching one of them) or ``edges``
  take ``1 / factor`` times as long while they start in ``[start, end)``;
* :class:`RandomDelays`: every move of every robot starts late with ``probability``;
  the delay is drawn from ``duration`` (``{exponential: mean}``, ``{uniform: [a, b]}``
  or ``{constant: d}``) with the generator seeded by ``seed``.

YAML::

    disturbances:
      - {kind: stop, agent: agent3, at_time: 4.0, duration: 6.0}   # or at_waypoint: k
      - {kind: breakdown, agent: agent7, at_time: 10.0}
      - {kind: slow, cells: [[3, 4], [3, 5]], factor: 0.3, from: 0.0, to: 30.0}
      - {kind: random, probability: 0.1, duration: {exponential: 2.0}, seed: 1}

Bad files are refused with one line naming the file, the line and the problem.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from hierplan_opt.core.errors import InputError
from hierplan_opt.io.yaml import Ctx, LDict, read_yaml


@dataclass(frozen=True)
class Stop:
    """Robot ``agent`` halts for ``duration`` s at ``at_time`` or at way-point ``at_waypoint``."""

    agent: str
    duration: float
    at_time: float | None = None
    at_waypoint: int | None = None

    def __post_init__(self) -> None:
        if (self.at_time is None) == (self.at_waypoint is None):
            raise InputError(f"stop of {self.agent}: give exactly one of at_time, at_waypoint")
        _nonneg("stop duration", self.duration)
        if self.at_time is not None:
            _nonneg("stop at_time", self.at_time)
        if self.at_waypoint is not None and self.at_waypoint < 0:
            raise InputError(f"stop of {self.agent}: at_waypoint must be >= 0")


@dataclass(frozen=True)
class Breakdown:
    """Robot ``agent`` stops for good at ``at_time``."""

    agent: str
    at_time: float

    def __post_init__(self) -> None:
        _nonneg("breakdown at_time", self.at_time)


@dataclass(frozen=True)
class Slow:
    """Moves touching ``cells`` (locations) or along ``edges`` run at ``factor`` of their
    speed while they start in ``[start, end)``."""

    factor: float
    cells: tuple[tuple[int, ...], ...] = ()
    edges: tuple[tuple[tuple[int, ...], tuple[int, ...]], ...] = ()
    start: float = 0.0
    end: float = math.inf

    def __post_init__(self) -> None:
        if not (math.isfinite(self.factor) and 0 < self.factor <= 1):
            raise InputError(f"slow factor must be in (0, 1], got {self.factor!r}")
        if not self.cells and not self.edges:
            raise InputError("a slow region needs cells or edges")
        if self.end < self.start:
            raise InputError(f"slow region: 'to' ({self.end}) is before 'from' ({self.start})")


@dataclass(frozen=True)
class RandomDelays:
    """Each move starts late with ``probability``; delays from ``distribution``
    (``exponential``: mean ``a``; ``uniform``: ``[a, b]``; ``constant``: ``a``)."""

    probability: float
    distribution: str = "exponential"
    a: float = 1.0
    b: float = 0.0
    seed: int | None = None

    def __post_init__(self) -> None:
        if not (math.isfinite(self.probability) and 0 <= self.probability <= 1):
            raise InputError(f"random delay probability must be in [0, 1], got {self.probability}")
        if self.distribution not in ("exponential", "uniform", "constant"):
            raise InputError(f"unknown delay distribution {self.distribution!r}")
        _nonneg("delay parameter", self.a)
        if self.distribution == "uniform" and not self.a <= self.b < math.inf:
            raise InputError(f"uniform delay needs a <= b, got [{self.a}, {self.b}]")

    def draw(self, rng: np.random.Generator) -> float:
        """One delay (seconds)."""
        if self.distribution == "exponential":
            return float(rng.exponential(self.a))
        if self.distribution == "uniform":
            return float(rng.uniform(self.a, self.b))
        return float(self.a)


Disturbance = Stop | Breakdown | Slow | RandomDelays


def on_map(graph: Any, cell: tuple[int, ...]) -> bool:
    """Whether a disturbance's ``cell`` lies on ``graph`` (cells outside are ignored in a
    phase; :func:`check_disturbances` refuses them up front).

    Example
    -------
    >>> from hierplan_opt.core.graph import Graph
    >>> on_map(Graph.grid(2, 2), (1, 1)), on_map(Graph.grid(2, 2), (2, 0))
    (True, False)
    """
    try:
        graph.vertex(cell)
    except InputError:
        return False
    return True


def check_disturbances(
    disturbances: Sequence[Disturbance], instance: Any, schedule: Any = None
) -> None:
    """Refuse disturbances that can never happen, with one line (:class:`InputError`)
    naming the disturbance, counted from 1 as in its file: a slow region's cell or edge
    end outside the map (a region may cover obstacles), an edge that is not one of the
    map's, and (with ``schedule``) a stop ``at_waypoint`` beyond the robot's way-points.
    Robot names are checked by the reader and by
    :func:`~hierplan_opt.execution.simulate`.

    Example
    -------
    >>> from hierplan_opt import Graph, Instance
    >>> inst = Instance.mapf(Graph.grid(3, 1), [(0, 0)], [(2, 0)])
    >>> check_disturbances([Slow(0.5, cells=((1, 0),))], inst)
    >>> check_disturbances([Slow(0.5, cells=((9, 9),))], inst)
    Traceback (most recent call last):
    ...
    hierplan_opt.core.errors.InputError: disturbance 1 (slow): cell (9, 9) is not on the map ...
    """
    g = instance.graph
    names = list(schedule.agent_names) if schedule is not None else []
    for i, d in enumerate(disturbances):
        what = f"disturbance {i + 1} ({_kind(d)})"
        if isinstance(d, Slow):
            for c in d.cells:
                _on_map(g, c, what, "cell")
            for a, b in d.edges:
                u, v = _on_map(g, a, what, "edge end"), _on_map(g, b, what, "edge end")
                if not (g.has_edge(u, v) or g.has_edge(v, u)):
                    raise InputError(f"{what}: {list(a)} - {list(b)} is not an edge of the map")
        if not isinstance(d, Stop) or d.at_waypoint is None or schedule is None:
            continue
        wp = d.at_waypoint
        if d.agent in names:
            k = names.index(d.agent)
            n = len(schedule.waypoints[k].arrival)
            if wp >= n:
                raise InputError(
                    f"{what}: {d.agent} has {n} way-points (0..{n - 1}), no way-point {wp}"
                )


def _kind(d: Disturbance) -> str:
    return {Stop: "stop", Breakdown: "breakdown", Slow: "slow"}.get(type(d), "random")


def _on_map(g: Any, c: tuple[int, ...], what: str, name: str) -> int:
    try:
        v = g.vertex(c)
    except InputError as exc:
        raise InputError(f"{what}: {name} {tuple(c)} is not on the map ({exc})") from None
    return int(v)


def _nonneg(what: str, x: float) -> None:
    if isinstance(x, bool) or not isinstance(x, (int, float)) or not math.isfinite(x) or x < 0:
        raise InputError(f"{what} must be a finite number >= 0, got {x!r}")


def as_dict(d: Disturbance) -> dict[str, Any]:
    """The YAML form of one disturbance (for reports)."""
    if isinstance(d, Stop):
        out: dict[str, Any] = {"kind": "stop", "agent": d.agent, "duration": d.duration}
        if d.at_time is not None:
            out["at_time"] = d.at_time
        else:
            out["at_waypoint"] = d.at_waypoint
        return out
    if isinstance(d, Breakdown):
        return {"kind": "breakdown", "agent": d.agent, "at_time": d.at_time}
    if isinstance(d, Slow):
        out = {"kind": "slow", "factor": d.factor, "from": d.start}
        if math.isfinite(d.end):
            out["to"] = d.end
        if d.cells:
            out["cells"] = [list(c) for c in d.cells]
        if d.edges:
            out["edges"] = [[list(a), list(b)] for a, b in d.edges]
        return out
    dist: dict[str, Any] = (
        {"uniform": [d.a, d.b]} if d.distribution == "uniform" else {d.distribution: d.a}
    )
    return {"kind": "random", "probability": d.probability, "duration": dist, "seed": d.seed}


# ---------------------------------------------------------------------- YAML
_KEYS = {
    "stop": (("kind", "agent", "at_time", "at_waypoint", "duration"), ("agent", "duration")),
    "breakdown": (("kind", "agent", "at_time"), ("agent", "at_time")),
    "slow": (("kind", "cells", "edges", "factor", "from", "to"), ("factor",)),
    "random": (("kind", "probability", "duration", "seed"), ("probability", "duration")),
}


def load_disturbances(path: str | Path, agents: tuple[str, ...] | None = None) -> list[Disturbance]:
    """Read a disturbances file (``disturbances: [...]``); one-line errors.

    ``agents`` (the instance's robot names), when given, must contain every robot named.

    Example
    -------
    >>> import tempfile, os
    >>> f = os.path.join(tempfile.mkdtemp(), "d.yaml")
    >>> text = "disturbances:\\n  - {kind: stop, agent: a, at_time: 1, duration: 2}\\n"
    >>> _ = open(f, "w").write(text)
    >>> load_disturbances(f)
    [Stop(agent='a', duration=2.0, at_time=1.0, at_waypoint=None)]
    """
    ctx = Ctx(path)
    data = read_yaml(path)
    top = ctx.mapping(data, "the disturbances file", None)
    ctx.check_keys(top, "the disturbances file", ("disturbances",), ("disturbances",))
    items = ctx.sequence(top["disturbances"], "'disturbances'", ctx.line_of(top, "disturbances"))
    out: list[Disturbance] = []
    for i, item in enumerate(items):
        line = ctx.line_of(items, i)
        out.append(_one(ctx, item, i, line, agents))
    return out


def _one(
    ctx: Ctx, item: Any, i: int, line: int | None, agents: tuple[str, ...] | None
) -> Disturbance:
    what = f"disturbance {i + 1}"
    d = ctx.mapping(item, what, line)
    if "kind" not in d:
        raise ctx.error(f"{what} has no 'kind' (use {', '.join(_KEYS)})", line)
    kind = d["kind"]
    if kind not in _KEYS:
        raise ctx.error(f"{what}: unknown kind {kind!r} (use {', '.join(_KEYS)})", line)
    allowed, required = _KEYS[kind]
    ctx.check_keys(d, f"{what} ({kind})", allowed, required)

    def num(key: str, **kw: bool) -> float:
        return ctx.number(d[key], f"{what}: {key}", ctx.line_of(d, key), **kw)

    def agent() -> str:
        name = ctx.string(d["agent"], f"{what}: agent", ctx.line_of(d, "agent"))
        if agents is not None and name not in agents:
            raise ctx.error(f"{what}: no robot named {name!r} in the instance", line)
        return name

    try:
        if kind == "stop":
            if ("at_time" in d) == ("at_waypoint" in d):
                raise ctx.error(f"{what}: give exactly one of at_time, at_waypoint", line)
            at_wp = (
                ctx.integer(d["at_waypoint"], f"{what}: at_waypoint", line, minimum=0)
                if "at_waypoint" in d
                else None
            )
            at_t = num("at_time", nonnegative=True) if "at_time" in d else None
            return Stop(agent(), num("duration", nonnegative=True), at_t, at_wp)
        if kind == "breakdown":
            return Breakdown(agent(), num("at_time", nonnegative=True))
        if kind == "slow":
            cells = tuple(_loc(ctx, c, f"{what}: cell", line) for c in _seq(ctx, d, "cells", what))
            edges = tuple(_edge(ctx, e, what, line) for e in _seq(ctx, d, "edges", what))
            start = num("from", nonnegative=True) if "from" in d else 0.0
            end = num("to", nonnegative=True) if "to" in d else math.inf
            return Slow(num("factor", positive=True), cells, edges, start, end)
        dist, a, b = _distribution(ctx, d["duration"], what, ctx.line_of(d, "duration"))
        seed = (
            ctx.integer(d["seed"], f"{what}: seed", ctx.line_of(d, "seed"), minimum=0)
            if "seed" in d
            else None
        )
        return RandomDelays(num("probability", nonnegative=True), dist, a, b, seed)
    except InputError as exc:
        if str(exc).startswith(ctx.file):
            raise
        raise ctx.error(f"{what}: {exc}", line) from None


def _seq(ctx: Ctx, d: LDict, key: str, what: str) -> list[Any]:
    if key not in d:
        return []
    return list(ctx.sequence(d[key], f"{what}: {key}", ctx.line_of(d, key)))


def _loc(ctx: Ctx, c: Any, what: str, line: int | None) -> tuple[int, ...]:
    if not isinstance(c, list) or not 2 <= len(c) <= 3:
        raise ctx.error(f"{what} must be [x, y] or [x, y, z], got {c!r}", line)
    return tuple(ctx.integer(x, what, line) for x in c)


def _edge(ctx: Ctx, e: Any, what: str, line: int | None) -> tuple[tuple[int, ...], tuple[int, ...]]:
    if not isinstance(e, list) or len(e) != 2:
        raise ctx.error(f"{what}: an edge must be [[x, y], [x, y]], got {e!r}", line)
    return _loc(ctx, e[0], f"{what}: edge end", line), _loc(ctx, e[1], f"{what}: edge end", line)


def _distribution(ctx: Ctx, v: Any, what: str, line: int | None) -> tuple[str, float, float]:
    if isinstance(v, (int, float)) and not isinstance(v, bool):
        return "constant", ctx.number(v, f"{what}: duration", line, nonnegative=True), 0.0
    if not isinstance(v, dict) or len(v) != 1:
        raise ctx.error(
            f"{what}: duration must be {{exponential: mean}}, {{uniform: [a, b]}} or "
            f"{{constant: d}}, got {v!r}",
            line,
        )
    ((name, arg),) = v.items()
    if name == "uniform":
        if not isinstance(arg, list) or len(arg) != 2:
            raise ctx.error(f"{what}: uniform needs [a, b], got {arg!r}", line)
        a = ctx.number(arg[0], f"{what}: uniform a", line, nonnegative=True)
        b = ctx.number(arg[1], f"{what}: uniform b", line, nonnegative=True)
        if b < a:
            raise ctx.error(f"{what}: uniform needs a <= b, got [{a:g}, {b:g}]", line)
        return "uniform", a, b
    if name in ("exponential", "constant"):
        return name, ctx.number(arg, f"{what}: {name}", line, nonnegative=True), 0.0
    raise ctx.error(f"{what}: unknown duration distribution {name!r}", line)
