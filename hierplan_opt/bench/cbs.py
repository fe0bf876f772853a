"""``hierplan bench cbs``: optimal CBS on the MovingAI samples.

Prints one row per (instance, agents, option set): status, time, cost, lower bound,
cost / lower bound, high-level nodes expanded / generated and low-level expansions.

Example
-------
``hierplan bench cbs --quick`` (a few seconds) or ``hierplan bench cbs`` (the targets,
60 s each), ``hierplan bench cbs --instance room-32-32-4-even-1:20 --time-limit 30
--option symmetry=false``; ``--rectangle-ablation`` adds a run without rectangle
reasoning per instance (column ``rect``: rectangle splits).

``hierplan bench cbs --reference [--quick] [--anchor PATH]``: the 31 MovingAI instances
with known optima of issue 22 (``reference_optimal_soc.json`` beside the maps), each
checked against its optimum, beside CBSH2-RTC: its times as recorded in that file, or,
with ``--anchor`` (a CBSH2-RTC binary), run here instance by instance right after ours
(interleaved), with its high-level and low-level node counts (column ``rect``: our
rectangle splits / the C++'s rectangle conflicts). The summary gives the
solved counts and the geometric mean of our time over the C++'s on the instances both
solve. Times compared are CPU seconds, as CBSH2-RTC measures them (``clock()``), so a
loaded machine does not skew the ratio: ours is the solving process's CPU time for
``registry.run`` (feasibility test, distances and search; the plan is validated
afterwards by ``registry.checked``, untimed), the C++'s is its ``runtime`` plus
``preprocessing runtime`` (its heuristic tables) when run here. Our time limit is
wall-clock, the C++'s is on CPU time.
Short instances are timed repeatedly (single CPU times of a few milliseconds are noise):
each side runs again, interleaved, until it has spent ``REPEAT_BUDGET`` seconds of CPU or
made ``REPEAT_MAX`` runs, each of ours on a freshly loaded instance (nothing cached); the
table gives the median of each side's runs (column ``runs``: ours/C++); an instance
that takes a side ``REPEAT_BUDGET`` or more is run once by it.

``--per-process`` (with ``--reference``): every run is its own process, as a user runs
the toolkit from a script: ``hierplan solve MAP --scen SCEN --agents K --out plan.json``
beside ``cbs ... --outputPaths=paths.txt``, interleaved run by run. Each side repeats an
instance while its processes have taken under ``PROCESS_BUDGET`` seconds of wall time in
all (at most ``PROCESS_MAX`` runs); medians. Columns: the solve's own time (ours: the
CPU seconds of ``hierplan_opt.solve`` in the process, printed by ``hierplan solve`` as
``cpu=``, which counts everything the solve triggers -- distance tables, feasibility
test, lazy imports and kernel loading on its path; the C++'s: ``runtime`` plus
``preprocessing runtime``, CPU) and the whole process (wall-clock from start to exit,
and the CPU seconds of user and system time from the kernel's accounting). The summary
gives the geometric means of the three ratios over the instances both solve.

Both tables end, when a side left an instance unsolved, with a line of the bounds each
side proved there (``unsolved by a side (...), ours/C++: NAME LB/LB, ...``; a side that
solved it shows its cost): on the instances neither solves, the bound reached in the time is
the measure of progress. The C++'s is its ``min f value``; without ``--anchor``, the
bound recorded in the reference file.
"""

from __future__ import annotations

import csv
import json
import math
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

from hierplan_opt import registry
from hierplan_opt.api import solve
from hierplan_opt.bench import SEARCH_HEAD, BenchParser, scenario, search_columns, time_limit
from hierplan_opt.core.errors import InputError
from hierplan_opt.core.options import parse_pairs
from hierplan_opt.core.result import Status

