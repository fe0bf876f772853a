"""``hierplan bench ecbs``: bounded-suboptimal ECBS / EECBS on MovingAI instances.

Prints one row per (instance, agents, solver, w): status, wall time, sum of costs,
lower bound, cost / lower bound (the proven suboptimality), high-level nodes expanded
and generated, low-level expansions.

Default: the targets of issue 3, ``random-32-32-20-random-1`` with 100 agents and
``warehouse-10-20-10-2-1-even-1`` with 200, ECBS(1.2) and EECBS(1.2), 60 s each.

Example
-------
>>> main(["--instances", "empty-8-8-even-1:4", "--solvers", "ecbs"])  # doctest: +ELLIPSIS
instance ...
empty-8-8-even-1 ...
0
"""

from __future__ import annotations

import argparse
import re
from pathlib import Path

import hierplan_opt as hp
from hierplan_opt.core.errors import InputError
from hierplan_opt.io.movingai import load_movingai

DEFAULT = ["random-32-32-20-random-1:100", "warehouse-10-20-10-2-1-even-1:200"]
QUICK = ["random-32-32-20-random-1:50", "warehouse-10-20-10-2-1-even-1:50"]


def _find(name: str) -> Path:
    from hierplan_opt.experiments.data import instances_dir  # shipped with the package

    p = instances_dir() / "movingai" / name
    if p.exists():
        return p
    raise InputError(f"{name} not found in {p.parent} (set $HIERPLAN_INSTANCES)")


def load(spec: str, agents: int | None) -> tuple[str, hp.Instance]:
    """``"SCEN[:K]"`` (scenario file name without ``.scen``) -> (name, instance)."""
    name, _, k = spec.partition(":")
    name = name.removesuffix(".scen")
    count = int(k) if k else agents
    map_name = re.sub(r"-(even|random)-\d+$", "", name) + ".map"
    inst = load_movingai(_find(map_name), _find(name + ".scen"), count)
    return name, inst


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="hierplan bench ecbs", description=__doc__.split("\n\n")[0])
    ap.add_argument(
        "--instances",
        nargs="+",
        metavar="SCEN[:K]",
        help="scenario names (without .scen) with an optional agent count "
        f"(default: {' '.join(DEFAULT)})",
    )
    ap.add_argument("--agents", type=int, help="agent count for instances given without :K")
    ap.add_argument("--solvers", default="ecbs,eecbs", help="comma-separated (ecbs,eecbs)")
    ap.add_argument("--w", default="1.2", help="comma-separated suboptimality factors")
    ap.add_argument("--time-limit", type=float, default=60.0, help="seconds per run")
    ap.add_argument(
        "--quick", action="store_true", help="50 agents on both maps, 10 s limit (a smoke run)"
    )
    args = ap.parse_args(argv)
    specs = args.instances or (QUICK if args.quick else DEFAULT)
    limit = 10.0 if args.quick and args.time_limit == 60.0 else args.time_limit
    solvers = [s for s in args.solvers.split(",") if s]
    ws = [float(x) for x in args.w.split(",") if x]

    head = (
        f"{'instance':32} {'agents':>6} {'solver':6} {'w':>4} {'status':10} {'time_s':>7} "
        f"{'cost':>7} {'LB':>7} {'cost/LB':>7} {'HL_exp':>7} {'HL_gen':>7} {'LL_exp':>9}"
    )
    print(head)  # noqa: T201
    print("-" * len(head))  # noqa: T201
    for spec in specs:
        try:
            name, inst = load(spec, args.agents)
        except InputError as exc:
            print(f"{spec}: skipped ({exc})")  # noqa: T201
            continue
        for solver in solvers:
            for w in ws:
                r = hp.solve(inst, solver, time_limit=limit, w=w)
                st = r.stats
                gap = f"{r.gap:.3f}" if r.gap is not None else "-"
                cost = "-" if r.cost is None else str(r.cost)
                lb = "-" if r.lower_bound is None else str(int(r.lower_bound))
                print(  # noqa: T201
                    f"{name:32} {inst.num_agents:>6} {solver:6} {w:>4g} {r.status.value:10} "
                    f"{r.runtime:>7.2f} {cost:>7} {lb:>7} {gap:>7} "
                    f"{st.get('high_level_expanded', 0):>7} {st.get('high_level_generated', 0):>7} "
                    f"{st.get('low_level_expanded', 0):>9}",
                    flush=True,
                )
    return 0


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
