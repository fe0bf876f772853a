"""``hierplan bench lifelong``: LoRR problems side by side with the Start-Kit's baseline.

For every problem, in one run: the League of Robot Runners Start-Kit's own ``lifelong``
(its C++ default planner, scheduler and executor; built outside the repository with
``build_startkit.sh``) and our loop (:func:`hierplan_opt.lifelong.run_lifelong`, each
scheduler asked for) at the same number of ticks, on the same problem file and the same
delays (our delay stream is checked tick for tick against the ``delayIntervals`` the
Start-Kit wrote). Both logs are replayed by :func:`hierplan_opt.lifelong.check_log`
(footprint overlaps, invalid moves, task events). Columns: tasks finished, throughput
(tasks per tick), wall seconds and milliseconds per tick, our planner's median and
largest time per call (budget: 1 s), peak memory of our process.

The Start-Kit runs against the wall clock (a tick every 100 ms, the planner in a thread
once a second); our loop simulates ticks and times each planning call instead. Problems:
``maze``, ``random``, ``room`` from ``instances/lorr``; ``city``, ``game``,
``warehouse`` and ``iron`` from a Start-Kit checkout (``--startkit DIR``).
"""

from __future__ import annotations

import json
import resource
import subprocess
import tempfile
import time
from pathlib import Path
from typing import Any

from hierplan_opt.bench import BenchParser
from hierplan_opt.core.errors import InputError
from hierplan_opt.io.values import to_json

ROOT = Path(__file__).resolve().parents[2]
LOCAL = ROOT / "instances" / "lorr"
PEERS = Path("/work/peers/Start-Kit")
PROBLEMS = {
    "maze": "maze.domain/maze-example_40.json",
    "random": "random.domain/random-example_400.json",
    "room": "room.domain/room-example_150.json",
    "city": "city.domain/bos-example_600.json",
    "game": "game.domain/orz-example_1800.json",
    "warehouse": "warehouse.domain/fulfill-example_2500.json",
    "iron": "iron_harvest.domain/iron-example_10000.json",
}
DEFAULT = ("maze", "random", "room", "city", "game", "warehouse")
QUICK = ("maze", "random")


def _path(name: str, startkit: Path) -> Path:
    local = LOCAL / PROBLEMS[name]
    if local.exists():
        return local
    p = startkit / "example_problems" / PROBLEMS[name]
    if not p.exists():
        raise InputError(f"problem {name!r}: {p} not found (give the Start-Kit with --startkit)")
    return p


def baseline(binary: Path, problem: Path, ticks: int, timeout: float) -> dict[str, Any]:
    """Run the Start-Kit's ``lifelong`` once; its log, wall time and exit status."""
    with tempfile.TemporaryDirectory() as d:
        out = Path(d) / "out.json"
        cmd = [str(binary), "--inputFile", str(problem), "-o", str(out)]
        cmd += ["--simulationTime", str(ticks), "-c", "1", "-l", str(Path(d) / "log.txt")]
        t0 = time.perf_counter()
        try:
            proc = subprocess.run(cmd, capture_output=True, timeout=timeout, check=False)
        except subprocess.TimeoutExpired:
            return {"error": f"timed out after {timeout:g} s"}
        wall = time.perf_counter() - t0
        if proc.returncode != 0 or not out.exists():
            return {"error": f"exit {proc.returncode}"}
        return {"log": json.loads(out.read_text()), "wall": wall}


def ours(
    problem,
    ticks: int,
    scheduler: str,
    window: int | None,
    planner: str = "pibt",
    budget: float | None = 1.0,
) -> dict[str, Any]:
    """One run of our loop (same process); its result and peak memory so far."""
    from hierplan_opt.lifelong import run_lifelong  # heavy module (scipy): on use only

    res = run_lifelong(
        problem, ticks=ticks, scheduler=scheduler, window=window, planner=planner, budget=budget
    )
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    return {"res": res, "peak_mb": peak}


