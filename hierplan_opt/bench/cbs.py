"""``hierplan bench cbs``: optimal CBS on the MovingAI samples (issue 3 targets).

Prints one row per (instance, agents, option set): status, time, cost, lower bound,
cost / lower bound, high-level nodes expanded / generated and low-level expansions.

Example
-------
``hierplan bench cbs --quick`` (a few seconds) or ``hierplan bench cbs`` (the issue's
targets, 60 s each), ``hierplan bench cbs --instance room-32-32-4-even-1:20
--time-limit 30 --option symmetry=false``; ``--rectangle-ablation`` adds a run
without rectangle reasoning per instance (column ``rect``: rectangle splits).
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from hierplan_opt.core.errors import InputError

#: (scenario stem, agents): the optimal-search targets of issue 3.
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


def _paths(stem: str) -> tuple[Path, Path]:
    from hierplan_opt.experiments.data import movingai_files  # shipped with the package

    return movingai_files(stem)


def _parse_option(text: str) -> tuple[str, object]:
    if "=" not in text:
        raise InputError(f"--option expects NAME=VALUE, got {text!r}")
    key, val = text.split("=", 1)
    low = val.lower()
    value: object
    if low in ("true", "yes", "on"):
        value = True
    elif low in ("false", "no", "off"):
        value = False
    elif low.isdigit():
        value = int(low)
    else:
        value = val
    return key.replace("-", "_"), value


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="hierplan bench cbs", description=__doc__.split("\n")[0])
    p.add_argument(
        "--instance",
        action="append",
        metavar="SCEN:K",
        help="scenario stem and agent count, e.g. room-32-32-4-even-1:20 (repeatable)",
    )
    p.add_argument("--time-limit", type=float, default=60.0, help="seconds per run (60)")
    p.add_argument("--quick", action="store_true", help="small preset, a few seconds in all")
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
    from hierplan_opt.io import load_instance

    if args.instance:
        runs = []
        for spec in args.instance:
            stem, _, k = spec.partition(":")
            if not k.isdigit():
                raise InputError(f"--instance expects SCEN:K, got {spec!r}")
            runs.append((stem, int(k)))
    else:
        runs = QUICK if args.quick else TARGETS
    tl = min(args.time_limit, 10.0) if args.quick else args.time_limit
    base = dict(_parse_option(o) for o in args.option)
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

    head = (
        f"{'instance':32} {'k':>4} {'options':10} {'status':10} {'time':>7} {'cost':>6} "
        f"{'LB':>6} {'cost/LB':>7} {'HL exp':>7} {'HL gen':>7} {'LL exp':>9} {'rect':>5}"
    )
    print(head)  # noqa: T201
    print("-" * len(head))  # noqa: T201
    for stem, k in runs:
        mp, scen = _paths(stem)
        inst = load_instance(mp, scen=scen, agents=k)
        for label, opts in variants:
            t0 = time.perf_counter()
            r = hierplan_opt.solve(inst, "cbs", time_limit=tl, objective=args.objective, **opts)
            dt = time.perf_counter() - t0
            st = r.stats
            ratio = f"{r.gap:.3f}" if r.gap is not None else "-"
            cost = "-" if r.cost is None else f"{r.cost:g}"
            lb = "-" if r.lower_bound is None else f"{r.lower_bound:g}"
            print(  # noqa: T201
                f"{stem:32} {k:>4} {label:10} {str(r.status):10} {dt:7.2f} {cost:>6} {lb:>6} "
                f"{ratio:>7} {st.get('high_level_expanded', 0):>7} "
                f"{st.get('high_level_generated', 0):>7} {st.get('low_level_expanded', 0):>9} "
                f"{st.get('rectangle_splits', 0):>5}",
                flush=True,
            )
    return 0


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
