"""``hierplan bench ecbs``: bounded-suboptimal ECBS / EECBS on MovingAI instances.

Prints one row per (instance, agents, solver, w): status, wall time, sum of costs,
lower bound, cost / lower bound (the proven suboptimality), high-level nodes expanded
and generated, low-level expansions.

Default: the targets, ``random-32-32-20-random-1`` with 100 agents and
``warehouse-10-20-10-2-1-even-1`` with 200, ECBS(1.2) and EECBS(1.2), 60 s each.

Example
-------
>>> main(["--instance", "empty-8-8-even-1:4", "--solvers", "ecbs"])  # doctest: +ELLIPSIS
instance ...
empty-8-8-even-1 ...
0
"""

from __future__ import annotations

import hierplan_opt as hp
from hierplan_opt.bench import SEARCH_HEAD, BenchParser, scenario, search_columns, time_limit
from hierplan_opt.core.errors import InputError

DEFAULT = ["random-32-32-20-random-1:100", "warehouse-10-20-10-2-1-even-1:200"]
QUICK = ["random-32-32-20-random-1:50", "warehouse-10-20-10-2-1-even-1:50"]


def main(argv: list[str] | None = None) -> int:
    ap = BenchParser(
        "ecbs",
        (__doc__ or "").split("\n\n")[0],
        instance=f"scenario with an optional agent count (default: {' '.join(DEFAULT)})",
        instance_aliases=("--instances",),
        quick="50 agents on both maps, 10 s limit (a smoke run)",
    )
    ap.add_argument("--agents", type=int, help="agent count for instances given without :K")
    ap.add_argument("--solvers", default="ecbs,eecbs", help="comma-separated (ecbs,eecbs)")
    ap.add_argument("--w", default="1.2", help="comma-separated suboptimality factors")
    args = ap.parse_args(argv)
    specs = args.instance or (QUICK if args.quick else DEFAULT)
    limit = time_limit(args.time_limit, args.quick)
    solvers = [s for s in args.solvers.split(",") if s]
    try:
        ws = [float(x) for x in args.w.split(",") if x]
    except ValueError:
        raise InputError(f"--w expects comma-separated numbers, got {args.w!r}") from None

    head = f"{'instance':32} {'agents':>6} {'solver':6} {'w':>4} {SEARCH_HEAD}"
    print(head)
    print("-" * len(head))
    for spec in specs:
        try:
            name, inst = scenario(spec, args.agents)
        except InputError as exc:
            print(f"{spec}: skipped ({exc})")
            continue
        for solver in solvers:
            for w in ws:
                # The search alone (no LaCAM fallback plan when the limit runs out).
                r = hp.solve(inst, solver, time_limit=limit, w=w, lacam="off")
                row = f"{name:32} {inst.num_agents:>6} {solver:6} {w:>4g} {search_columns(r)}"
                print(row, flush=True)
    return 0


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
