"""The picture commands on 200 robots (part of ``hierplan bench view``).

A LaCAM plan of 200 robots on ``warehouse-10-20-10-2-1`` (the bundled random scenario,
5 s anytime budget), its MAPF-POST schedule and a simulated execution. Timed in this
process (one warm process; matplotlib already imported by the first row): the plan
plot (``solve --plot``), the Gantt chart (``post --gantt``), the MP4 and GIF animations
of the first 60 s of the execution (``simulate --animate``, 10 frames per second) and
the viewer page (``hierplan view``).
"""

from __future__ import annotations

import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from hierplan_opt.api import solve

TARGET_S = 20.0


def _timed(fn: Callable[[], Any]) -> float:
    t0 = time.perf_counter()
    fn()
    return time.perf_counter() - t0


def picture_table(quick: bool = False, robots: int = 200, seconds: float = 60.0) -> bool:
    """Print the table; True when every picture took less than :data:`TARGET_S`."""
    from hierplan_opt.execution import simulate
    from hierplan_opt.experiments.data import movingai_files
    from hierplan_opt.io.movingai import load_movingai
    from hierplan_opt.schedule import postprocess
    from hierplan_opt.viz.animation import animate
    from hierplan_opt.viz.gantt import plot_gantt
    from hierplan_opt.viz.html import write_view
    from hierplan_opt.viz.plots import save_plan_figure
    from hierplan_opt.viz.scene import scene_from_execution

    if quick:
        robots, seconds = 50, 20.0
    mp, _ = movingai_files("warehouse-10-20-10-2-1-even-1")
    scen = Path(mp).parent.parent / "large" / "warehouse-10-20-10-2-1-gen-1.scen"
    inst = load_movingai(mp, scen, robots)
    res = solve(inst, "lacam", time_limit=5.0)
    if res.plan is None:
        print(f"pictures: LaCAM found no plan for {robots} robots")
        return False
    plan = res.plan
    schedule = postprocess(inst, plan)
    ex = simulate(inst, schedule)
    scene = scene_from_execution(inst, ex)
    print(
        f"pictures: {robots} robots on {inst.name}, plan makespan {plan.makespan}, "
        f"execution {ex.statistics['makespan']:.1f} s; animations of the first {seconds:g} s "
        "at 10 fps; one warm process"
    )
    print(f"{'picture':34} {'time_s':>7} {'size_MB':>8}")
    ok = True
    with tempfile.TemporaryDirectory() as d:
        rows = [
            ("plan plot (solve --plot)", "plan.png",
             lambda p: save_plan_figure(inst, plan, p)),
            ("Gantt chart (post --gantt)", "gantt.png", lambda p: plot_gantt(schedule, p)),
            ("MP4 (simulate --animate)", "run.mp4",
             lambda p: animate(scene, None, p, until=seconds)),
            ("GIF (simulate --animate)", "run.gif",
             lambda p: animate(scene, None, p, until=seconds)),
            ("viewer page (hierplan view)", "view.html", lambda p: write_view(scene, p)),
        ]  # fmt: skip
        for label, name, make in rows:
            path = Path(d) / name
            secs = _timed(lambda make=make, path=path: make(path))
            ok &= secs < TARGET_S
            print(f"{label:34} {secs:>7.2f} {path.stat().st_size / 1e6:>8.2f}")
    print(f"target: every picture under {TARGET_S:g} s: " + ("met" if ok else "NOT met"))
    return ok
