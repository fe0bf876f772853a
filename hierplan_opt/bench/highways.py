"""``hierplan bench highways``: ECBS/CBS with highways on the Kiva map and the corridor.

One row per (instance set, configuration): how many instances were solved within the
limit, median and largest time, mean cost over the lower bound (the proven
suboptimality; the guarantee is the configuration's bound), mean share of moves on
highway edges (of the user highways for the configurations without highways), median
number of head-on (swap) conflicts the search split on; and the published figures of
Cohen, Uras and Koenig (SoCS 2015; C++, 3.2 GHz, 5-minute limit) beside them.

Sets: ``kiva`` (22 x 54, 150 agents, seeds 0-9), ``corridor`` (5 x 20, 20 agents),
``warehouse`` (the overview's Fig. 2). ``--quick``: seeds 0-1 of kiva, the corridor.

Example
-------
>>> main(["--instance", "warehouse", "--configs", "cbs+user"])  # doctest: +ELLIPSIS
set ...
warehouse cbs+user ...
0
"""

from __future__ import annotations

import logging
import statistics
from dataclasses import replace
from pathlib import Path
from typing import Any

from hierplan_opt.api import solve
from hierplan_opt.bench import BenchParser, time_limit
from hierplan_opt.core.errors import InputError
from hierplan_opt.core.highways import Highways, highway_share
from hierplan_opt.core.instance import Instance
from hierplan_opt.core.result import Result

#: configuration -> (solver, options, published result on the same kind of instance)
CONFIGS: dict[str, tuple[str, dict[str, Any]]] = {
    "ecbs(1.5)": ("ecbs", {"w": 1.5}),
    "ecbs(2.0)": ("ecbs", {"w": 2.0}),
    "ecbs(1.2)+user": ("ecbs", {"w": 1.2, "highways": "instance", "w_hwy": 2.0}),
    "ecbs(1.2)+crisscross": ("ecbs", {"w": 1.2, "highways": "crisscross", "w_hwy": 2.0}),
    "ecbs(1.2)+learned": ("ecbs", {"w": 1.2, "highways": "learned", "w_hwy": 2.0}),
    "ecbs(1.2)+flow": ("ecbs", {"w": 1.2, "highways": "flow", "w_hwy": 2.0}),
    "ecbs(1.2)+user/cost": (
        "ecbs",
        {"w": 1.2, "highways": "instance", "w_hwy": 2.0, "hwy_mode": "cost"},
    ),
    "eecbs(1.2)": ("eecbs", {"w": 1.2}),
    "cbs+user": ("cbs", {"highways": "instance", "w_hwy": 2.0}),
}
PUBLISHED = {
    ("kiva", "ecbs(1.5)"): "4/10 solved, 254-272 s",
    ("kiva", "ecbs(1.2)+user"): "9/10 solved, 84-205 s (ECBS(1.2)+HWY(2.0))",
    ("corridor", "ecbs(2.0)"): "3,073 ms, cost 521",
    ("corridor", "cbs+user"): "266 ms, cost 423 (CBS+HWY(2.0))",
}
SETS = {
    "kiva": [
        "ecbs(1.5)",
        "ecbs(1.2)+user",
        "ecbs(1.2)+crisscross",
        "ecbs(1.2)+learned",
        "ecbs(1.2)+flow",
        "eecbs(1.2)",
    ],
    "corridor": ["ecbs(2.0)", "cbs+user", "ecbs(1.2)+user"],
    "warehouse": ["ecbs(1.5)", "ecbs(1.2)+user", "cbs+user"],
}


def data_dir() -> Path:
    """The shipped highway instances (``instances/highways`` of the repository)."""
    from hierplan_opt.experiments.data import instances_dir

    return instances_dir() / "highways"


def instances(name: str, seeds: list[int]) -> list[tuple[str, Instance]]:
    """The instances of a set, each carrying its user highways (``highways="instance"``).

    Example
    -------
    >>> [(n, i.num_agents, len(i.highways)) for n, i in instances("corridor", [0])]
    [('corridor-5x20', 20, 22)]
    """
    from hierplan_opt.io import load_instance
    from hierplan_opt.io.highways import load_highways

    d = data_dir()
    if name == "warehouse":
        return [("warehouse-fig2", load_instance(d / "warehouse-fig2.yaml"))]
    if name == "corridor":
        inst = load_instance(d / "corridor-5x20.map", scen=d / "corridor-5x20.scen")
        hw = load_highways(d / "corridor-5x20.hwy", inst.graph)
        return [("corridor-5x20", replace(inst, highways=hw, name="corridor-5x20"))]
    if name == "kiva":
        out = []
        hw: Highways | None = None
        for s in seeds:
            inst = load_instance(d / "kiva-22x54.map", scen=d / f"kiva-22x54-seed{s}.scen")
            if hw is None:
                hw = load_highways(d / "kiva-22x54.map.highway", inst.graph)
            out.append((f"kiva-seed{s}", replace(inst, highways=hw, name=f"kiva-seed{s}")))
        return out
    raise InputError(f"unknown instance set {name!r} (use {', '.join(SETS)})")


