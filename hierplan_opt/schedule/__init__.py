"""MAPF-POST: from a valid discrete plan to an execution schedule.

Pipeline: plan -> temporal plan graph with markers from the robots' radii
(:mod:`.tpg`, :mod:`.clearance`) -> simple temporal network (:mod:`.stn`) -> node
times by graph algorithms (:mod:`.solve_graph`) or an LP (:mod:`.solve_lp`) ->
:class:`Schedule` (:mod:`.output`), checked independently by a continuous-time replay
(:mod:`.replay`). The front door is :func:`postprocess`.
"""

from __future__ import annotations

from hierplan_opt.schedule.clearance import ClearanceError, PairClearance, Requirement
from hierplan_opt.schedule.files import load_schedule, plan_from_tree
from hierplan_opt.schedule.output import (
    Schedule,
    Waypoints,
    plan_tree,
    read_schedule,
    schedule_text,
    to_dot,
    write_schedule,
)
from hierplan_opt.schedule.post import postprocess
from hierplan_opt.schedule.replay import (
    PairSeparations,
    ReplayReport,
    check_bounds,
    collides,
    pair_separations,
    replay,
    required_separation,
)
from hierplan_opt.schedule.solve_graph import (
    GraphSolution,
    InconsistentSTNError,
    bellman_ford,
    critical_path,
    earliest_times,
    fix_and_propagate,
    latest_times,
    solve_graph,
    windows,
)
from hierplan_opt.schedule.solve_lp import LPError, LPSolution, solve_lp
from hierplan_opt.schedule.stn import STN, accel_time, build_stn, reach_time
from hierplan_opt.schedule.tpg import TPG, build_tpg

__all__ = [
    "STN",
    "TPG",
    "ClearanceError",
    "GraphSolution",
    "InconsistentSTNError",
    "LPError",
    "LPSolution",
    "PairClearance",
    "PairSeparations",
    "ReplayReport",
    "Requirement",
    "Schedule",
    "Waypoints",
    "accel_time",
    "bellman_ford",
    "build_stn",
    "build_tpg",
    "check_bounds",
    "collides",
    "critical_path",
    "earliest_times",
    "fix_and_propagate",
    "latest_times",
    "load_schedule",
    "pair_separations",
    "plan_from_tree",
    "plan_tree",
    "postprocess",
    "reach_time",
    "read_schedule",
    "replay",
    "required_separation",
    "schedule_text",
    "solve_graph",
    "solve_lp",
    "to_dot",
    "windows",
    "write_schedule",
]