def main(argv: list[str] | None = None) -> int:
    from hierplan_opt.io.lorr import load_problem
    from hierplan_opt.lifelong import check_log  # heavy module (scipy): on use only

    ap = BenchParser(
        "lifelong",
        (__doc__ or "").split("\n\n")[0],
        instance=f"problems to run, of {', '.join(PROBLEMS)} (default: all but iron)",
        quick="maze and random, 200 ticks",
        time_limit="seconds allowed per Start-Kit run (default 1800)",
    )
    ap.add_argument("--ticks", type=int, default=1000, help="execution ticks (default 1000)")
    ap.add_argument("--startkit", type=Path, default=PEERS, help="Start-Kit checkout and build")
    ap.add_argument("--no-baseline", action="store_true", help="our runs only")
    ap.add_argument(
        "--scheduler",
        action="append",
        choices=("greedy", "hungarian"),
        help="our schedulers to run (repeatable; default both)",
    )
    ap.add_argument(
        "--window", type=int, help="our planning window (default 6; 4 above 1,000 robots)"
    )
    ap.add_argument(
        "--planner",
        action="append",
        choices=("pibt", "lacam", "pibt-guided", "lacam-guided"),
        help="our planners (repeatable; default pibt and lacam, the windowed planners of "
        "search/windowed; *-guided: windowed PIBT guided by that registry solver)",
    )
    ap.add_argument(
        "--budget", type=float, default=1.0, help="our seconds per planning call (default 1)"
    )
    ap.add_argument("--json", metavar="FILE", help="also write the rows as JSON")
    args = ap.parse_args(argv)
    names = args.instance or (QUICK if args.quick else DEFAULT)
    for n in names:
        if n not in PROBLEMS:
            raise InputError(f"--instance {n}: unknown problem (use: {', '.join(PROBLEMS)})")
    ticks = 200 if args.quick and args.ticks == 1000 else args.ticks
    if ticks < 1:
        raise InputError(f"--ticks must be at least 1, got {ticks}")
    schedulers = args.scheduler or ["greedy", "hungarian"]
    binary = args.startkit / "build" / "lifelong"
    use_baseline = not args.no_baseline
    if use_baseline and not binary.exists():
        print(f"(no Start-Kit build at {binary}: our runs only; see build_startkit.sh)")
        use_baseline = False
    rows: list[dict[str, Any]] = []
    print(
        f"{'problem':<10} {'robots':>6} {'ticks':>5}  {'who':<24} {'tasks':>6} {'per tick':>8} "
        f"{'wall s':>7} {'ms/tick':>7} {'plan med/max s':>14} {'peak MB':>7}  replay"
    )
    for name in names:
        path = _path(name, args.startkit)
        problem = load_problem(path)
        base_delays = None
        if use_baseline:
            b = baseline(binary, path, ticks, args.time_limit or 1800.0)
            if "error" in b:
                row = {"problem": name, "who": "start-kit", "error": b["error"]}
                print(f"{name:<10} {problem.team_size:>6} {ticks:>5}  start-kit: {b['error']}")
            else:
                log = b["log"]
                rep = check_log(problem, log)
                base_delays = log.get("delayIntervals")
                pt = sorted(log.get("plannerTimes", []) or [float("nan")])
                row = {
                    "problem": name,
                    "robots": problem.team_size,
                    "ticks": ticks,
                    "who": "start-kit",
                    "tasks": log["numTaskFinished"],
                    "wall": b["wall"],
                    "plan_med": pt[len(pt) // 2],
                    "plan_max": pt[-1],
                    "replay_ok": rep.ok,
                    "replay": _replay_text(rep),
                    "errors": log.get("numPlannerErrors"),
                }
                _print(row)
            rows.append(row)
        planners = args.planner or ["pibt", "lacam"]
        for sched, planner in [(s_, p_) for p_ in planners for s_ in schedulers]:
            o = ours(problem, ticks, sched, args.window, planner, args.budget)
            res = o["res"]
            rep = check_log(problem, res.log)
            same = None
            if base_delays is not None:
                same = res.log["delayIntervals"] == base_delays
            s = res.summary()
            row = {
                "problem": name,
                "robots": problem.team_size,
                "ticks": ticks,
                "who": f"ours ({sched}+{planner})",
                "tasks": res.tasks_finished,
                "wall": res.wall_time,
                "plan_med": s["planner_s_median"],
                "plan_max": s["planner_s_max"],
                "over_budget": s["over_budget_calls"],
                "calls": s["planner_calls"],
                "cut": s["calls_cut_by_deadline"],
                "preprocess": s["preprocess_s"],
                "peak_mb": o["peak_mb"],
                "replay_ok": rep.ok,
                "replay": _replay_text(rep),
                "same_delays": same,
                "delays": res.delays,
                "handled": res.handled,
            }
            _print(row)
            rows.append(row)
    if args.json:
        Path(args.json).write_text(to_json(rows, indent=1, default=str))
    return 0


def _replay_text(rep) -> str:
    if rep.ok:
        return "ok"
    return f"{rep.invalid} invalid, {rep.collisions} overlaps, {rep.bad_events} bad events"


def _print(row: dict[str, Any]) -> None:
    t = row["ticks"]
    peak = f"{row['peak_mb']:.0f}" if "peak_mb" in row else "-"
    same = row.get("same_delays")
    extra = "" if same is None else ("; same delays" if same else "; DELAYS DIFFER")
    if "over_budget" in row:
        extra += f"; over budget {row['over_budget']}/{row['calls']}, cut {row['cut']}"
    print(
        f"{row['problem']:<10} {row['robots']:>6} {t:>5}  {row['who']:<24} {row['tasks']:>6} "
        f"{row['tasks'] / t:>8.3f} {row['wall']:>7.1f} {1000 * row['wall'] / t:>7.1f} "
        f"{row['plan_med']:>6.3f}/{row['plan_max']:<7.3f} {peak:>7}  {row['replay']}{extra}",
        flush=True,
    )
