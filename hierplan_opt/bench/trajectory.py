"""``hierplan bench trajectory``: trajectory refinement, end to end; profile vs IPOPT vs fatrop.

Cases: the overview paper's formation change (32 quadcopters, 3D,
``instances/paper/formation-usc.yaml``, radius 0.15 m, plan by max-flow) and the first K
agents of ``warehouse-10-20-10-2-1-even-1`` planned by ECBS (robots given ``v_max = 1
m/s``, ``a_max = 1 m/s^2`` and radius 0.3 m on the 1 m cells; MovingAI files carry no
kinematics). Each plan goes through MAPF-POST (earliest schedule, clearance
``r_i + r_j``), then ``refine(..., stretch="auto", solver=S)`` for every refine solver
``S`` (``profile``: no NLP; ``ipopt``: one NLP per robot) and the independent ``verify``
(every pair against its ``r_i + r_j``). "schedule -> verified" is refine + verify, the
quantity the targets are about. The second table re-solves every robot in the final
windows of the first solver's run with each solver and reports per-robot solve times
and iterations (profile: delays) side by side.
"""

from __future__ import annotations

import importlib
import statistics
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from hierplan_opt.api import solve
from hierplan_opt.bench import BenchParser, time_limit
from hierplan_opt.core.instance import Instance, Kinematics
from hierplan_opt.core.validate import validate

#: The issue's targets (seconds, schedule to verified trajectories).
TARGETS = {"formation-usc": 5.0, "warehouse": 10.0}
WAREHOUSE_MAP = "instances/movingai/warehouse-10-20-10-2-1.map"
WAREHOUSE_SCEN = "instances/movingai/warehouse-10-20-10-2-1-even-1.scen"
#: Radius of the warehouse robots (metres, 1 m cells).
WAREHOUSE_RADIUS = 0.3


def _formation():
    from hierplan_opt.experiments.data import shipped_file  # package data
    from hierplan_opt.io import load_instance

    inst = load_instance(shipped_file("instances/paper/formation-usc.yaml"))
    res = solve(inst, "flow", time_limit=60)
    if res.plan is None:
        raise RuntimeError(f"flow found no plan for the formation ({res.status})")
    return "formation-usc", inst, res.plan, "flow"


def _warehouse(k: int, w: float, cache: str | None, time_limit: float):
    from hierplan_opt.bench.post import make_plan
    from hierplan_opt.experiments.data import shipped_file  # package data
    from hierplan_opt.io import load_plan, save_plan
    from hierplan_opt.io.movingai import load_map, load_scen

    g = load_map(shipped_file(WAREHOUSE_MAP))
    inst = load_scen(shipped_file(WAREHOUSE_SCEN), g, agents=k)
    kin = Kinematics("warehouse-robot", v_max=1.0, a_max=1.0, radius=WAREHOUSE_RADIUS)
    inst = Instance(
        inst.graph, tuple(replace(a, kinematics=kin) for a in inst.agents), name=inst.name
    )
    path = Path(cache) / f"warehouse-{k}-ecbs-w{w}.yaml" if cache else None
    if path is not None and path.exists():
        return f"warehouse-{k}", inst, load_plan(path, inst), "cached"
    plan, planner = make_plan(inst, w=w, time_limit=time_limit)
    if path is not None:
        path.parent.mkdir(parents=True, exist_ok=True)
        save_plan(path, inst, plan)
    return f"warehouse-{k}", inst, plan, planner


def _resolve_all(instance, traj, solver: str) -> list[tuple[bool, float, int]]:
    """Every robot once more in its final windows with ``solver``: (ok, seconds, iterations)."""
    R = importlib.import_module("hierplan_opt.trajectory.refine")
    from hierplan_opt.trajectory.model import path_ocp

    win = traj.windows
    net = win.network
    knots = (win.lo > 0) | np.isfinite(win.hi)
    opts = {
        "mode": traj.mode,
        "corridor": traj.corridor,
        "solvers": (solver,),
        "weights": (1.0, 0.01, 1e-3, R.ARRIVAL_WEIGHT),
        "base": 2,
    }
    out = []
    for j, r in enumerate(traj.robots):
        lim = R.Limits(**{k: float(v) for k, v in r.limits.items()})
        path = R.robot_path(net, j, r.model, lim, turns=r.model == "unicycle", knots=knots)
        if path.num_pieces == 0:
            continue
        if solver == "profile":
            from hierplan_opt.trajectory.profile import solve

            lo, hi = R._effective_windows(path, win, None)
            t0 = time.perf_counter()
            pr = solve(path, win.stretch, lo / win.stretch, hi / win.stretch)
            out.append((pr.ok, time.perf_counter() - t0, pr.delays))
            continue
        pp = R.path_problem(path, opts["base"])
        path_ocp(pp.N, solver)  # build outside the timing
        o = R._solve_one(path, win, opts)
        if o is not None:
            out.append((bool(o["ok"]), float(o["wall"]), int(o["iterations"])))
    return out


