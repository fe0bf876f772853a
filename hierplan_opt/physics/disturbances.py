"""Physical disturbances as data: what the MuJoCo world does to the robots.

* :class:`Spill`: a low-friction region (the paper's water spill): the floor's friction
  coefficient there is ``friction`` instead of :data:`~.models.MU_FLOOR`; wheels slip,
  so the traction (and the controller's acceleration, which senses it) drops.
* :class:`Payload`: ``mass`` kg more on one robot (its motors stay as they were).
* :class:`WeakMotor`: one robot's motors give ``factor`` of their force (thrust, torque).
* :class:`Wind`: a gust (air velocity, m/s) on every robot (or those named) between two
  times: aerodynamic drag ``0.5 rho c_d A |w - v| (w - v)``.
* :class:`RobotStop`: a robot stops as fast as it can at ``at_time`` and stays stopped
  for ``duration`` seconds (None: a breakdown, for good).
* :class:`RandomStops`: after each way-point a robot pauses with ``probability`` for a
  random time (the execution module's delay distributions; seeded).

:func:`from_execution` turns the execution module's disturbances (``hierplan run
--disturbances`` files: ``slow``, ``stop``, ``breakdown``, ``random``) into these, and
:func:`parse` reads the physical kinds (``spill``, ``payload``, ``weak_motor``, ``wind``)
from a disturbances file's list.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from hierplan_opt.core.errors import InputError

#: Friction coefficient of a water film on a smooth floor (ours: wet rubber on sealed
#: concrete is 0.1-0.3; a spill of water with some soap or oil lower).
SPILL_FRICTION = 0.05


@dataclass(frozen=True)
class Spill:
    """Low friction in axis-aligned boxes ``(x0, y0, x1, y1)`` (metres) from ``start`` to
    ``end`` (seconds)."""

    boxes: tuple[tuple[float, float, float, float], ...]
    friction: float = SPILL_FRICTION
    start: float = 0.0
    end: float = math.inf


@dataclass(frozen=True)
class Payload:
    agent: str
    mass: float


@dataclass(frozen=True)
class WeakMotor:
    agent: str
    factor: float


@dataclass(frozen=True)
class Wind:
    velocity: tuple[float, float, float]
    start: float = 0.0
    end: float = math.inf
    agents: tuple[str, ...] | None = None


@dataclass(frozen=True)
class RobotStop:
    agent: str
    at_time: float
    duration: float | None = None


@dataclass(frozen=True)
class RandomStops:
    """After each way-point a robot pauses with ``probability``; the pause is drawn by
    ``delays.draw(rng)`` (an execution ``RandomDelays``), seeded by ``seed``."""

    probability: float
    delays: Any
    seed: int | None = None


PhysicalDisturbance = Spill | Payload | WeakMotor | Wind | RobotStop | RandomStops


def cell_boxes(
    cells: Iterable[Sequence[float]], scale: float
) -> tuple[tuple[float, float, float, float], ...]:
    """Metre boxes of grid cells (instance coordinates; a cell is ``scale`` wide,
    centred on its coordinates).

    Example
    -------
    >>> cell_boxes([(1, 2)], 1.0)
    ((0.5, 1.5, 1.5, 2.5),)
    """
    h = 0.5 * scale
    return tuple(
        (float(c[0]) * scale - h, float(c[1]) * scale - h, float(c[0]) * scale + h,
         float(c[1]) * scale + h)
        for c in cells
    )  # fmt: skip


def from_execution(
    disturbances: Iterable[Any], scale: float, *, friction: float = SPILL_FRICTION
) -> list[PhysicalDisturbance]:
    """The physical counterparts of :mod:`hierplan_opt.execution.disturbances` items:
    ``Slow`` -> :class:`Spill` over its cells (its ``factor`` is not used: the physics
    decide how much slower), ``Stop`` -> :class:`RobotStop` with a duration,
    ``Breakdown`` -> :class:`RobotStop` for good, ``RandomDelays`` -> :class:`RandomStops`
    (same distribution). Physical kinds pass through.

    Example
    -------
    >>> from hierplan_opt.execution.disturbances import Stop
    >>> from_execution([Stop("a", at_time=1.0, duration=2.0)], 1.0)
    [RobotStop(agent='a', at_time=1.0, duration=2.0)]
    """
    # Recognised by their class names: the execution layer drives physics, so physics
    # does not import it (no import cycle).
    out: list[PhysicalDisturbance] = []
    for d in disturbances:
        kind = type(d).__name__
        if isinstance(d, (Spill, Payload, WeakMotor, Wind, RobotStop, RandomStops)):
            out.append(d)
        elif kind == "Slow":
            boxes = cell_boxes(d.cells, scale)
            for a, b in d.edges:
                boxes += cell_boxes([a, b], scale)
            out.append(Spill(boxes, friction, float(d.start), float(d.end)))
        elif kind == "Breakdown":
            out.append(RobotStop(d.agent, float(d.at_time), None))
        elif kind == "Stop":
            if d.at_time is None:
                raise InputError(
                    f"physics: stop of {d.agent!r} at a way-point is not supported (give at_time)"
                )
            out.append(RobotStop(d.agent, float(d.at_time), float(d.duration)))
        elif kind == "RandomDelays":
            out.append(RandomStops(float(d.probability), d, d.seed))
        else:
            raise InputError(f"physics: unknown disturbance {d!r}")
    return out


def parse(items: Sequence[Mapping[str, Any]], scale: float) -> list[PhysicalDisturbance]:
    """Physical disturbances from plain data (a YAML list).

    Kinds: ``spill`` (``cells`` or ``boxes``, ``friction``, ``from``, ``to``),
    ``payload`` (``agent``, ``mass``), ``weak_motor`` (``agent``, ``factor``), ``wind``
    (``velocity``, ``from``, ``to``, ``agents``), ``robot_stop`` (``agent``,
    ``at_time``, ``duration``). One clear :class:`InputError` for bad entries.

    Example
    -------
    >>> parse([{"kind": "payload", "agent": "r1", "mass": 5}], 1.0)
    [Payload(agent='r1', mass=5.0)]
    """
    out: list[PhysicalDisturbance] = []
    for n, it in enumerate(items):
        kind = it.get("kind")
        try:
            if kind == "spill":
                boxes = tuple(tuple(float(x) for x in b) for b in it.get("boxes", ()))
                boxes += cell_boxes(it.get("cells", ()), scale)
                if not boxes or any(len(b) != 4 for b in boxes):
                    raise ValueError("needs cells or boxes [x0, y0, x1, y1]")
                out.append(
                    Spill(
                        boxes,  # type: ignore[arg-type]
                        float(it.get("friction", SPILL_FRICTION)),
                        float(it.get("from", 0.0)),
                        float(it.get("to", math.inf)),
                    )
                )
            elif kind == "payload":
                out.append(Payload(str(it["agent"]), _nonneg(it["mass"])))
            elif kind == "weak_motor":
                f = float(it["factor"])
                if not 0 < f <= 1:
                    raise ValueError(f"factor must be in (0, 1], got {f}")
                out.append(WeakMotor(str(it["agent"]), f))
            elif kind == "wind":
                v = tuple(float(x) for x in it["velocity"])
                if len(v) == 2:
                    v = (*v, 0.0)
                if len(v) != 3:
                    raise ValueError("velocity needs 2 or 3 numbers")
                ag = it.get("agents")
                out.append(
                    Wind(
                        v,  # type: ignore[arg-type]
                        float(it.get("from", 0.0)),
                        float(it.get("to", math.inf)),
                        tuple(str(a) for a in ag) if ag is not None else None,
                    )
                )
            elif kind == "robot_stop":
                dur = it.get("duration")
                out.append(
                    RobotStop(
                        str(it["agent"]),
                        float(it["at_time"]),
                        None if dur is None else _nonneg(dur),
                    )
                )
            else:
                raise ValueError(f"unknown kind {kind!r}")
        except (KeyError, TypeError, ValueError) as e:
            raise InputError(f"physical disturbance {n + 1} ({kind}): {e}") from None
    return out


def _nonneg(x: Any) -> float:
    v = float(x)
    if not math.isfinite(v) or v < 0:
        raise ValueError(f"must be a non-negative number, got {x!r}")
    return v
