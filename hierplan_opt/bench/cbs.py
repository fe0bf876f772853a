"""``hierplan bench cbs``: optimal CBS on the MovingAI samples.

Prints one row per (instance, agents, option set): status, time, cost, lower bound,
cost / lower bound, high-level nodes expanded / generated and low-level expansions.

Example
-------
``hierplan bench cbs --quick`` (a few seconds) or ``hierplan bench cbs`` (the targets,
60 s each), ``hierplan bench cbs --instance room-32-32-4-even-1:20 --time-limit 30
--option symmetry=false``; ``--rectangle-ablation`` adds a run without rectangle
reasoning per instance (column ``rect``: rectangle splits).
"""

from __future__ import annotations

from hierplan_opt.bench import SEARCH_HEAD, BenchParser, scenario, search_columns, time_limit
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
    args = p.parse_args(argv)

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


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
