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
(interleaved), with its high-level and low-level node counts. The summary gives the
solved counts and the geometric mean of our time over the C++'s on the instances both
solve. Times compared are CPU seconds, as CBSH2-RTC measures them (``clock()``), so a
loaded machine does not skew the ratio: ours is the solving process's CPU time for
``registry.run`` (feasibility test, distances and search; the plan is validated
afterwards, untimed), the C++'s is its ``runtime`` plus ``preprocessing runtime`` (its
heuristic tables) when run here. Our time limit is wall-clock, the C++'s is on CPU time.
Short instances are timed repeatedly (single CPU times of a few milliseconds are noise):
each side runs again, interleaved, until it has spent ``REPEAT_BUDGET`` seconds of CPU or
made ``REPEAT_MAX`` runs, each of ours on a freshly loaded instance (nothing cached); the
table gives the median of each side's runs (column ``runs``: ours/C++); an instance
that takes a side ``REPEAT_BUDGET`` or more is run once by it.
"""

from __future__ import annotations

import csv
import json
import math
import statistics
import subprocess
import tempfile
import time
from pathlib import Path
from typing import Any

from hierplan_opt.bench import SEARCH_HEAD, BenchParser, scenario, search_columns, time_limit
from hierplan_opt.core.errors import InputError
from hierplan_opt.core.options import parse_pairs

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
    args = p.parse_args(argv)
    if args.reference or args.anchor:
        return reference(args.instance, args.quick, args.time_limit, args.anchor)

    import hierplan_opt
    from hierplan_opt import registry

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
            ("-disjoint", {"disjoint_splitting": False}),
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
            r = hierplan_opt.solve(inst, "cbs", time_limit=tl, objective=args.objective, **opts)
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
            return {"solved": False, "time": math.inf, "cost": -1, "hl": "-", "ll": "-"}
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
    }


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
    specs: list[str] | None, quick: bool, tl_given: float | None, anchor: str | None
) -> int:
    """The reference table (see the module doc); 1 if any optimum differs from the known one."""
    import hierplan_opt
    from hierplan_opt import registry
    from hierplan_opt.core.validate import validate

    ref = reference_table()
    names = specs or (REFERENCE_QUICK if quick else sorted(ref))
    for name in names:
        if name not in ref:
            raise InputError(f"--instance {name}: not a reference instance (SCEN:K of {len(ref)})")
    tl = time_limit(tl_given, False)
    # Warm-up: the first solve of a process pays the solver's lazy imports.
    hierplan_opt.solve(scenario("empty-8-8-even-1:2")[1], "cbs")
    head = (
        f"{'instance':36} {'opt':>6} {'status':9} {'ours_s':>7} {'C++_s':>7} {'ratio':>6} "
        f"{'runs':>5} {'HL ours':>11} {'HL C++':>11} {'LL ours':>9} {'LL C++':>9}"
    )
    print(head)
    print("-" * len(head))
    ratios: list[tuple[float, str]] = []
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
                r = registry.run("cbs", inst, time_limit=tl)
                ours.append(time.process_time() - c0)
            if more_cpp and anchor is not None:
                cpps.append(run_anchor(anchor, name, tl))
        assert r is not None and inst is not None
        cpu = statistics.median(ours)
        ok = r.plan is not None
        bad = r.plan is not None and bool(validate(inst, r.plan))
        if ok and (bad or (known is not None and r.cost != known)):
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
            cpp = {"solved": t < tl, "time": t, "hl": "-", "ll": "-"}
        cpp_solved += cpp["solved"]
        ratio = "-"
        if ok and cpp["solved"]:
            x = cpu / max(cpp["time"], 1e-4)
            ratios.append((x, name))
            ratio = f"{x:.1f}"
        st = r.stats
        hl = f"{st.get('high_level_expanded', 0)}/{st.get('high_level_generated', 0)}"
        runs = f"{len(ours)}/{len(cpps) if anchor else '-'}"
        print(
            f"{name:36} {known if known is not None else '-':>6} {status:9} "
            f"{secs(cpu):>7} {secs(cpp['time'] if cpp['solved'] else math.inf):>7} {ratio:>6} "
            f"{runs:>5} {hl:>11} {cpp['hl']:>11} {st.get('low_level_expanded', 0):>9} "
            f"{cpp['ll']:>9}",
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
    return 1 if wrong else 0


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
