"""``hierplan bench lacam``: PIBT and LaCAM* on large fleets, side by side with peers.

Measures, in one run, the targets of issue 20 and prints one table:

* first solution (the whole ``hierplan_opt.solve`` call, plan validated) for 400
  agents of ``random-32-32-10-random-1``, all 409 of ``random-32-32-20-random-1``,
  1000 agents on ``warehouse-10-20-10-2-1`` and 2000 on an empty 64 x 64 map (the
  last two scenarios are generated, ``instances/large/``), with the peak memory of
  the process;
* anytime quality: sum of costs over the sum of distances after 10 s and after the
  full anytime run (60 s by default), and the MAPF-LNS area under the curve,
  ``integral over [0, T] of (cost(t) - sum of distances) dt`` (before the first plan
  the first plan's cost counts), on the same four instances.

Peers are measured in the same run when their locations are given; each runs in its
own process and is timed there around its own solve call:

* ``--peer-lacam3 PATH``: the ``main`` binary of Kei18/lacam3 (Release build). First
  solution: run with ``--no-star``, its own ``comp_time`` (which includes its distance
  tables); anytime: its final sum of costs after 10 s and after 30 s;
* ``--peer-pylacam PYTHON``: a Python interpreter that imports ``pycam`` from
  Kei18/py-lacam (branch ``pibt``); ``LaCAM().solve(..., flg_star=False)``;
* ``--peer-pypibt PYTHON``: a Python interpreter that imports ``pypibt`` from
  Kei18/pypibt; the ``PIBT(...)`` constructor (distance tables) plus ``run()``.

Without peers only our rows are printed. Our runs each use a fresh process too
(``--worker``), so peak memory is per instance.

Example
-------
>>> main(["--quick", "--instance", "first:random-32-32-10-random-1:20"])  # doctest: +ELLIPSIS
measure ...
first ... lacam ...
0
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

from hierplan_opt.api import solve
from hierplan_opt.bench import BenchParser
from hierplan_opt.core.errors import InputError
from hierplan_opt.experiments.data import shipped_file

_MOVINGAI = shipped_file("instances/movingai")  # package data in an installed wheel too
_LARGE = shipped_file("instances/large")


@dataclass(frozen=True)
class Case:
    """One benchmark instance: map and scenario files and the agent count."""

    name: str
    map_path: Path
    scen_path: Path
    agents: int


CASES = {
    "random-32-32-10-random-1": (
        _MOVINGAI / "random-32-32-10.map",
        _MOVINGAI / "random-32-32-10-random-1.scen",
    ),
    "random-32-32-20-random-1": (
        _MOVINGAI / "random-32-32-20.map",
        _MOVINGAI / "random-32-32-20-random-1.scen",
    ),
    "warehouse-10-20-10-2-1-gen-1": (
        _MOVINGAI / "warehouse-10-20-10-2-1.map",
        _LARGE / "warehouse-10-20-10-2-1-gen-1.scen",
    ),
    "empty-64-64-gen-1": (_LARGE / "empty-64-64.map", _LARGE / "empty-64-64-gen-1.scen"),
}

#: (measure, case, agents, our first-solution target in seconds or None)
FIRST = [
    ("first", "random-32-32-10-random-1", 400, 0.5),
    ("first", "random-32-32-20-random-1", 409, 10.0),
    ("first", "warehouse-10-20-10-2-1-gen-1", 1000, 15.0),
    ("first", "empty-64-64-gen-1", 2000, 30.0),
]
ANYTIME = [
    ("anytime", "random-32-32-10-random-1", 400, None),
    ("anytime", "random-32-32-20-random-1", 409, None),
    ("anytime", "warehouse-10-20-10-2-1-gen-1", 1000, None),
    ("anytime", "empty-64-64-gen-1", 2000, None),
]
#: Python ports are run on this measure only (they take minutes on the others).
PY_PEERS_ON = ("random-32-32-10-random-1", 400)
MEMORY_LIMIT_MB = 4096
QUALITY_FACTOR = 1.25

# ---------------------------------------------------------------- peer drivers
# Small driver programs run by the peers' own interpreters; they use only the peers'
# public functions and print one JSON line.
_PYLACAM = """
import json, sys, time
from pycam import LaCAM, get_grid, get_scenario
grid = get_grid(sys.argv[1]); starts, goals = get_scenario(sys.argv[2], int(sys.argv[3]))
t = time.perf_counter()
plan = LaCAM().solve(grid=grid, starts=starts, goals=goals, seed=0,
                     time_limit_ms=int(float(sys.argv[4]) * 1000), flg_star=False, verbose=0)
