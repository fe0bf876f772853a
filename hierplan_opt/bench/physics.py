"""``hierplan bench physics``: robots in MuJoCo under the execution hierarchy.

Five tables, every run in one process, one after the other:

1. **Paper warehouse, part 1 then part 2**, each with
   ``instances/paper/warehouse-disturbances.yaml`` (a stop, a blocking breakdown, a water
   spill, random delays), CBM plan, MAPF-POST, physics closed loop (slack -> STN ->
   re-plan). Targets: every working robot at its goal, 0 contacts, minimum distance >=
   the guaranteed clearance (and how much of the schedule's own minimum distance tracking
   error ate), each disturbance handled by a named layer, >= 10x real time. Tables 1-3
   also print the accelerations the engine measured against the robots' ``a_max``.
2. **32-quadcopter formation** (``formation-usc.yaml``, 3D): 0 contacts, all at targets.
3. **200 differential drives** (iRobot Create 2 size) on ``warehouse-10-20-10-2-1``,
   LaCAM (first plan; the next seed when MAPF-POST finds a rotation that no clearance
   allows) + MAPF-POST: simulated seconds per wall second >= 1 on one core.
4. **Spill vs no spill** on the paper warehouse (part 1, only the spill): which robots
   were on the spill and how late, and the layer that handled each delay the spill
   caused (``spill`` events: slack when it absorbed them); the run without the spill
   has no robot on it and no such event.

Tables 1-4 run ``simulate(..., mode="physics")``: the execution package's ClosedLoop
over the MuJoCo plant.
5. **Agreement** without disturbances, per drive type (youBot, Pioneer, Create 2,
   quadcopter; a 4-robot swap, a 3-robot 3D swap): largest |arrival - schedule| at any
   way-point and at the goals against the stated tolerances
   (:data:`hierplan_opt.physics.run.AGREEMENT`).

``--quick``: 50 robots in table 3. ``--instance`` is not used (fixed instances).
"""

from __future__ import annotations

import logging
import math
import time
from dataclasses import replace
from typing import Any

import numpy as np

from hierplan_opt.bench import BenchParser, time_limit
from hierplan_opt.core.errors import InputError
from hierplan_opt.core.graph import Graph
from hierplan_opt.core.instance import Instance, Kinematics

log = logging.getLogger(__name__)

PAPER = "instances/paper"
WAREHOUSE_MAP = "instances/movingai/warehouse-10-20-10-2-1.map"
WAREHOUSE_SCEN = "instances/movingai/warehouse-10-20-10-2-1-even-1.scen"


def _ok(flag: bool) -> str:
    return "yes" if flag else "NO"


def _plan(inst: Any, solver: str, limit: float, **options: Any) -> Any:
    from hierplan_opt.execution.chain import plan_and_post

    planned = plan_and_post(inst, solver, time_limit=limit, **options)
    if planned.schedule is None:
        raise RuntimeError(f"{inst.name}: {planned.why}")
    return planned.schedule


def _accel(st: dict[str, Any]) -> str:
    """The measured accelerations of an execution's statistics: largest |a| / a_max and
    the control periods above it (``physics.run.accelerations``), or why not checked."""
    if not st.get("acceleration_checked"):
        return "accelerations not checked (no robot type gives a_max)"
    from hierplan_opt.physics.run import ACCEL_TOL

    return (
        f"measured max |a| / a_max {st['max_acceleration_ratio']:.2f} (|dv/dt| of the "
        f"velocity vector, turns included), {st['acceleration_violations']} control "
        f"period(s) above a_max + {ACCEL_TOL:.0%}"
    )


def _planned_min(sched: Any, t: np.ndarray) -> float:
    from hierplan_opt.physics.run import scheduled_positions

    pos = scheduled_positions(sched, t)
    n = pos.shape[1]
    iu = np.triu_indices(n, 1)
    best = math.inf
    for k in range(0, len(t), 5):
        d = np.linalg.norm(pos[k, iu[0]] - pos[k, iu[1]], axis=1)
        best = min(best, float(d.min()))
    return best