#: (scenario stem, agents): the optimal-search targets.
TARGETS = [
    ("random-32-32-20-random-1", 20),
    ("random-32-32-20-random-1", 30),
    ("warehouse-10-20-10-2-1-even-1", 100),
    ("room-32-32-4-even-1", 20),
    ("maze-32-32-2-even-1", 20),
    ("empty-32-32-even-1", 50),
]
QUICK = [
    ("random-32-32-20-random-1", 20),
    ("empty-16-16-even-1", 16),
    ("room-32-32-4-even-1", 8),
    ("maze-32-32-2-even-1", 8),
]
#: ``--reference --quick``: reference instances that take both solvers under a second.
REFERENCE_QUICK = [
    "empty-8-8-even-1:16",
    "empty-32-32-even-1:50",
    "random-32-32-10-random-1:50",
    "random-32-32-20-random-1:30",
    "maze-32-32-2-even-1:10",
    "room-32-32-4-even-1:10",
    "den312d-even-2:20",
    "warehouse-10-20-10-2-1-even-1:30",
]
#: ``--per-process``: each side repeats an instance while its processes took under this
#: many wall seconds in all ...
PROCESS_BUDGET = 3.0
#: ... and at most this many times.
PROCESS_MAX = 3
#: ``--reference``: each side repeats an instance until it spent this much CPU (s) ...
REPEAT_BUDGET = 0.5
#: ... or made this many runs; the table gives the median.
REPEAT_MAX = 11


def main(argv: list[str] | None = None) -> int:
    p = BenchParser(
        "cbs",
        (__doc__ or "").split("\n")[0],
        instance="scenario and agent count, e.g. room-32-32-4-even-1:20",
    )
    p.add_argument("--objective", default="soc", choices=["soc", "makespan"])
    p.add_argument(
        "--option", action="append", default=[], metavar="NAME=VALUE", help="a cbs option"
    )
    p.add_argument(
        "--rectangle-ablation",
        action="store_true",
        help="also run each instance with rectangle reasoning switched off",
    )
    p.add_argument(
        "--ablation",
        action="store_true",
        help="also run each instance with each acceleration switched off",
    )
    p.add_argument(
        "--reference",
        action="store_true",
        help="the 31 instances with known optima, beside CBSH2-RTC (see the module doc)",
    )
    p.add_argument("--anchor", metavar="PATH", help="a CBSH2-RTC binary to run beside ours")
    p.add_argument(
        "--per-process",
        action="store_true",
        help="with --reference: every run its own `hierplan solve` process (see the module doc)",
    )
    args = p.parse_args(argv)
    if args.per_process:
        ref = reference_table()
        names = args.instance or (REFERENCE_QUICK if args.quick else sorted(ref))
        known = {}
        for name in names:
            if name not in ref:
                raise InputError(f"--instance {name}: not a reference instance (SCEN:K)")
            known[name] = ref[name]["optimal_soc"]
        tl = time_limit(args.time_limit, False)
        rows = per_process(names, "cbs", tl, args.anchor, known=known)
        return 1 if any(r["wrong"] for r in rows) else 0
    if args.reference or args.anchor:
        opts = registry.get("cbs").load().options.parse(parse_pairs(args.option, "--option"), "cbs")
        return reference(args.instance, args.quick, args.time_limit, args.anchor, opts)

    specs = args.instance or [f"{s}:{k}" for s, k in (QUICK if args.quick else TARGETS)]
    tl = time_limit(args.time_limit, args.quick)
    texts = parse_pairs(args.option, "--option")
    base = registry.get("cbs").load().options.parse(texts, "cbs")
    variants: list[tuple[str, dict]] = [("default" if not base else "custom", base)]
    if args.rectangle_ablation and not args.ablation:
        variants.append(("-rect", {**base, "rectangle": False}))
    if args.ablation:
        for name, off in (
            ("-prio", {"prioritize_conflicts": False}),
            ("-bypass", {"bypass": False}),
            ("h=dg", {"heuristic": "dg"}),
            ("h=none", {"heuristic": "none"}),
            ("+disjoint", {"disjoint_splitting": True}),
            ("-symmetry", {"symmetry": False}),
            ("-rect", {"rectangle": False}),
        ):
            variants.append((name, {**base, **off}))
    head = f"{'instance':32} {'k':>4} {'options':10} {SEARCH_HEAD} {'rect':>5}"
    print(head)
    print("-" * len(head))
    for spec in specs:
        stem, inst = scenario(spec)
        k = inst.num_agents
        for label, opts in variants:
            r = solve(inst, "cbs", time_limit=tl, cost=args.objective, **opts)
            print(
                f"{stem:32} {k:>4} {label:10} {search_columns(r)} "
                f"{r.stats.get('rectangle_splits', 0):>5}",
                flush=True,
            )
    return 0


