"""Execution of MAPF-POST schedules under disturbances (issue 11).

:func:`simulate` runs a schedule with scripted stops, breakdowns, slow regions and
random delays under an execution policy (slack, STN re-solve, MAPF re-plan, and the
``adg`` / ``naive`` baselines) and returns an :class:`Execution` with the executed
trajectories, event times per TPG node, the log of which layer handled each
disturbance, and statistics (collisions, minimum distance, arrivals, layer counts).
"""

from __future__ import annotations

from hierplan_opt.execution.disturbances import (
    Breakdown,
    Disturbance,
    RandomDelays,
    Slow,
    Stop,
    load_disturbances,
)
from hierplan_opt.execution.simulate import simulate
from hierplan_opt.execution.state import POLICIES, Event, ExecState, Execution, Phase

__all__ = [
    "POLICIES",
    "Breakdown",
    "Disturbance",
    "Event",
    "ExecState",
    "Execution",
    "Phase",
    "RandomDelays",
    "Slow",
    "Stop",
    "load_disturbances",
    "simulate",
]