HEAD = (
    f"{'set':9} {'config':21} {'bound':>5} {'solved':>6} {'t_med':>6} {'t_max':>6} "
    f"{'cost/LB':>7} {'hwy%':>5} {'headon':>6}  published (SoCS 2015)"
)


def row(set_name: str, config: str, results: list[tuple[Instance, Result]], limit: float) -> str:
    """One table row: the results of one configuration on one set."""
    solved = [(i, r) for i, r in results if r.plan is not None and r.runtime <= limit]
    times = [r.runtime if r.plan is not None else limit for _, r in results]
    ratios = [r.cost / r.lower_bound for _, r in solved if r.cost and r.lower_bound]
    shares = [
        r.stats.get("highway_share", highway_share(r.plan, i.highways or ()))
        for i, r in solved
        if r.plan is not None
    ]
    heads = [r.stats.get("head_on_conflicts", 0) for _, r in results]
    solver, opts = CONFIGS[config]
    w = float(opts.get("w", 1.0))
    bound = w * float(opts.get("w_hwy", 1.0)) if "highways" in opts else w
    if solver == "cbs" and "highways" not in opts:
        bound = 1.0

    def mean(xs: list[float]) -> str:
        return f"{statistics.fmean(xs):.3f}" if xs else "-"

    share = f"{100 * statistics.fmean(shares):.0f}" if shares else "-"
    t_med = f"{statistics.median(times):.2f}" if times else "-"
    t_max = f"{max(times):.2f}" if times else "-"
    head_med = f"{statistics.median(heads):g}" if heads else "-"
    pub = PUBLISHED.get((set_name, config), "")
    return (
        f"{set_name:9} {config:21} {bound:>5.2g} {len(solved):>3}/{len(results):<2} "
        f"{t_med:>6} {t_max:>6} {mean(ratios):>7} {share:>5} {head_med:>6}  {pub}"
    )


def main(argv: list[str] | None = None) -> int:
    ap = BenchParser(
        "highways",
        (__doc__ or "").split("\n\n")[0],
        instance="instance set: kiva, corridor, warehouse (default: kiva corridor)",
        quick="kiva seeds 0-1 and the corridor, 60 s limit",
    )
    ap.add_argument("--seeds", default="0-9", help="kiva seeds, e.g. 0-9 or 0,3,5")
    ap.add_argument("--configs", help="comma-separated configurations (default: per set)")
    ap.add_argument("--per-instance", action="store_true", help="also print one row per run")
    args = ap.parse_args(argv)
    limit = time_limit(args.time_limit, args.quick, small=60.0)
    seeds = _seeds("0-1" if args.quick else args.seeds)
    sets = args.instance or ["kiva", "corridor"]
    chosen = [c for c in (args.configs or "").split(",") if c]
    for c in chosen:
        if c not in CONFIGS:
            raise InputError(f"unknown configuration {c!r} (use {', '.join(CONFIGS)})")
    # the searches' progress lines would interleave with the table
    logging.getLogger("hierplan_opt.search").setLevel(logging.WARNING)
    print(HEAD)
    print("-" * len(HEAD))
    for set_name in sets:
        insts = instances(set_name, seeds)
        for config in chosen or SETS[set_name]:
            solver, opts = CONFIGS[config]
            results: list[tuple[Instance, Result]] = []
            for name, inst in insts:
                r = solve(inst, solver, time_limit=limit, **opts)
                results.append((inst, r))
                if args.per_instance:
                    cost = "-" if r.cost is None else f"{r.cost:g}"
                    print(f"  {name:14} {config:21} {r.status.value:10} {r.runtime:7.2f} {cost}")
            print(row(set_name, config, results, limit), flush=True)
    return 0


def _seeds(text: str) -> list[int]:
    try:
        if "-" in text:
            a, b = text.split("-", 1)
            out = list(range(int(a), int(b) + 1))
        else:
            out = [int(x) for x in text.split(",") if x]
    except ValueError:
        out = []
    if not out or any(s < 0 or s > 9 for s in out):
        raise InputError(f"--seeds expects seeds 0-9 like 0-9 or 0,3,5, got {text!r}")
    return out


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
