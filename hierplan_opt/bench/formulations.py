"""``hierplan bench formulations``: model sizes and time to optimum, MIP vs CP-SAT vs CBS.

Two tables:

1. model size (variables, constraints) of the time-expanded network with and without
   reachability pruning, at the makespan lower bound and for the sum of costs at slack
   ``Δ = 2``;
2. time to a proven optimum against the number of agents (the first K agents of the
   scenario) for each solver side by side; a solver drops out of larger K once it fails
   to prove optimality within the time limit ("how far it goes").

Target: both formulations prove optimality for 10 agents on random-32-32-20-random-1
within 60 s.
"""

from __future__ import annotations

import contextlib
import time
from collections.abc import Iterable, Iterator

from hierplan_opt import registry
from hierplan_opt.api import solve
from hierplan_opt.bench import BenchParser, time_limit
from hierplan_opt.core.graph import Graph
from hierplan_opt.core.instance import Instance
from hierplan_opt.core.result import Status

MAPS = {
    "random-32-32-20": "random-32-32-20-random-1.scen",
    "room-32-32-4": "room-32-32-4-even-1.scen",
}


def _load(map_name: str, k: int):
    from hierplan_opt.experiments.data import instances_dir  # shipped with the package
    from hierplan_opt.io.movingai import load_map, load_scen

    root = instances_dir() / "movingai"
    return load_scen(root / MAPS[map_name], load_map(root / f"{map_name}.map"), agents=k)


def size_table(maps: list[str], agents: list[int]) -> list[tuple]:
    """Rows: map, K, model, horizon, variables/constraints pruned and unpruned."""
    from hierplan_opt.formulations.time_expanded import (
        TimeExpandedNetwork,
        commodity_min_deadline,
    )

    rows = []
    for m in maps:
        for k in agents:
            inst = _load(m, k)
            lb = inst.makespan_lower_bound()
            dl = [d + 2 for d in commodity_min_deadline(inst)]
            for label, objective, deadlines in (
                ("makespan T=LB", "makespan", None),
                ("soc slack 2", "soc", dl),
            ):
                p = TimeExpandedNetwork.build(inst, lb, deadlines=deadlines).stats(objective)
                f = TimeExpandedNetwork.build(inst, lb, deadlines=deadlines, prune=False).stats(
                    objective
                )
                rows.append(
                    (
                        m,
                        k,
                        label,
                        p["horizon"],
                        p["variables"],
                        p["constraints"],
                        f["variables"],
                        f["constraints"],
                        f["variables"] / max(1, p["variables"]),
                    )
                )
    return rows


def time_table(
    maps: list[str], agents: list[int], solvers: list[str], objective: str, time_limit: float
) -> Iterator[tuple]:
    """Rows: map, K, solver, status, cost, lower bound, seconds (or why it was skipped)."""

    # Warm up: the first call of a solver pays for importing Pyomo / OR-Tools.
    tiny = Instance.mapf(Graph.grid(3, 2), [(0, 0)], [(2, 1)])
    for s in solvers:
        with contextlib.suppress(ImportError):
            solve(tiny, s, cost=objective, time_limit=time_limit)
    for m in maps:
        dropped: set[str] = set()
        for k in agents:
            inst = _load(m, k)
            for s in solvers:
                if s in dropped:
                    yield (m, k, s, "skipped", "", "", "")
                    continue
                try:
                    registry.get(s).load()
                except ImportError:
                    yield (m, k, s, "n/a", "", "", "")
                    dropped.add(s)
                    continue
                t0 = time.perf_counter()
                res = solve(inst, s, cost=objective, time_limit=time_limit)
                dt = time.perf_counter() - t0
                if res.status != Status.OPTIMAL:
                    dropped.add(s)
                yield (
                    m,
                    k,
                    s,
                    res.status.value,
                    "" if res.cost is None else int(res.cost),
                    "" if res.lower_bound is None else int(res.lower_bound),
                    f"{dt:.1f}",
                )


def _print(header: tuple, rows: Iterable[tuple], widths: list[int] | None = None) -> None:
    """Print a table; with fixed ``widths`` rows are printed as they come."""
    if widths is None:
        rows = list(rows)
        cells = [tuple(f"{c:.1f}" if isinstance(c, float) else str(c) for c in r) for r in rows]
        widths = [max(len(str(h)), *(len(r[i]) for r in cells)) for i, h in enumerate(header)]
        rows = cells
    else:
        rows = (tuple(str(c) for c in r) for r in rows)
    print("  ".join(str(h).ljust(w) for h, w in zip(header, widths, strict=True)), flush=True)
    for r in rows:
        print("  ".join(c.ljust(w) for c, w in zip(r, widths, strict=True)), flush=True)


def main(argv: list[str] | None = None) -> int:
    """Print the model-size and time-to-optimum tables.

    Example
    -------
    >>> main(["--sizes-only", "--maps", "room-32-32-4", "--agents", "2"])  # doctest: +ELLIPSIS
    map ...
    0
    """
    p = BenchParser(
        "formulations",
        (__doc__ or "").split("\n\n")[0],
        instance=f"map ({', '.join(sorted(MAPS))}; default both)",
        instance_aliases=("--maps",),
        quick="small preset: K = 2 5, 20 s limit",
        time_limit="seconds per solve (default 60, --quick 20)",
    )
    p.add_argument(
        "--agents", nargs="+", type=int, help="agent counts (default 2 4 6 8 10 12 15 20)"
    )
    p.add_argument("--solvers", nargs="+", default=["mip", "cpsat", "cbs"])
    p.add_argument("--objective", choices=("soc", "makespan"), default="soc")
    p.add_argument("--sizes-only", action="store_true", help="only the model-size table")
    args = p.parse_args(argv)
    maps = args.instance or sorted(MAPS)
    for m in maps:
        if m not in MAPS:
            p.error(f"unknown map {m!r} (use {', '.join(sorted(MAPS))})")
    args.maps = maps
    agents = args.agents or ([2, 5] if args.quick else [2, 4, 6, 8, 10, 12, 15, 20])
    limit = time_limit(args.time_limit, args.quick, small=20.0)

    _print(
        ("map", "K", "model", "T", "vars", "cons", "vars(no prune)", "cons(no prune)", "ratio"),
        size_table(args.maps, agents[-2:] if not args.sizes_only else agents),
    )
    if args.sizes_only:
        return 0
    print()
    print(f"time to optimum ({args.objective}), limit {limit:g} s per solve")
    _print(
        ("map", "K", "solver", "status", "cost", "LB", "seconds"),
        time_table(args.maps, agents, args.solvers, args.objective, limit),
        widths=[15, 3, 6, 10, 6, 6, 7],
    )
    return 0