def main(argv: list[str] | None = None) -> int:
    from hierplan_opt.schedule import postprocess
    from hierplan_opt.trajectory import InfeasibleWindowsError, refine
    from hierplan_opt.trajectory.model import clear_cache
    from hierplan_opt.trajectory.verify import verify

    ap = BenchParser(
        "trajectory",
        __doc__ or "",
        instance="unused (the cases are fixed)",
        quick="formation and 50 warehouse robots",
        time_limit="ECBS time limit for the warehouse plan (default 120, --quick 60)",
    )
    ap.add_argument("--agents", type=int, default=200, help="warehouse robots (200)")
    ap.add_argument("--w", type=float, default=1.5, help="ECBS bound for the warehouse plan")
    ap.add_argument("--cache", metavar="DIR", help="keep the warehouse plan in DIR and reuse it")
    ap.add_argument(
        "--refine-solvers",
        default="profile,profile+qp,ipopt",
        help="solvers of the end-to-end runs, one row each (profile,profile+qp,ipopt)",
    )
    ap.add_argument("--solvers", default="profile,ipopt,fatrop", help="solvers compared per robot")
    ap.add_argument("--verify-dt", type=float, default=0.02, help="verification step (s)")
    args = ap.parse_args(argv)
    k = 50 if args.quick else args.agents
    limit = time_limit(args.time_limit, args.quick, full=120.0, small=60.0)
    cases = [_formation(), _warehouse(k, args.w, args.cache, limit)]
    print(
        f"{'case':<16} {'K':>4} {'planner':>8} {'solver':>10} {'post':>6} {'refine':>7} "
        f"{'verify':>7} {'sched->ver':>10} {'target':>7} {'met':>4} {'stretch':>7} "
        f"{'T_sched':>8} {'T_traj':>8} {'guarant.':>8} {'min d':>7} {'gap':>7} {'ok':>3} "
        f"{'N max':>5}"
    )
    results = []
    for name, inst, plan, planner in cases:
        hp_valid = validate(inst, plan)
        if hp_valid:
            raise RuntimeError(f"{name}: the plan is invalid: {hp_valid[0]}")
        t0 = time.perf_counter()
        sched = postprocess(inst, plan, "makespan", check_plan=False)
        t1 = time.perf_counter()
        for solver in [x for x in args.refine_solvers.split(",") if x]:
            clear_cache()
            t2 = time.perf_counter()
            try:
                traj = refine(inst, sched, stretch="auto", solver=solver)
            except InfeasibleWindowsError as exc:
                print(f"{name:<16} {inst.num_agents:>4} {solver:>7} refine failed: {exc}")
                continue
            t3 = time.perf_counter()
            rep = verify(traj, inst, dt=args.verify_dt)
            t4 = time.perf_counter()
            e2e = (t3 - t2) + (t4 - t3)
            key = "formation-usc" if name.startswith("formation") else "warehouse"
            target = TARGETS[key]
            met = e2e < target and rep.ok
            nmax = max((r.stats.get("intervals", 0) or 0) for r in traj.robots)
            print(
                f"{name:<16} {inst.num_agents:>4} {planner:>8} {solver:>10} {t1 - t0:6.2f} "
                f"{t3 - t2:7.2f} {t4 - t3:7.2f} {e2e:10.2f} {target:7.1f} "
                f"{'yes' if met else 'NO':>4} {traj.stretch:7.3f} {sched.makespan:8.2f} "
                f"{traj.makespan:8.2f} {traj.safety_distance:8.4f} {rep.min_distance:7.4f} "
                f"{rep.worst_gap:+7.4f} {'yes' if rep.ok else 'NO':>3} {nmax:>5}"
            )
            if solver == "profile+qp":
                qt = [r.stats["qp_time"] * 1e3 for r in traj.robots if "qp_time" in r.stats]
                print(
                    f"{'':<16} QP per robot: median {statistics.median(qt):.2f} ms, max "
                    f"{max(qt):.2f} ms, sum {sum(qt) / 1e3:.2f} s; integral |a|^2 (sum over "
                    f"robots) {traj.stats['accel_before']:.1f} -> {traj.stats['accel_after']:.1f}; "
                    f"QP fallbacks {traj.stats['qp_fallbacks']}/{len(qt)}"
                )
            results.append((name, solver, inst, traj, e2e, target, rep))
    print()
    print(
        f"{'case':<16} {'solver':>7} {'ok':>9} {'median ms':>10} {'max ms':>8} "
        f"{'sum s':>7} {'it med':>7} {'it max':>7}"
    )
    first: dict[str, tuple] = {}
    for name, _, inst, traj, _, _, _ in results:
        first.setdefault(name, (inst, traj))
    for name, (inst, traj) in first.items():
        for solver in [s for s in args.solvers.split(",") if s]:
            rows = _resolve_all(inst, traj, solver)
            if not rows:
                continue
            ok = sum(r[0] for r in rows)
            times = [r[1] * 1e3 for r in rows]
            its = [r[2] for r in rows]
            print(
                f"{name:<16} {solver:>7} {ok:>4}/{len(rows):<4} {statistics.median(times):10.1f} "
                f"{max(times):8.1f} {sum(times) / 1e3:7.2f} {statistics.median(its):7.0f} "
                f"{max(its):7d}"
            )
    print()
    for name, solver, _, _, e2e, target, rep in results:
        met = e2e < target and rep.ok
        print(
            f"target {name} ({solver}): schedule -> verified trajectories in {e2e:.2f} s "
            f"(< {target:g} s): {'MET' if met else 'NOT MET'}"
            + ("" if rep.ok else " (verification failed)")
        )
    print(
        "post = MAPF-POST earliest schedule; refine = windows + per-robot solves + stretch "
        "search (one process; profile: no NLP, profile+qp: the profile smoothed by a QP per "
        "robot (HPIPM), ipopt: IPOPT/MUMPS); met = sched->ver under "
        "the target and verified; guarant. = reported safety distance (smallest "
        "r_i + r_j); min d = verified minimum distance (lower bound over continuous time); "
        "gap = smallest (distance - r_i - r_j) over all pairs; N max = largest grid; "
        "second table: every robot re-solved in the final windows of the first solver's "
        "run (it = IPOPT/fatrop iterations, profile: knot delays)"
    )
    return 0