def reference_table() -> dict[str, dict[str, Any]]:
    """``"SCEN:K"`` -> optimum (None if unknown), lower bound, CBSH2-RTC's recorded time.

    Example
    -------
    >>> ref = reference_table()
    >>> len(ref), ref["room-32-32-4-even-1:20"]["optimal_soc"]
    (31, 506)
    """
    from hierplan_opt.experiments.data import instances_dir

    path = instances_dir() / "movingai" / "reference_optimal_soc.json"
    data = json.loads(path.read_text(encoding="utf-8"))
    return {k: v for k, v in data.items() if not k.startswith("_")}


def run_anchor(binary: str, spec: str, time_limit: float) -> dict[str, Any]:
    """Run the CBSH2-RTC binary on ``spec``: solved, time, cost and node counts."""
    from hierplan_opt.experiments.data import movingai_files

    mp, scen = movingai_files(spec.partition(":")[0])
    k = spec.partition(":")[2]
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "stats.csv"
        cmd = [binary, "-m", str(mp), "-a", str(scen), "-k", k, "-t", f"{time_limit:g}"]
        cmd += ["-o", str(out), "-s", "0"]
        try:
            subprocess.run(cmd, capture_output=True, timeout=2 * time_limit + 60, check=False)
        except subprocess.TimeoutExpired:  # its limit is on search time: a loaded machine
            return {
                "solved": False,
                "time": math.inf,
                "cost": -1,
                "hl": "-",
                "ll": "-",
                "rect": "-",
                "lb": "-",
            }
        except OSError as exc:
            raise InputError(f"--anchor {binary}: {exc}") from None
        if not out.is_file():
            raise InputError(f"--anchor {binary}: wrote no statistics for {spec}")
        with out.open(newline="") as fh:
            row = next(csv.DictReader(fh))
    cost = int(float(row["solution cost"]))
    hl_exp = int(float(row["#high-level expanded"]))
    hl_gen = int(float(row["#high-level generated"]))
    return {
        "solved": cost >= 0,
        "time": float(row["runtime"]) + float(row.get("preprocessing runtime") or 0),
        "cost": cost,
        "hl": f"{hl_exp}/{hl_gen}",
        "ll": int(float(row["#low-level expanded"])),
        "rect": int(float(row.get("rectangle conflicts") or 0)),
        "lb": row.get("min f value", "-"),
    }


def _timed(cmd: list[str], timeout: float) -> tuple[str, float, float, bool]:
    """Run ``cmd``: (stdout, wall seconds, CPU seconds of user and system time, whether it
    was killed at ``timeout``)."""
    import resource

    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    try:
        proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL)
    except OSError as exc:
        raise InputError(f"{cmd[0]}: {exc}") from None
    killed = False
    try:
        out, _ = proc.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        proc.kill()
        out, _ = proc.communicate()
        killed = True
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return out.decode("utf-8", "replace"), wall, cpu, killed


def parse_summary(line: str) -> dict[str, str]:
    """The ``key=value`` fields of ``hierplan solve``'s summary line (``status``: the first word).

    Example
    -------
    >>> d = parse_summary("OPTIMAL cost=8 lb=8 runtime=0.012s cpu=0.010s high_level_expanded=3")
    >>> d["status"], d["cost"], d["cpu"], d["high_level_expanded"]
    ('OPTIMAL', '8', '0.010s', '3')
    """
    words = line.split()
    out = {"status": words[0] if words else "NO_OUTPUT"}
    for w in words[1:]:
        key, eq, value = w.partition("=")
        if eq:
            out[key] = value
    return out


def hierplan_command() -> list[str]:
    """How to start ``hierplan`` beside this interpreter (its console script if present)."""
    script = Path(sys.executable).with_name("hierplan")
    return [str(script)] if script.is_file() else [sys.executable, "-m", "hierplan_opt"]


