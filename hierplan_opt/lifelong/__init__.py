"""Lifelong multi-robot operation on the League of Robot Runners (LoRR 2026) problems.

Tasks are revealed all the time; a scheduler gives them to free robots
(:mod:`~hierplan_opt.lifelong.scheduler`), a rolling-horizon planner plans a window
(:mod:`~hierplan_opt.lifelong.planner`), and an executor keeps the robots safe under
the problem's delays with an action dependency graph
(:mod:`~hierplan_opt.lifelong.executor`). :func:`run_lifelong` is the loop;
:func:`~hierplan_opt.lifelong.replay.check_log` replays a written log independently.
The files are read and written by :mod:`hierplan_opt.io.lorr`.
"""

from __future__ import annotations

from hierplan_opt.lifelong.replay import ReplayReport, check_log
from hierplan_opt.lifelong.run import LifelongResult, run_lifelong

__all__ = ["LifelongResult", "ReplayReport", "check_log", "run_lifelong"]