dt = time.perf_counter() - t
ok = len(plan) > 0 and all(a == b for a, b in zip(plan[-1], goals))
paths = [[q[i] for q in plan] for i in range(len(starts))] if ok else []
print(json.dumps({"time": dt, "solved": ok, "configs": [[list(v) for v in p] for p in paths]}))
"""
_PYPIBT = """
import json, sys, time
from pypibt import PIBT, get_grid, get_scenario
grid = get_grid(sys.argv[1]); starts, goals = get_scenario(sys.argv[2], int(sys.argv[3]))
t = time.perf_counter()
plan = PIBT(grid, starts, goals, seed=0).run(max_timestep=1000)
dt = time.perf_counter() - t
ok = all(a == b for a, b in zip(plan[-1], goals))
paths = [[q[i] for q in plan] for i in range(len(starts))] if ok else []
print(json.dumps({"time": dt, "solved": ok, "configs": [[list(v) for v in p] for p in paths]}))
"""


def _soc(paths: list[list]) -> int:
    """Sum over agents of the last arrival (paths as lists of positions)."""
    total = 0
    for p in paths:
        t = len(p) - 1
        while t > 0 and p[t - 1] == p[-1]:
            t -= 1
        total += t
    return total


def _run(cmd: list[str], timeout: float) -> tuple[str, float, float]:
    """Run ``cmd``; its stdout, wall time and peak resident memory (MB)."""
    with tempfile.TemporaryFile() as out:
        t0 = time.perf_counter()
        p = subprocess.Popen(cmd, stdout=out, stderr=subprocess.DEVNULL)
        deadline = t0 + timeout
        while True:
            pid, status, usage = os.wait4(p.pid, os.WNOHANG)
            if pid:
                break
            if time.perf_counter() > deadline:
                p.kill()
                pid, status, usage = os.wait4(p.pid, 0)
                break
            time.sleep(0.005)
        wall = time.perf_counter() - t0
        p.returncode = os.waitstatus_to_exitcode(status)
        out.seek(0)
        return out.read().decode(errors="replace"), wall, usage.ru_maxrss / 1024.0


# ---------------------------------------------------------------- measurements
def _ours(
    solver: str, case: Case, time_limit: float, anytime: float | None, **options: object
) -> dict:
    spec = {
        "solver": solver,
        "map": str(case.map_path),
        "scen": str(case.scen_path),
        "agents": case.agents,
        "time_limit": time_limit,
        "options": dict(options, anytime=anytime) if solver == "lacam" else options,
    }
    out, wall, peak = _run(
        [sys.executable, "-m", "hierplan_opt.bench.lacam", "--worker", json.dumps(spec)],
        time_limit + 120,
    )
    try:
        res = json.loads(out.strip().splitlines()[-1])
    except (ValueError, IndexError):
        return {"error": "worker failed", "peak": peak}
    res["peak"] = peak
    return res


def _worker(spec: dict) -> int:
    """Run one solve in this process and print the result as JSON."""
    import resource

    from hierplan_opt.io.movingai import load_movingai

    inst = load_movingai(spec["map"], spec["scen"], spec["agents"])
    t0 = time.perf_counter()
    r = solve(inst, spec["solver"], time_limit=spec["time_limit"], **spec["options"])
    dt = time.perf_counter() - t0
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
    out = {
        "time": dt,
        "status": r.status.value,
        "cost": r.cost,
        "lb": r.lower_bound if r.lower_bound is not None else None,
        "first_time": r.stats.get("first_time", dt if r.plan is not None else None),
        "first_cost": r.stats.get("first_cost", r.cost),
        "history": r.stats.get("history", []),
        "self_peak": peak,
    }
    print(json.dumps(out))
    return 0


def _lacam3(binary: str, case: Case, seconds: int, star: bool) -> dict:
    with tempfile.TemporaryDirectory() as tmp:
        log = Path(tmp) / "result.txt"
        cmd = [
            binary,
            "-m",
            str(case.map_path),
            "-i",
            str(case.scen_path),
            "-N",
            str(case.agents),
            "-t",
            str(seconds),
            "-v",
            "0",
            "-o",
            str(log),
            "-l",
        ]
        if not star:
            cmd.append("--no-star")
        _, wall, peak = _run(cmd, seconds + 120)
        if not log.exists():
            return {"error": "no result file", "wall": wall, "peak": peak}
        kv = dict(line.split("=", 1) for line in log.read_text().splitlines() if "=" in line)
    if kv.get("solved") != "1":
        return {"error": "not solved", "wall": wall, "peak": peak}
    return {
        "time": float(kv["comp_time"]) / 1000.0,
        "first_time": float(kv["comp_time_initial_solution"]) / 1000.0,
        "cost": int(kv["soc"]),
        "lb": int(kv["soc_lb"]),
        "wall": wall,
        "peak": peak,
    }


def _python_peer(python: str, driver: str, case: Case, limit: float) -> dict:
    out, wall, peak = _run(
        [python, "-c", driver, str(case.map_path), str(case.scen_path), str(case.agents)]
        + [str(limit)],
        limit + 120,
    )
    try:
        res = json.loads(out.strip().splitlines()[-1])
    except (ValueError, IndexError):
        return {"error": "driver failed", "wall": wall, "peak": peak}
    paths = res.pop("configs")
    res.update(cost=_soc(paths) if res["solved"] else None, wall=wall, peak=peak)
    return res


def _cost_at(history: list, t: float, first: tuple[float, int] | None) -> int | None:
    best = None
    for ht, hc in history:
        if ht <= t:
            best = hc
    if best is None and first is not None and first[0] <= t:
        best = first[1]
    return best


def _auc(history: list, lb: int, horizon: float) -> float:
    """Area under ``cost(t) - lb`` over [0, horizon]; the first cost before it exists."""
    if not history:
        return float("nan")
    pts = sorted((float(t), int(c)) for t, c in history if t <= horizon)
    area = (pts[0][1] - lb) * pts[0][0]
    for (t0, c0), (t1, _) in zip(pts, pts[1:], strict=False):
        area += (c0 - lb) * (t1 - t0)
    area += (pts[-1][1] - lb) * (horizon - pts[-1][0])
    return area


# ---------------------------------------------------------------- table
HEAD = (
    f"{'measure':8} {'instance':29} {'agents':>6} {'solver':9} {'status':10} {'time_s':>8} "
    f"{'cost':>7} {'LB':>6} {'cost/LB':>7} {'peak_MB':>8}  note"
)


def _row(measure: str, case: Case, solver: str, r: dict, note: str = "") -> None:
    if "error" in r:
        print(
            f"{measure:8} {case.name:29} {case.agents:>6} {solver:9} {'ERROR':10} "
            f"{'-':>8} {'-':>7} {'-':>6} {'-':>7} {r.get('peak', 0):>8.0f}  {r['error']}",
            flush=True,
        )
        return
    cost = r.get("cost")
    lb = r.get("lb")
    gap = f"{cost / lb:.3f}" if cost and lb else "-"
    t = r.get("time")
    print(
        f"{measure:8} {case.name:29} {case.agents:>6} {solver:9} {r.get('status', 'solved'):10} "
        f"{t if t is not None else float('nan'):>8.3f} {cost if cost is not None else '-':>7} "
        f"{lb if lb is not None else '-':>6} {gap:>7} {r.get('peak', 0):>8.0f}  {note}",
        flush=True,
    )


def main(argv: list[str] | None = None) -> int:

    ap = BenchParser(
        "lacam",
        (__doc__ or "").split("\n\n")[0],
        instance="run only these, MEASURE:CASE:K (measure first|anytime, case name, agents)",
        quick="smaller instances, 5 s anytime runs (a smoke run)",
        time_limit="seconds per first-solution run (default 60)",
        instance_aliases=("--only",),
    )
    ap.add_argument("--peer-lacam3", metavar="PATH", help="lacam3 `main` binary (Release build)")
    ap.add_argument("--peer-pylacam", metavar="PYTHON", help="interpreter that imports pycam")
    ap.add_argument("--peer-pypibt", metavar="PYTHON", help="interpreter that imports pypibt")
    ap.add_argument("--anytime", type=float, default=60.0, help="seconds of our anytime runs")
    ap.add_argument(
        "--ablation",
        action="store_true",
        help="our refinements switched off one at a time (first plan and anytime runs)",
    )
    ap.add_argument("--worker", metavar="JSON", help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.worker:
        return _worker(json.loads(args.worker))
    if args.ablation:
        return _ablation(10.0 if args.anytime == 60.0 else args.anytime)
    plan = FIRST + ANYTIME
    anytime = 5.0 if args.quick and args.anytime == 60.0 else args.anytime
    if args.quick:
        plan = [(m, c, min(k, 100), None) for m, c, k, _ in plan[:1] + ANYTIME[:1]]
    limit = args.time_limit or 60.0
    if args.instance:
        plan = []
        targets = {(c, k): t for _, c, k, t in FIRST}
        for spec in args.instance:
            m, c, k = (spec.split(":") + ["", ""])[:3]
            if c not in CASES or m not in ("first", "anytime") or not k.isdigit():
                raise InputError(
                    f"--instance {spec}: expected first|anytime:CASE:K, CASE one of {list(CASES)}"
                )
            plan.append((m, c, int(k), targets.get((c, int(k))) if m == "first" else None))
    print(HEAD)
    print("-" * len(HEAD))
    verdicts: list[str] = []
    for measure, name, k, target in plan:
        map_path, scen_path = CASES[name]
        case = Case(name, map_path, scen_path, k)
        if measure == "first":
            _first(case, target, args, verdicts, limit)
        else:
            _anytime_rows(case, anytime, args, verdicts)
    if verdicts:
        print()
        print("targets (issue 20):")
        for v in verdicts:
            print("  " + v)
    return 0


def _first(
    case: Case, target: float | None, args: argparse.Namespace, verdicts: list[str], limit: float
) -> None:
    ours = _ours("lacam", case, limit, 0.0)
    _row("first", case, "lacam", ours, "whole solve call")
    pibt = _ours("pibt", case, limit, None)
    _row("first", case, "pibt", pibt, "whole solve call")
    peers: dict[str, dict] = {}
    if args.peer_lacam3:
        peers["lacam3"] = _lacam3(args.peer_lacam3, case, int(limit), star=False)
        _row("first", case, "lacam3", peers["lacam3"], "comp_time, --no-star")
    if (case.name, case.agents) == PY_PEERS_ON:
        if args.peer_pylacam:
            peers["py-lacam"] = _python_peer(args.peer_pylacam, _PYLACAM, case, limit)
            _row("first", case, "py-lacam", peers["py-lacam"], "solve call")
        if args.peer_pypibt:
            peers["pypibt"] = _python_peer(args.peer_pypibt, _PYPIBT, case, limit)
            _row("first", case, "pypibt", peers["pypibt"], "PIBT() + run()")
    if target is None or "error" in ours or ours.get("cost") is None:
        if target is not None:
            verdicts.append(f"{case.name} x{case.agents}: NOT met (no plan)")
        return
    t = ours["time"]
    line = f"{case.name} x{case.agents}: first solution {t:.3f} s < {target:g} s: " + (
        "met" if t < target else "NOT met"
    )
    py = [(n, r["time"]) for n, r in peers.items() if n != "lacam3" and r.get("solved")]
    if py:
        n, pt = min(py, key=lambda x: x[1])
        ratio = pt / t
        verdict = "met" if ratio >= 2 else "NOT met"
        line += f"; {ratio:.1f}x faster than {n} ({pt:.3f} s): {verdict}"
    if "lacam3" in peers and "time" in peers["lacam3"]:
        t3 = peers["lacam3"]["time"]
        line += f"; lacam3 {t3:.3f} s (ours/lacam3 {t / t3:.2f})"
    if case.agents >= 2000:
        line += f"; peak {ours['peak']:.0f} MB < {MEMORY_LIMIT_MB} MB: " + (
            "met" if ours["peak"] < MEMORY_LIMIT_MB else "NOT met"
        )
    verdicts.append(line)


def _anytime_rows(
    case: Case, anytime: float, args: argparse.Namespace, verdicts: list[str]
) -> None:
    ours = _ours("lacam", case, anytime, None)
    if "error" in ours:
        _row("anytime", case, "lacam", ours)
        return
    lb = ours["lb"]
    hist = [(float(t), int(c)) for t, c in ours["history"]]
    first = (ours["first_time"], ours["first_cost"])
    marks = sorted({min(10.0, anytime), anytime})
    for m in marks:
        c = _cost_at(hist, m, first)
        r = dict(ours, time=m, cost=c)
        note = f"after {m:g} s"
        if m == anytime:
            note += f"; AUC {_auc(hist, lb, anytime):.0f}"
        _row("anytime", case, "lacam", r, note)
    if args.peer_lacam3:
        l3 = {}
        for secs in (10, 30):
            l3[secs] = _lacam3(args.peer_lacam3, case, secs, star=True)
            _row("anytime", case, "lacam3", l3[secs], f"after {secs} s")
        ref = l3[30].get("cost")
        final = _cost_at(hist, anytime, first)
        if ref and final:
            ok = final <= QUALITY_FACTOR * ref
            verdicts.append(
                f"{case.name} x{case.agents}: cost after {anytime:g} s {final} vs lacam3 after "
                f"30 s {ref}: ratio {final / ref:.3f} <= {QUALITY_FACTOR}: "
                + ("met" if ok else "NOT met")
            )
    if case.agents >= 2000:
        verdicts.append(
            f"{case.name} x{case.agents}: anytime run peak {ours['peak']:.0f} MB < "
            f"{MEMORY_LIMIT_MB} MB: " + ("met" if ours["peak"] < MEMORY_LIMIT_MB else "NOT met")
        )


#: (label, solver, options) of the ablation runs: each switches one refinement off.
FIRST_VARIANTS = [
    ("lacam", "lacam", {}),
    ("no swap", "lacam", {"swap": False}),
    ("pibt", "pibt", {}),
    ("pibt no swap", "pibt", {"swap": False, "max_steps": 2000}),
]
ANYTIME_VARIANTS = [
    ("lacam*", {}),
    ("no LNS", {"refine": False}),
    ("no guide", {"guide": False}),
    ("mc=4", {"mc": 4}),
    ("search only", {"refine": False, "guide": False}),
]


def _ablation(anytime: float) -> int:
    """Our own variants side by side (first plan; anytime cost and AUC)."""
    print(HEAD)
    print("-" * len(HEAD))
    for name, k in (("random-32-32-10-random-1", 400), ("random-32-32-20-random-1", 409)):
        case = Case(name, *CASES[name], k)
        for label, solver, opts in FIRST_VARIANTS:
            extra = {"anytime": 0.0} if solver == "lacam" else {}
            r = _ours(solver, case, 60.0, extra.pop("anytime", None), **opts)
            _row("first", case, label, r)
        for label, opts in ANYTIME_VARIANTS:
            r = _ours("lacam", case, anytime, None, **opts)
            if "error" in r:
                _row("anytime", case, label, r)
                continue
            hist = [(float(t), int(c)) for t, c in r["history"]]
            c = _cost_at(hist, anytime, (r["first_time"], r["first_cost"]))
            auc = _auc(hist, r["lb"], anytime)
            _row("anytime", case, label, dict(r, time=anytime, cost=c), f"AUC {auc:.0f}")
    return 0


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