def _layers_by_kind(events: list[Any]) -> dict[str, set[str]]:
    out: dict[str, set[str]] = {}
    for e in events:
        out.setdefault(e.kind, set()).add(e.layer)
    return out


def warehouse(limit: float) -> list[dict[str, Any]]:
    from hierplan_opt.execution.disturbances import Breakdown, Stop, load_disturbances
    from hierplan_opt.execution.simulate import simulate
    from hierplan_opt.io import load_instance

    print("\n1. paper warehouse in physics, with warehouse-disturbances.yaml (closed loop)")
    print(
        f"{'part':6} {'robots':>6} {'at goal':>9} {'contacts':>8} {'min_d':>6} {'guar.':>6} "
        f"{'ate':>6} {'track':>6} {'makesp':>7} {'plan':>6} {'slack':>5} {'stn':>4} "
        f"{'replan':>6} {'none':>4} {'RTF':>6}  disturbance -> layer"
    )
    rows = []
    successor: dict[str, str] = {}
    for part in ("part1", "part2"):
        inst = load_instance(f"{PAPER}/warehouse-{part}.yaml")
        dist = load_disturbances(f"{PAPER}/warehouse-disturbances.yaml")
        if successor:
            # Part 2's robots start where part 1's ended: the file's robot names are
            # carried over to the robot that starts at that robot's part-1 goal.
            dist = [
                replace(d, agent=successor[d.agent]) if isinstance(d, (Stop, Breakdown)) else d
                for d in dist
            ]
        sched = _plan(inst, "cbm", limit)
        # simulate(mode="physics"): ClosedLoop (slack -> re-order -> STN -> re-plan)
        # over the MuJoCo plant.
        ex = simulate(inst, sched, disturbances=dist, policy="replan", mode="physics")
        st = ex.statistics
        names = ex.agent_names
        working = len(names) - len(st["broken"])
        h = st["handled"]
        t_samples = ex.trajectories[0][:, 0]
        ate = _planned_min(sched, t_samples) - st["measured_min_distance"]
        by_kind = _layers_by_kind(list(ex.log))
        named = {k: sorted(v) for k, v in by_kind.items()}
        print(
            f"{part:6} {len(names):>6} {st['finished']:>4}/{working:<4} {st['contacts']:>8} "
            f"{st['measured_min_distance']:>6.3f} {st['guaranteed_distance']:>6.3f} {ate:>6.3f} "
            f"{st['tracking_error_max']:>6.2f} {st['makespan']:>7.2f} "
            f"{st['planned_makespan']:>6.2f} {h.get('slack', 0):>5} {h.get('stn', 0):>4} "
            f"{h.get('replan', 0):>6} {h.get('none', 0):>4} {st['real_time_factor']:>6.1f}  "
            + ", ".join(f"{k}: {'/'.join(v)}" for k, v in sorted(named.items()))
        )
        print(f"       {_accel(st)}")
        target = (
            st["finished"] == working
            and st["contacts"] == 0
            and st["collisions"] == 0
            and st["measured_min_margin"] >= 0
            and all("none" not in v for v in by_kind.values())
            and st["real_time_factor"] >= 10
        )
        print(
            f"       target (all working at goal, 0 contacts, distance kept, every "
            f"disturbance handled by a layer, >= 10x real time): {_ok(target)}"
        )
        rows.append({"part": part, **{k: st[k] for k in ("contacts", "finished")}})
        if part == "part1":
            at = {
                tuple(int(round(c)) for c in sched.waypoints[i].coords[-1]): n
                for i, n in enumerate(sched.agent_names)
            }
            nxt = load_instance(f"{PAPER}/warehouse-part2.yaml")
            for a in nxt.agents:
                loc = tuple(int(c) for c in np.atleast_1d(nxt.graph.location(a.start)))
                if loc in at:
                    successor[at[loc]] = a.name
    return rows