def run_ours_process(
    spec: str, solver: str, tl: float, tmp: Path, w: float | None = None
) -> dict[str, Any]:
    """One ``hierplan solve`` process on ``spec``: status, cost, solve CPU, process wall/CPU."""
    from hierplan_opt.experiments.data import movingai_files

    mp, scen = movingai_files(spec.partition(":")[0])
    plan = tmp / "plan.json"
    plan.unlink(missing_ok=True)
    cmd = hierplan_command() + ["-q", "solve", str(mp), "--scen", str(scen)]
    cmd += ["--agents", spec.partition(":")[2], "--solver", solver, "--time-limit", f"{tl:g}"]
    cmd += ["--out", str(plan)] + ([] if w is None else ["--w", f"{w:g}"])
    out, wall, pcpu, killed = _timed(cmd, 2 * tl + 60)
    lines = [ln for ln in out.splitlines() if ln.strip()]
    d = parse_summary(lines[-1] if lines and not killed else "KILLED")
    stats: dict[str, Any] = {}
    if plan.is_file():
        stats = json.loads(plan.read_text(encoding="utf-8")).get("statistics", {})
    solved = d["status"] in ("OPTIMAL", "FEASIBLE") and plan.is_file()
    hl_e = stats.get("highLevelExpanded", d.get("high_level_expanded", "-"))
    hl_g = stats.get("high_level_generated", d.get("high_level_generated", "-"))
    return {
        "solved": solved,
        "status": d["status"],
        "cost": int(float(d["cost"])) if "cost" in d else -1,
        "lb": d.get("lb", "-"),
        "time": float(d["cpu"].rstrip("s")) if "cpu" in d else math.inf,
        "wall": wall,
        "pcpu": pcpu,
        "hl": f"{hl_e}/{hl_g}",
        "ll": stats.get("lowLevelExpanded", d.get("low_level_expanded", "-")),
        "plan_from": stats.get("plan_from", "search"),
    }


def run_anchor_process(
    binary: str, spec: str, tl: float, tmp: Path, extra: list[str] | None = None
) -> dict[str, Any]:
    """One run of a C++ peer (CBSH2-RTC ``cbs`` or EECBS ``eecbs``; same command line and
    statistics file) on ``spec``, writing its paths as a user would."""
    from hierplan_opt.experiments.data import movingai_files

    mp, scen = movingai_files(spec.partition(":")[0])
    stats, paths = tmp / "stats.csv", tmp / "paths.txt"
    stats.unlink(missing_ok=True)
    cmd = [binary, "-m", str(mp), "-a", str(scen), "-k", spec.partition(":")[2]]
    cmd += ["-t", f"{tl:g}", "-o", str(stats), f"--outputPaths={paths}", "-s", "0"]
    _, wall, pcpu, killed = _timed(cmd + (extra or []), 2 * tl + 60)
    if killed or not stats.is_file():
        if not killed:
            raise InputError(f"--anchor {binary}: wrote no statistics for {spec}")
        return {"solved": False, "time": math.inf, "cost": -1, "hl": "-", "ll": "-",
                "wall": wall, "pcpu": pcpu, "lb": "-"}  # fmt: skip
    with stats.open(newline="") as fh:
        row = next(csv.DictReader(fh))
    cost = int(float(row["solution cost"]))
    t = float(row["runtime"]) + float(row.get("preprocessing runtime") or 0)
    return {
        "solved": cost >= 0 and t < tl,
        "time": t,
        "cost": cost,
        "lb": row.get("min f value", "-"),
        "hl": f"{int(float(row['#high-level expanded']))}/"
        f"{int(float(row['#high-level generated']))}",
        "ll": int(float(row["#low-level expanded"])),
        "wall": wall,
        "pcpu": pcpu,
    }


