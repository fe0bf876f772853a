"""``hierplan bench teams``: CBM and max-flow on warehouse-like TAPF instances.

For every instance the table shows CBM's optimal TAPF makespan (time, lower bound,
high-level nodes) next to the makespan of a *fixed* assignment: the Hungarian /
bottleneck assignment by distance solved as MAPF, and (``--fixed``) the instance's
own random goals solved as MAPF. Both fixed-assignment columns use CBM on the MAPF
instance (one team per agent), which is makespan-optimal for that assignment, or
whatever solver ``--mapf-solver`` names.

Instances are generated: a warehouse grid with blocks of shelves separated by
one-cell passageways (``--shelf-rows``, ``--shelf-cols``), robots starting in the
left and right aisles and targets on cells next to shelves (pick-up locations).
``--map`` uses a MovingAI map instead (random free cells).

Example
-------
>>> main(["--quick", "--teams", "2", "--size", "2", "--mapf-solver", "cbm"])  # doctest: +ELLIPSIS
teams benchmark: ...
0
"""

from __future__ import annotations

import argparse
import logging
import time

import numpy as np

from hierplan_opt.api import solve
from hierplan_opt.bench import BenchParser, time_limit
from hierplan_opt.core.instance import Instance
from hierplan_opt.core.validate import validate
from hierplan_opt.experiments.generators import warehouse_grid, warehouse_tapf


def map_tapf(path: str, teams: int, size: int, seed: int) -> Instance:
    """Random distinct starts and targets on a MovingAI map, grouped into teams."""
    from hierplan_opt.io.movingai import load_map

    g = load_map(path)
    rng = np.random.default_rng(seed)
    free = np.flatnonzero(g.passable)
    k = teams * size
    cells = [g.location(int(v)) for v in rng.choice(free, 2 * k, replace=False)]
    spec = [
        (cells[i * size : (i + 1) * size], cells[k + i * size : k + (i + 1) * size])
        for i in range(teams)
    ]
    return Instance.tapf(g, spec, name=f"{path.rsplit('/', 1)[-1]}-{teams}x{size}-s{seed}")


def _run(
    inst: Instance, solver: str, limit: float, **options
) -> tuple[str, object, object, float, dict]:

    t0 = time.perf_counter()
    r = solve(inst, solver, time_limit=limit, cost="makespan", **options)
    dt = time.perf_counter() - t0
    if r.plan is not None and validate(inst, r.plan):
        return "INVALID", None, None, dt, r.stats
    return str(r.status), r.cost, r.lower_bound, dt, r.stats


def main(argv: list[str] | None = None) -> int:
    """Run the benchmark and print one table row per instance."""
    p = BenchParser(
        "teams",
        (__doc__ or "").split("\n\n")[0],
        instance="a MovingAI .map instead of the generated warehouse (random free cells)",
        instance_aliases=("--map",),
        quick="small preset (under a minute)",
        time_limit="seconds per solve (default 60, --quick 20)",
    )
    p.add_argument("--teams", help="comma-separated numbers of teams (default 5,10,20; quick 2,4)")
    p.add_argument("--size", type=int, help="robots per team (default 10, quick 3)")
    p.add_argument("--seeds", type=int, help="instances per setting (default 1)")
    p.add_argument("--shelf-rows", type=int, help="shelf block rows (default 10, quick 2)")
    p.add_argument("--shelf-cols", type=int, help="shelf block columns (default 14, quick 3)")
    p.add_argument("--shelf-len", type=int, help="cells per shelf block (default 4, quick 5)")
    p.add_argument(
        "--starts",
        choices=["sides", "random"],
        help="where robots start (default random, quick sides)",
    )
    p.add_argument("--tie-break", default="auto", help="CBM tie_break option (default auto)")
    p.add_argument(
        "--mapf-solver", default="cbs", help="makespan MAPF solver for fixed assignments (cbs)"
    )
    p.add_argument("--fixed", action="store_true", help="also solve the random fixed goals")
    p.add_argument(
        "--flow", action="store_true", help="also run max-flow with all robots as one team"
    )
    args = p.parse_args(argv)
    q = args.quick
    team_counts = [int(x) for x in (args.teams or ("2,4" if q else "5,10,20")).split(",")]
    size = args.size or (3 if q else 10)
    seeds = args.seeds or 1
    rows = args.shelf_rows or (2 if q else 10)
    cols = args.shelf_cols or (3 if q else 14)
    slen = args.shelf_len or (5 if q else 4)
    starts_at = args.starts or ("sides" if q else "random")
    limit = time_limit(args.time_limit, q, small=20.0)
    if args.instance is not None and len(args.instance) != 1:
        p.error("--instance takes one map")
    map_path = args.instance[0] if args.instance else None
    logging.getLogger("hierplan_opt").setLevel(logging.WARNING)

    header = (
        f"{'instance':<28} {'cells':>6} {'K':>4} | {'cbm':>11} {'mk':>4} {'lb':>4} "
        f"{'time':>7} {'nodes':>5} | {'hungarian':>11} {'mk':>4} {'time':>7}"
    )
    if args.fixed:
        header += f" | {'fixed':>11} {'mk':>4} {'time':>7}"
    if args.flow:
        header += f" | {'flow(1 team)':>12} {'mk':>4} {'time':>7}"
    print(
        f"teams benchmark: teams {team_counts} x {size} robots, time limit {limit:g} s, "
        f"fixed assignments solved by {args.mapf_solver} (makespan)"
    )
    print(header)
    print("-" * len(header))
    solved = total = 0
    for teams in team_counts:
        for seed in range(seeds):
            if map_path:
                inst = map_tapf(map_path, teams, size, seed)
            else:
                grid = warehouse_grid(rows, cols, slen)
                inst = warehouse_tapf(grid, teams, size, seed, starts_at)
            total += 1
            print(_row(inst, args, limit), flush=True)
            solved += _LAST["cbm"] == "OPTIMAL"
    print(f"cbm solved {solved}/{total} optimally within {limit:g} s")
    return 0


_LAST: dict[str, str] = {}


def _row(inst: Instance, args: argparse.Namespace, limit: float) -> str:
    st, mk, lb, dt, stats = _run(inst, "cbm", limit, tie_break=args.tie_break)
    _LAST["cbm"] = st
    line = (
        f"{inst.name:<28} {inst.graph.num_vertices:>6} {inst.num_agents:>4} | {st:>11} "
        f"{_s(mk):>4} {_s(lb):>4} {dt:>7.2f} {stats.get('high_level_expanded', 0):>5} | "
    )
    hst, hmk, _, hdt, _ = _run(inst, "hungarian", limit, mapf_solver=args.mapf_solver)
    line += f"{hst:>11} {_s(hmk):>4} {hdt:>7.2f}"
    if args.fixed:
        fixed = inst.with_goals([t for team in inst.teams for t in team.targets])
        fst, fmk, _, fdt, _ = _run(fixed, args.mapf_solver, limit)
        line += f" | {fst:>11} {_s(fmk):>4} {fdt:>7.2f}"
    if args.flow:
        g = inst.graph
        one = Instance.tapf(
            g,
            [
                (
                    [g.location(s) for s in inst.starts],
                    [g.location(t) for team in inst.teams for t in team.targets],
                )
            ],
        )
        ost, omk, _, odt, _ = _run(one, "flow", limit)
        line += f" | {ost:>12} {_s(omk):>4} {odt:>7.2f}"
    return line


def _s(x: object) -> str:
    return "-" if x is None else str(x)


if __name__ == "__main__":
    raise SystemExit(main())