def formation(limit: float) -> None:
    from hierplan_opt.execution.simulate import simulate
    from hierplan_opt.io import load_instance

    print("\n2. formation change, 32 quadcopters (3D), physics closed loop")
    inst = load_instance(f"{PAPER}/formation-usc.yaml")
    sched = _plan(inst, "cbm", limit)
    ex = simulate(inst, sched, mode="physics")
    st = ex.statistics
    n = len(ex.agent_names)
    print(
        f"robots {n}, at targets {st['finished']}, contacts {st['contacts']}, min distance "
        f"{st['measured_min_distance']:.3f} m (guaranteed {st['guaranteed_distance']:.3f}),"
        f" makespan {st['makespan']:.2f} s (planned {st['planned_makespan']:.2f}), latest "
        f"way-point {_lateness(ex).max():.2f} s late, RTF {st['real_time_factor']:.1f}; "
        + _accel(st)
    )
    ok = st["contacts"] == 0 and st["collisions"] == 0 and st["finished"] == n
    print(f"target (0 contacts, every quadcopter at its target): {_ok(ok)}")


def fleet(n: int, limit: float) -> None:
    from hierplan_opt.execution.chain import plan_and_post
    from hierplan_opt.execution.simulate import simulate
    from hierplan_opt.io.movingai import load_movingai

    print(
        f"\n3. {n} differential drives (Create 2 size) on warehouse-10-20-10-2-1, LaCAM + "
        "MAPF-POST, physics closed loop, one process"
    )
    inst = load_movingai(WAREHOUSE_MAP, WAREHOUSE_SCEN, n)
    k = Kinematics(
        "create2", drive="differential", v_max=0.5, omega_max=2.0, a_max=0.5, radius=0.17
    )
    inst = replace(inst, agents=tuple(replace(a, kinematics=k) for a in inst.agents))
    sched = None
    for seed in range(10):
        planned = plan_and_post(inst, "lacam", time_limit=limit, seed=seed, anytime=0)
        plan = planned.result.plan
        if plan is None:
            continue
        if planned.schedule is None:
            print(f"LaCAM seed {seed}: {planned.why}; next seed")
            continue
        sched = planned.schedule
        print(f"LaCAM seed {seed}: plan makespan {plan.makespan}, schedule {sched.makespan:.1f} s")
        break
    if sched is None:
        print("no schedule")
        return
    t0 = time.perf_counter()
    ex = simulate(inst, sched, mode="physics")
    wall = time.perf_counter() - t0
    st = ex.statistics
    print(
        f"robots {n}, at goals {st['finished']}, contacts {st['contacts']}, min distance "
        f"{st['measured_min_distance']:.3f} m (guaranteed {st['guaranteed_distance']:.3f}), "
        "simulated "
        f"{st['sim_time']:.1f} s in {wall:.1f} s wall: {st['sim_time'] / wall:.2f} sim s per "
        f"wall s, {st['physics_steps']} physics steps; {_accel(st)}"
    )
    print(f"target (>= 1 simulated second per wall second): {_ok(st['sim_time'] / wall >= 1)}")


def _lateness(ex: Any) -> np.ndarray:
    """Per robot: its largest lateness at a way-point of the first schedule (s)."""
    ph = ex.phases[0]
    tpg = ph.schedule.stn.tpg
    late = np.asarray(ph.times, dtype=float) - np.asarray(ph.schedule.times, dtype=float)
    out = np.full(len(ex.agent_names), np.nan)
    for j, g in enumerate(ph.agents):
        seg = late[tpg.agent_nodes(j)]
        if np.isfinite(seg).any():
            out[g] = float(np.nanmax(seg))
    return out


