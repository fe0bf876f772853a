"""Rolling-horizon planning for the lifelong loop: the search package's windowed PIBT
and windowed LaCAM (:mod:`hierplan_opt.search.windowed`), with turning costs,
congestion guidance and a deadline per call.

:data:`PLANNERS` names the choices of ``run_lifelong(planner=...)``: ``pibt`` and
``lacam`` (the windowed planners themselves) and ``pibt-guided`` / ``lacam-guided``
(windowed PIBT steered by the first steps of a one-shot plan of the registry's
``pibt`` / ``lacam`` solver, :mod:`~hierplan_opt.lifelong.guidance`).
"""

from __future__ import annotations

from hierplan_opt.search.windowed import (
    WindowedLaCAM,
    WindowedPIBT,
    WindowPlan,
    errand_done,
    turns,
)

PLANNERS = ("pibt", "lacam", "pibt-guided", "lacam-guided")

__all__ = ["PLANNERS", "WindowPlan", "WindowedLaCAM", "WindowedPIBT", "errand_done", "turns"]