def per_process(
    names: list[str],
    solver: str,
    tl: float,
    anchor: str | None,
    *,
    known: dict[str, int | None] | None = None,
    w: float | None = None,
    anchor_args: list[str] | None = None,
) -> list[dict[str, Any]]:
    """The per-process table (see the module doc): ours and the peer, interleaved run by
    run, each run its own process. With ``w``, a solved run must be within ``w`` times
    the peer's lower bound (``min f value``) when known; ``known`` gives the optima.
    Returns one row per instance."""
    head = (
        f"{'instance':34} {'status':9} {'cost':>6} {'C++':>6} {'solve_s':>7} {'C++_s':>7} "
        f"{'ratio':>6} {'proc_s':>6} {'C++_p':>6} {'ratio':>6} {'pcpu_s':>6} {'C++_c':>6} "
        f"{'runs':>5} {'HL ours':>13} {'HL C++':>13}"
    )
    print(head)
    print("-" * len(head))
    rows: list[dict[str, Any]] = []
    unsolved: list[str] = []
    with tempfile.TemporaryDirectory(prefix="hierplan-bench-") as tmp_dir:
        tmp = Path(tmp_dir)
        for name in names:
            ours: list[dict[str, Any]] = []
            cpps: list[dict[str, Any]] = []

            def more(runs: list[dict[str, Any]]) -> bool:
                if not runs:
                    return True
                return (
                    runs[-1]["solved"]
                    and len(runs) < PROCESS_MAX
                    and sum(r["wall"] for r in runs) < PROCESS_BUDGET
                )

            while more(ours) or (anchor is not None and more(cpps)):
                if more(ours):
                    ours.append(run_ours_process(name, solver, tl, tmp, w))
                if anchor is not None and more(cpps):
                    cpps.append(run_anchor_process(anchor, name, tl, tmp, anchor_args))
            o = {**ours[-1]}
            for key in ("time", "wall", "pcpu"):
                o[key] = statistics.median(r[key] for r in ours)
            o["solved"] = all(r["solved"] for r in ours)
            c: dict[str, Any] = {"solved": False, "time": math.inf, "wall": math.nan,
                                 "pcpu": math.nan, "cost": -1, "hl": "-"}  # fmt: skip
            if cpps:
                c = {**cpps[-1], "solved": all(r["solved"] for r in cpps)}
                for key in ("time", "wall", "pcpu"):
                    c[key] = statistics.median(r[key] for r in cpps)
            wrong = False
            opt = (known or {}).get(name)
            if o["solved"] and opt is not None and w is None and o["cost"] != opt:
                wrong = True
            if o["solved"] and w is not None:
                # within the bound: at most w times a proven lower bound (ours or the C++'s)
                lbs = [_num(o["lb"])] + ([_num(c["lb"])] if c["solved"] else [])
                o["over_bound"] = o["cost"] > w * max(lbs) + 1e-9
            status = "WRONG" if wrong else o["status"][:9]
            if o.get("over_bound"):
                status = "OVER_W"
            both = o["solved"] and c["solved"]
            ratio = o["time"] / max(c["time"], 1e-4) if both else math.nan
            pratio = o["wall"] / c["wall"] if both else math.nan
            cratio = o["pcpu"] / max(c["pcpu"], 1e-3) if both else math.nan
            rows.append({"name": name, "ours": o, "cpp": c, "wrong": wrong, "both": both,
                         "ratio": ratio, "pratio": pratio, "cratio": cratio})  # fmt: skip
            if not both and (anchor is not None or not o["solved"]):
                unsolved.append(
                    f"{name} {_side(o['solved'], o['cost'], o.get('lb'))}"
                    f"/{_side(c['solved'], c['cost'], c.get('lb'))}"
                )
            print(
                f"{name:34} {status:9} {o['cost'] if o['solved'] else '-':>6} "
                f"{c['cost'] if c['solved'] else '-':>6} "
                f"{secs(o['time'] if o['solved'] else math.inf):>7} "
                f"{secs(c['time'] if c['solved'] else math.inf):>7} {_x(ratio):>6} "
                f"{o['wall']:>6.2f} {c['wall']:>6.2f} {_x(pratio):>6} {o['pcpu']:>6.2f} "
                f"{c['pcpu']:>6.2f} {len(ours)}/{len(cpps):<3} {o['hl']:>13} {c['hl']:>13}",
                flush=True,
            )
    both = [r for r in rows if r["both"]]
    print(
        f"solved ours {sum(r['ours']['solved'] and not r['ours'].get('over_bound') for r in rows)}"
        f"/{len(rows)}, C++ {sum(r['cpp']['solved'] for r in rows)}/{len(rows)}"
        f"{f' (w={w:g}, within the bound)' if w is not None else ''}; over the {len(both)} both "
        f"solve, geometric means ours/C++: solve {geomean([r['ratio'] for r in both]):.2f}x "
        f"(worst {max((r['ratio'] for r in both), default=math.nan):.1f}x), process wall "
        f"{geomean([r['pratio'] for r in both]):.2f}x, process CPU "
        f"{geomean([r['cratio'] for r in both]):.2f}x; optima differing from the known ones: "
        f"{sum(r['wrong'] for r in rows)}; every run its own process (solve_s: CPU s of the "
        f"solve, proc_s: process wall s, pcpu_s: process user+system CPU s), medians of the "
        f"runs (ours/C++), time limit {tl:g} s"
    )
    line = bounds_line(unsolved)
    if line:
        print(line)
    return rows


