"""Trajectory refinement: from a MAPF-POST schedule to smooth, limited motion.

:func:`refine` (CasADi, :mod:`.refine`) decouples the schedule's time windows
(:mod:`.windows`), refines every robot on its own and returns :class:`Trajectories`;
:func:`verify` (:mod:`.verify`) checks them independently of the optimiser. CasADi and
matplotlib are imported only when used.
"""

from __future__ import annotations

from hierplan_opt.trajectory.events import EventNetwork, from_file, from_schedule
from hierplan_opt.trajectory.refine import InfeasibleWindowsError, refine
from hierplan_opt.trajectory.result import (
    RobotTrajectory,
    Trajectories,
    read_trajectories,
    write_trajectories,
)
from hierplan_opt.trajectory.windows import Windows, decouple

__all__ = [
    "EventNetwork",
    "InfeasibleWindowsError",
    "RobotTrajectory",
    "Trajectories",
    "Windows",
    "decouple",
    "from_file",
    "from_schedule",
    "read_trajectories",
    "refine",
    "write_trajectories",
]