def spill(limit: float) -> None:
    from hierplan_opt.execution.disturbances import Slow, load_disturbances
    from hierplan_opt.execution.simulate import simulate
    from hierplan_opt.io import load_instance

    print("\n4. water spill vs no spill (paper warehouse part 1, only the spill)")
    inst = load_instance(f"{PAPER}/warehouse-part1.yaml")
    spills = [
        d for d in load_disturbances(f"{PAPER}/warehouse-disturbances.yaml") if isinstance(d, Slow)
    ]
    sched = _plan(inst, "cbm", limit)
    runs = {}
    for label, dist in (("spill", spills), ("no spill", [])):
        ex = simulate(inst, sched, disturbances=dist, mode="physics")
        runs[label] = ex
        st = ex.statistics
        on = [n for n, c in st["disturbed"].items() if "spill" in c]
        # The physics' own delays reach the monitor as lateness, named after the spill
        # that acted on the robot (events of kind "spill", whichever layer handled them).
        wet = [e for e in ex.log if e.kind in ("spill", "late") and e.agent in on]
        layers = sorted({e.layer for e in wet})
        print(
            f"{label:9} late events of robots on the spill {len(wet):>3} (layers "
            f"{', '.join(layers) or '-'}), robots on the spill: {', '.join(on) or '-'}"
            f", makespan {st['makespan']:.2f} s, contacts {st['contacts']}"
        )
    wet_robots = [n for n, c in runs["spill"].statistics["disturbed"].items() if "spill" in c]
    w, d = runs["spill"], runs["no spill"]
    lw_all, ld_all = _lateness(w), _lateness(d)
    print(f"{'robot':10} {'latest wp (spill)':>17} {'(dry)':>6} {'goal (spill)':>12} {'(dry)':>6}")
    for n in wet_robots:
        i = w.agent_names.index(n)
        a, b = float(w.arrival[i]), float(d.arrival[i])
        print(f"{n:10} {lw_all[i]:>17.2f} {ld_all[i]:>6.2f} {a:>12.2f} {b:>6.2f}")


def agreement() -> None:
    from hierplan_opt.physics.run import AGREEMENT, GOAL_TOL, follow

    print("\n5. agreement with the schedule, no disturbance (4-robot swap; 3D: 3 robots)")
    kinds = [
        Kinematics("youbot", drive="omni", v_max=0.8, a_max=1.0, radius=0.35),
        Kinematics(
            "pioneer", drive="differential", v_max=0.6, omega_max=1.5, a_max=0.3, radius=0.3
        ),
        Kinematics(
            "create2", drive="differential", v_max=0.5, omega_max=2.0, a_max=0.5, radius=0.17
        ),
        Kinematics("quad", drive="omni", v_max=1.0, a_max=2.0, radius=0.15),
    ]
    print(f"{'type':8} {'max |dt|':>8} {'tol':>5} {'goal |dt|':>9} {'tol':>5} {'contacts':>8}")
    for k in kinds:
        if k.robot_type == "quad":
            g = Graph.grid(3, 3, 3)
            inst = Instance.mapf(
                g,
                [(0, 0, 0), (2, 2, 2), (0, 2, 0)],
                [(2, 2, 2), (0, 0, 0), (2, 0, 2)],
                kinematics=k,
            )
        else:
            g = Graph.grid(5, 4, obstacles=[(2, 1), (2, 2)])
            inst = Instance.mapf(
                g, [(0, 0), (4, 0), (0, 3), (4, 3)], [(4, 3), (0, 3), (4, 0), (0, 0)], kinematics=k
            )
        sched = _plan(inst, "cbs", 10)
        run = follow(inst, sched)
        dev = max(
            float(np.nanmax(np.abs(r - p))) for r, p in zip(run.reach, run.planned, strict=True)
        )
        goal = max(abs(float(r[-1] - p[-1])) for r, p in zip(run.reach, run.planned, strict=True))
        tol = AGREEMENT[k.robot_type]
        print(
            f"{k.robot_type:8} {dev:>8.2f} {tol:>5.2f} {goal:>9.2f} {GOAL_TOL:>5.2f} "
            f"{run.statistics['contacts']:>8}  {_ok(dev <= tol and goal <= GOAL_TOL)}"
        )


def main(argv: list[str] | None = None) -> int:
    p = BenchParser(
        "physics",
        "robots in MuJoCo physics under the execution hierarchy",
        instance="not used (the tables' instances are fixed)",
        quick="50 robots in table 3 instead of 200",
    )
    args = p.parse_args(argv)
    if args.instance:
        raise InputError("bench physics: --instance is not used (its instances are fixed)")
    limit = time_limit(args.time_limit, args.quick, full=60.0, small=10.0)
    from hierplan_opt.physics.plant import mujoco  # heavy module

    print(f"MuJoCo {mujoco.__version__}; RTF = simulated seconds per wall second")
    warehouse(limit)
    formation(limit)
    fleet(50 if args.quick else 200, min(limit, 30.0))
    spill(limit)
    agreement()
    return 0