def _num(text: Any) -> float:
    """A lower bound as printed (``-`` or empty: 0, i.e. none).

    Example
    -------
    >>> _num("869"), _num("-")
    (869.0, 0.0)
    """
    try:
        return float(text)
    except (TypeError, ValueError):
        return 0.0


def _side(solved: bool, cost: Any, lb: Any) -> str:
    """A side's entry on the bounds line: its cost if it solved the instance, else the
    lower bound it proved (``-`` for none).

    Example
    -------
    >>> _side(True, 74, "70"), _side(False, -1, "1443.0"), _side(False, -1, None)
    ('74', '1443', '-')
    """
    if solved:
        return str(cost)
    x = _num(lb)
    return f"{x:g}" if x else "-"


def bounds_line(entries: list[str]) -> str | None:
    """The closing line over the instances a side left unsolved (None if there are none).

    Example
    -------
    >>> print(bounds_line(["den312d-even-1:100 6209/6205"]))
    unsolved by a side (bound proved; cost if solved), ours/C++: den312d-even-1:100 6209/6205
    """
    if not entries:
        return None
    return "unsolved by a side (bound proved; cost if solved), ours/C++: " + ", ".join(entries)


def _x(ratio: float) -> str:
    return "-" if math.isnan(ratio) else f"{ratio:.1f}"


def _again(times: list[float]) -> bool:
    """Whether a side with these run times (CPU s) runs the instance once more.

    Example
    -------
    >>> _again([0.01, 0.02]), _again([0.6]), _again([0.001] * REPEAT_MAX)
    (True, False, False)
    """
    return len(times) < REPEAT_MAX and sum(times) < REPEAT_BUDGET


def secs(x: float) -> str:
    """A CPU time for the table: four decimals below 0.1 s (sub-millisecond runs).

    Example
    -------
    >>> secs(0.00071), secs(0.0412), secs(1.5), secs(math.inf)
    ('0.0007', '0.0412', '1.500', 'inf')
    """
    return f"{x:.4f}" if x < 0.1 else f"{x:.3f}"


def geomean(xs: list[float]) -> float:
    """Geometric mean (nan for an empty list).

    Example
    -------
    >>> round(geomean([1.0, 4.0]), 6)
    2.0
    """
    return math.exp(sum(math.log(x) for x in xs) / len(xs)) if xs else math.nan


