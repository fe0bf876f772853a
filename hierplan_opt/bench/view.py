"""``hierplan bench view``: the browser viewer on a large fleet, and the picture commands
on 200 robots.

Viewer table: a LaCAM plan of ``--robots`` robots (default 10,000) on an empty 128 x 128
grid (random distinct starts and goals, seed 1; ``--quick``: 2,000 robots on 64 x 64),
written by :func:`hierplan_opt.viz.html.write_view` and opened ``--repeats`` times in
headless Chromium (Debian's package, Playwright): load time (navigation start to the
first frame drawn), frames per second while playing (the page's requestAnimationFrame
loop), and the median time the page spends drawing one frame; at 1200 x 800 and at
1920 x 1080 (larger robots on screen: discs instead of 2-pixel squares).

Pictures table: the animation (GIF and MP4), the Gantt chart, the plan plot and the
viewer page of a 200-robot plan on the warehouse map (60 s of plan for the animation),
wall time of each in this process.
"""

from __future__ import annotations

import random
import statistics
import tempfile
import time
from pathlib import Path
from typing import Any

from hierplan_opt.api import solve
from hierplan_opt.bench import BenchParser
from hierplan_opt.core.errors import InputError
from hierplan_opt.core.graph import Graph
from hierplan_opt.core.instance import Instance
from hierplan_opt.core.plan import Plan
from hierplan_opt.core.validate import validate

TARGET_LOAD_S = 3.0
TARGET_FPS = 30.0
TARGET_PICTURE_S = 20.0


def _empty_instance(n: int, robots: int, seed: int = 1) -> Any:

    if robots > n * n:
        raise InputError(f"{robots} robots do not fit on a {n} x {n} grid")
    g = Graph.grid(n, n)
    cells = [(x, y) for y in range(n) for x in range(n)]
    rng = random.Random(seed)
    starts, goals = cells[:], cells[:]
    rng.shuffle(starts)
    rng.shuffle(goals)
    return Instance.mapf(g, starts[:robots], goals[:robots], name=f"empty-{n}-{n}")


def _save(path: str, plan: Any) -> None:
    import numpy as np

    from hierplan_opt.io.files import atomic_path

    H = plan.horizon + 1
    arr = np.array([list(p) + [p[-1]] * (H - len(p)) for p in plan.paths], dtype=np.int32)
    with atomic_path(path) as tmp, open(tmp, "wb") as f:
        np.savez_compressed(f, paths=arr)


def _load(path: str, inst: Any) -> Any:
    import numpy as np

    with np.load(path) as z:
        arr = z["paths"]
    if arr.shape[0] != inst.num_agents:
        raise InputError(f"{path}: a plan of {arr.shape[0]} robots, not {inst.num_agents}")
    return Plan.from_paths(arr.tolist()).trimmed()


def viewer_rows(path: Path, repeats: int, sizes: list[tuple[int, int]]) -> list[dict[str, Any]]:
    """Load time and frame rate of the page at ``path`` (medians over ``repeats``)."""
    from hierplan_opt.viz.browser import browser, open_view

    rows = []
    with browser() as b:
        for w, h in sizes:
            loads, fps, draw = [], [], []
            for _ in range(repeats):
                page, errors, load = open_view(b, path, width=w, height=h)
                if errors:
                    raise InputError(f"{path}: the page reported errors: {errors[:2]}")
                m = page.evaluate("hierplan.measure(3000)")
                loads.append(load)
                fps.append(m["fps"])
                draw.append(m["drawMsMedian"])
                page.close()
            rows.append(
                {
                    "viewport": f"{w}x{h}",
                    "load_s": statistics.median(loads),
                    "fps": statistics.median(fps),
                    "draw_ms": statistics.median(draw),
                }
            )
    return rows


def main(argv: list[str] | None = None) -> int:
    p = BenchParser(
        "view",
        __doc__.splitlines()[0] if __doc__ else "view",
        instance="ignored (the instances are generated)",
        quick="2,000 robots on 64 x 64, one repeat",
        time_limit="seconds for the LaCAM solve (default 300, --quick 10)",
    )
    p.add_argument("--robots", type=int, default=None, help="fleet size (default 10000)")
    p.add_argument("--repeats", type=int, default=3, help="page loads per viewport (default 3)")
    p.add_argument("--no-pictures", action="store_true", help="skip the 200-robot picture table")
    p.add_argument(
        "--reuse",
        metavar="NPZ",
        help="keep the LaCAM plan in this file: solved and saved when missing, else loaded "
        "(a 10,000-robot solve takes minutes)",
    )
    args = p.parse_args(argv)
    from hierplan_opt.viz.html import write_view
    from hierplan_opt.viz.scene import scene_from_plan

    n, robots = (64, 2000) if args.quick else (128, 10000)
    robots = args.robots or robots
    repeats = 1 if args.quick else args.repeats
    inst = _empty_instance(n, robots)
    plan = _load(args.reuse, inst) if args.reuse and Path(args.reuse).is_file() else None
    solve_s = float("nan")
    if plan is None:
        t0 = time.perf_counter()
        limit = args.time_limit or (10.0 if args.quick else 300.0)
        res = solve(inst, "lacam", time_limit=limit)
        solve_s = time.perf_counter() - t0
        if res.plan is None:
            print(f"LaCAM found no plan for {robots} robots in {solve_s:.0f} s: {res.status.value}")
            return 1
        plan = res.plan
        if args.reuse:
            _save(args.reuse, plan)
    bad = validate(inst, plan)
    if bad:
        print(f"LaCAM's plan is invalid: {bad[0]}")
        return 1
    with tempfile.TemporaryDirectory() as d:
        page = Path(d) / "view.html"
        t0 = time.perf_counter()
        write_view(scene_from_plan(inst, plan), page)
        write_s = time.perf_counter() - t0
        size = page.stat().st_size / 1e6
        how = f"solved in {solve_s:.1f} s" if solve_s == solve_s else f"loaded from {args.reuse}"
        print(
            f"viewer: {robots} robots, {inst.name}, LaCAM plan makespan {plan.makespan} "
            f"({how}, valid); page {size:.2f} MB written in {write_s:.2f} s"
        )
        print(f"{'viewport':10} {'load_s':>7} {'fps':>6} {'draw_ms':>8}")
        rows = viewer_rows(page, repeats, [(1200, 800), (1920, 1080)])
    ok = True
    for r in rows:
        print(f"{r['viewport']:10} {r['load_s']:>7.2f} {r['fps']:>6.1f} {r['draw_ms']:>8.2f}")
        ok &= r["load_s"] < TARGET_LOAD_S and r["fps"] >= TARGET_FPS
    print(
        f"targets: load < {TARGET_LOAD_S:g} s and >= {TARGET_FPS:g} fps: "
        + ("met" if ok else "NOT met")
        + f" (medians of {repeats} page loads, 3 s of play each)"
    )
    if not args.no_pictures:
        from hierplan_opt.bench.view_pictures import picture_table

        ok &= picture_table(quick=args.quick)
    return 0 if ok else 1
