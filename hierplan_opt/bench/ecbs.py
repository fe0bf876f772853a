"""``hierplan bench ecbs``: bounded-suboptimal ECBS / EECBS on MovingAI instances.

Prints one row per (instance, agents, solver, w): status, wall time, sum of costs,
lower bound, cost / lower bound (the proven suboptimality), high-level nodes expanded
and generated, low-level expansions.

Default: the targets, ``random-32-32-20-random-1`` with 100 agents and
``warehouse-10-20-10-2-1-even-1`` with 200, ECBS(1.2) and EECBS(1.2), 60 s each.

``hierplan bench ecbs --reference --per-process [--anchor PATH] [--solvers eecbs]
[--w 1.2]``: the bounded set (:data:`BOUNDED`, 11 instances) with every run its own
``hierplan solve --solver eecbs --w 1.2`` process, interleaved run by run with the EECBS
binary (``eecbs ... --suboptimality=1.2``), as ``hierplan bench cbs --reference
--per-process`` does with CBSH2-RTC (the same columns). A plan counts as solved only
within the bound: its cost at most ``w`` times a proven lower bound (ours or EECBS's);
a LaCAM fallback plan over it is counted ``OVER_W``.

Example
-------
>>> main(["--instance", "empty-8-8-even-1:4", "--solvers", "ecbs"])  # doctest: +ELLIPSIS
instance ...
empty-8-8-even-1 ...
0
"""

from __future__ import annotations

from hierplan_opt.api import solve
from hierplan_opt.bench import SEARCH_HEAD, BenchParser, scenario, search_columns, time_limit
from hierplan_opt.core.errors import InputError

DEFAULT = ["random-32-32-20-random-1:100", "warehouse-10-20-10-2-1-even-1:200"]
QUICK = ["random-32-32-20-random-1:50", "warehouse-10-20-10-2-1-even-1:50"]
#: ``--reference``: the bounded set of issue 35, beside EECBS at w = 1.2.
BOUNDED = [
    "random-32-32-20-random-1:100",
    "random-32-32-20-random-1:150",
    "random-32-32-20-random-1:200",
    "warehouse-10-20-10-2-1-even-1:100",
    "warehouse-10-20-10-2-1-even-1:200",
    "warehouse-10-20-10-2-1-even-1:300",
    "warehouse-10-20-10-2-1-even-1:400",
    "den312d-even-1:100",
    "den312d-even-1:200",
    "room-32-32-4-even-1:50",
    "room-32-32-4-even-1:80",
]


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
    ap.add_argument(
        "--reference", action="store_true", help="the bounded set (BOUNDED) beside EECBS"
    )
    ap.add_argument("--anchor", metavar="PATH", help="an EECBS binary to run beside ours")
    ap.add_argument(
        "--per-process",
        action="store_true",
        help="with --reference: every run its own `hierplan solve` process",
    )
    args = ap.parse_args(argv)
    specs = args.instance or (QUICK if args.quick else DEFAULT)
    limit = time_limit(args.time_limit, args.quick)
    solvers = [s for s in args.solvers.split(",") if s]
    try:
        ws = [float(x) for x in args.w.split(",") if x]
    except ValueError:
        raise InputError(f"--w expects comma-separated numbers, got {args.w!r}") from None
    if args.reference or args.per_process or args.anchor:
        if not args.per_process:
            raise InputError("--reference / --anchor run per process: add --per-process")
        from hierplan_opt.bench.cbs import per_process

        names = args.instance or BOUNDED
        solver = "eecbs" if args.solvers == "ecbs,eecbs" else args.solvers
        if len(ws) != 1 or "," in solver:
            raise InputError("--per-process runs one solver at one w")
        tl = time_limit(args.time_limit, False)
        extra = [f"--suboptimality={ws[0]:g}"]
        if solver == "ecbs":
            extra += ["--highLevelSolver=A*eps"]
        rows = per_process(names, solver, tl, args.anchor, w=ws[0], anchor_args=extra)
        return 0 if rows else 1

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
                r = solve(inst, solver, time_limit=limit, w=w, lacam="off")
                row = f"{name:32} {inst.num_agents:>6} {solver:6} {w:>4g} {search_columns(r)}"
                print(row, flush=True)
    return 0


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