def reference(
    specs: list[str] | None,
    quick: bool,
    tl_given: float | None,
    anchor: str | None,
    options: dict[str, Any] | None = None,
) -> int:
    """The reference table (see the module doc); 1 if any optimum differs from the known one."""

    ref = reference_table()
    names = specs or (REFERENCE_QUICK if quick else sorted(ref))
    for name in names:
        if name not in ref:
            raise InputError(f"--instance {name}: not a reference instance (SCEN:K of {len(ref)})")
    tl = time_limit(tl_given, False)
    # Warm-up: the first solve of a process pays the solver's lazy imports.
    solve(scenario("empty-8-8-even-1:2")[1], "cbs")
    head = (
        f"{'instance':36} {'opt':>6} {'status':9} {'ours_s':>7} {'C++_s':>7} {'ratio':>6} "
        f"{'runs':>5} {'HL ours':>11} {'HL C++':>11} {'LL ours':>9} {'LL C++':>9} "
        f"{'rect':>11}"
    )
    print(head)
    print("-" * len(head))
    ratios: list[tuple[float, str]] = []
    unsolved: list[str] = []
    ours_solved = cpp_solved = wrong = 0
    for name in names:
        known = ref[name]["optimal_soc"]
        ours: list[float] = []
        cpps: list[dict[str, Any]] = []
        r = inst = None
        while True:  # interleaved; a side stops once unsolved (the limit is then its time)
            more_ours = r is None or (r.plan is not None and _again(ours))
            more_cpp = anchor is not None and (
                not cpps or (cpps[-1]["solved"] and _again([c["time"] for c in cpps]))
            )
            if not (more_ours or more_cpp):
                break
            if more_ours:
                _, inst = scenario(name)  # fresh: no distance table cached from a run before
                c0 = time.process_time()
                r = registry.run("cbs", inst, time_limit=tl, **(options or {}))
                ours.append(time.process_time() - c0)
            if more_cpp and anchor is not None:
                cpps.append(run_anchor(anchor, name, tl))
        assert r is not None and inst is not None
        cpu = statistics.median(ours)
        r = registry.checked(inst, r)  # the plan validated (untimed)
        ok = r.plan is not None
        bad = r.status is Status.ERROR
        if bad or (ok and known is not None and r.cost != known):
            wrong += 1
            status = "WRONG"
        else:
            status = "solved" if ok else r.status.value[:9]
        ours_solved += ok
        if anchor:
            cpp = {**cpps[-1], "time": statistics.median(c["time"] for c in cpps)}
            cpp["solved"] = all(c["solved"] for c in cpps)
        else:
            t = ref[name]["cbsh2_rtc_runtime_s"]
            cpp = {"solved": t < tl, "time": t, "hl": "-", "ll": "-", "rect": "-",
                   "cost": known, "lb": ref[name]["lower_bound"]}  # fmt: skip
        cpp_solved += cpp["solved"]
        if not (ok and cpp["solved"]):
            unsolved.append(
                f"{name} {_side(ok, r.cost, r.lower_bound)}"
                f"/{_side(cpp['solved'], cpp.get('cost'), cpp.get('lb'))}"
            )
        ratio = "-"
        if ok and cpp["solved"]:
            x = cpu / max(cpp["time"], 1e-4)
            ratios.append((x, name))
            ratio = f"{x:.1f}"
        st = r.stats
        hl = f"{st.get('high_level_expanded', 0)}/{st.get('high_level_generated', 0)}"
        runs = f"{len(ours)}/{len(cpps) if anchor else '-'}"
        # Rectangle splits, ours / the C++'s rectangle conflicts (its GR by default).
        rect = f"{st.get('rectangle_splits', 0)}/{cpp.get('rect', '-')}"
        print(
            f"{name:36} {known if known is not None else '-':>6} {status:9} "
            f"{secs(cpu):>7} {secs(cpp['time'] if cpp['solved'] else math.inf):>7} {ratio:>6} "
            f"{runs:>5} {hl:>11} {cpp['hl']:>11} {st.get('low_level_expanded', 0):>9} "
            f"{cpp['ll']:>9} {rect:>11}",
            flush=True,
        )
    worst = max(ratios, default=(math.nan, "-"))
    print(
        f"solved ours {ours_solved}/{len(names)}, CBSH2-RTC {cpp_solved}/{len(names)}"
        f"{' (recorded)' if not anchor else ''}; ours/C++ time over the {len(ratios)} both solve: "
        f"geometric mean {geomean([x for x, _ in ratios]):.2f}x, worst {worst[0]:.1f}x "
        f"({worst[1]}); optima differing from the known ones: {wrong}; times: CPU s, median "
        f"of the runs (each side repeats while under {REPEAT_BUDGET:g} s in all, "
        f"at most {REPEAT_MAX})"
    )
    line = bounds_line(unsolved)
    if line:
        print(line)
    return 1 if wrong else 0


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
