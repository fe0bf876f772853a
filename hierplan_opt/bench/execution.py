"""``hierplan bench execution``: what each execution layer costs and buys.

Three tables:

1. **STN re-solve after one delay** (MovingAI warehouse, ECBS plans, point robots):
   one robot's next event in the middle of the plan is made late by its slack plus 5 s;
   the incremental re-solve (``rebound`` + ``fix_and_propagate``, as the ``stn`` layer
   runs it) is timed against a full earliest-times pass on the same STN and against a
   MAPF re-plan (ECBS, same ``w``) from the robots' plan positions at that moment to
   their goals. Target: re-solve under 50 ms at 300 robots.
2. **Monte Carlo throughput**: runs per second of :func:`monte_carlo` (random delays,
   policy ``replan``) at 50 and 300 robots, in one process and in ``--workers``.
3. **Layers on the paper's warehouse** (``warehouse-part1.yaml``): share of random
   delays handled by slack, STN re-solve and re-plan at three delay rates, with
   delivery windows (each robot due 10 % after its planned arrival) so that large
   delays make the STN inconsistent and escalate to a re-plan.
4. **Robot mode through re-plans** (warehouse): seeded runs with random delays, a stop
   and a blocking breakdown: re-plans, largest |a| / a_max (from the controller),
   acceleration violations, collisions, makespan against the agent run, time per run.
5. **Delay-aware re-plan** (warehouse, random delays p = 0.2 of 1 s): the lowest on-time
   probability before and after ``monte_carlo(..., replan_below=0.9)``, the rounds and
   the planned makespans.
6. **Re-plan layer against its MAPF solve** (MovingAI warehouse, 50 robots, point
   robots and robots of radius 0.3; per seed three breakdowns, a stop and random
   delays): for each re-plan the whole layer's time (frontier, solve, MAPF-POST,
   hand-over) beside the solve's own time. Target: layer <= 2x solve and < 2 s.
   ``--replan-only`` prints this table alone.

Figures are medians over ``--repeats``; plans are made once per robot count.
"""

from __future__ import annotations

import statistics
import time
from pathlib import Path

import numpy as np

from hierplan_opt.api import solve
from hierplan_opt.bench import BenchParser, time_limit
from hierplan_opt.core.errors import InputError
from hierplan_opt.core.instance import Instance, Kinematics


def _say(line: str) -> None:
    print(line)


def _median(fn, repeats: int) -> float:
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def _delay_point(schedule) -> tuple[int, float]:
    """A node in the middle of the plan on the robot with the most nodes, and its delay."""
    tpg = schedule.stn.tpg
    lengths = np.diff(tpg.agent_ptr)
    j = int(np.argmax(lengths))
    nodes = tpg.agent_nodes(j)
    v = nodes.start + len(nodes) // 2
    return v, float(schedule.slack[v]) + 5.0


def resolve_row(
    instance: Instance, plan, schedule, w: float, repeats: int, time_limit: float = 120.0
) -> dict:
    """Times of the incremental re-solve, a full pass and a MAPF re-plan (seconds)."""
    from hierplan_opt.execution.simulate import rebound
    from hierplan_opt.schedule import earliest_times, fix_and_propagate

    stn = schedule.stn
    v, delay = _delay_point(schedule)
    times = np.array(schedule.times)
    release = np.array(stn.release)
    release[v] = times[v] + delay
    _ = stn.topo  # built once with the schedule

    def incremental():
        new = rebound(stn, release=release)
        return fix_and_propagate(new, times, {v - 1: float(times[v - 1])}, changed=[v])

    t_inc = _median(incremental, repeats)
    new_times = incremental()
    pushed = int(np.count_nonzero(new_times > times + 1e-9))
    full_stn = stn.with_bounds(release=release)
    full_stn.__dict__["topo"] = stn.topo
    t_full = _median(lambda: earliest_times(full_stn), repeats)
    assert np.allclose(earliest_times(full_stn), new_times)  # the same schedule
    # The same moment as a MAPF problem: plan positions at the node's step.
    step = int(stn.tpg.node_step[v])
    starts = [plan.position(j, step) for j in range(instance.num_agents)]
    inst2 = Instance(
        instance.graph,
        tuple(
            type(a)(a.name, s, a.goal, None, a.kinematics)
            for a, s in zip(instance.agents, starts, strict=True)
        ),
        (),
        None,
        "replan",
    )
    t0 = time.perf_counter()
    res = solve(inst2, "ecbs", w=w, time_limit=time_limit)
    t_replan = time.perf_counter() - t0
    return {
        "resolve": t_inc,
        "full": t_full,
        "replan": t_replan,
        "replan_status": str(res.status),
        "replan_ok": res.plan is not None,
        "pushed": pushed,
        "nodes": stn.num_nodes,
        "delay": delay,
    }


def main(argv: list[str] | None = None) -> int:
    from hierplan_opt.bench.post import DEFAULT_MAP, DEFAULT_SCEN, make_plan
    from hierplan_opt.execution import RandomDelays
    from hierplan_opt.execution.montecarlo import monte_carlo
    from hierplan_opt.experiments.data import instances_dir, movingai_files
    from hierplan_opt.io import load_instance
    from hierplan_opt.io.movingai import load_map, load_scen
    from hierplan_opt.schedule import postprocess

    ap = BenchParser(
        "execution",
        (__doc__ or "").split("\n\n")[0],
        instance="a bundled MovingAI scenario of tables 1 and 2 "
        "(default warehouse-10-20-10-2-1-even-1)",
        quick="small sizes (a smoke test)",
        time_limit="seconds per plan and re-plan (default 120)",
    )
    ap.add_argument("--agents", default="100,200,300", help="robot counts of table 1")
    ap.add_argument("--mc-agents", default="50,300", help="robot counts of table 2")
    ap.add_argument("--runs", type=int, default=40, help="Monte Carlo runs per row")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--w", type=float, default=1.5, help="ECBS suboptimality bound")
    ap.add_argument("--rates", default="0.05,0.1,0.2", help="delay probabilities of table 3")
    ap.add_argument("--layer-runs", type=int, default=50)
    ap.add_argument("--replan-agents", type=int, default=50, help="robots of table 6")
    ap.add_argument("--replan-seeds", type=int, default=4, help="seeds of table 6")
    ap.add_argument("--replan-only", action="store_true", help="table 6 alone")
    args = ap.parse_args(argv)
    limit = time_limit(args.time_limit, False, full=120.0)
    if args.quick:
        args.agents, args.mc_agents, args.runs, args.repeats = "20,40", "20", 6, 2
        args.layer_runs, args.workers = 6, 1

    def shipped(name: str) -> Path:
        return Path(name) if Path(name).exists() else instances_dir() / name.split("/", 1)[-1]

    map_path, scen_path = shipped(DEFAULT_MAP), shipped(DEFAULT_SCEN)
    if args.instance:
        if len(args.instance) != 1:
            ap.error("--instance takes one scenario")
        map_path, scen_path = movingai_files(args.instance[0].removesuffix(".scen"))
    graph = load_map(str(map_path))
    scen = str(scen_path)
    cache: dict[int, tuple] = {}
    if args.replan_only:
        inst = load_scen(scen, graph, agents=args.replan_agents)
        replan_rows(inst, args.replan_seeds, limit)
        return 0

    def setup(k: int) -> tuple:
        if k not in cache:
            inst = load_scen(scen, graph, agents=k)
            plan, planner = make_plan(inst, w=args.w, time_limit=limit)
            cache[k] = (inst, plan, postprocess(inst, plan, check_plan=False), planner)
        return cache[k]

    _say(f"1. STN re-solve after one delay ({map_path.name}, medians of {args.repeats})")
    _say(
        f"{'K':>4} {'planner':>10} {'nodes':>7} {'pushed':>7} {'resolve ms':>10} "
        f"{'full ms':>8} {'replan s':>9} {'speed-up':>9}"
    )
    for k in [int(x) for x in args.agents.split(",") if x]:
        try:
            inst, plan, s, planner = setup(k)
        except InputError as exc:  # more robots than the scenario has
            _say(f"{k:>4} skipped: {exc}")
            continue
        r = resolve_row(inst, plan, s, args.w, args.repeats, limit)
        _say(
            f"{k:>4} {planner:>10} {r['nodes']:>7} {r['pushed']:>7} {r['resolve'] * 1e3:>10.2f} "
            f"{r['full'] * 1e3:>8.2f} {r['replan']:>9.3f} {r['replan'] / r['resolve']:>8.0f}x"
            + ("" if r["replan_ok"] else f"  (re-plan {r['replan_status']})")
        )
    _say(f"\n2. Monte Carlo throughput (random delays p=0.05, exp. mean 2 s; {args.runs} runs)")
    _say(f"{'K':>4} {'workers':>7} {'runs/s':>8} {'collisions':>10}")
    delays = [RandomDelays(0.05, "exponential", 2.0)]
    for k in [int(x) for x in args.mc_agents.split(",") if x]:
        try:
            inst, plan, s, _ = setup(k)
        except InputError as exc:  # more robots than the scenario has
            _say(f"{k:>4} skipped: {exc}")
            continue
        for w in sorted({1, args.workers}):
            mc = monte_carlo(inst, s, delays, runs=args.runs, workers=w, progress=False)
            _say(f"{k:>4} {w:>7} {mc.runs_per_second:>8.2f} {mc.collisions:>10}")
    wh = load_instance(shipped("instances/paper/warehouse-part1.yaml"))

    plan = solve(wh, "cbm", time_limit=60.0 if args.time_limit is None else limit).plan
    assert plan is not None
    plain = postprocess(wh, plan, check_plan=False)
    # Delivery windows: every robot due 10 % after its planned arrival.
    names, wps = plain.agent_names, plain.waypoints
    due: dict[str | int, float] = {
        n: float(w.arrival[-1]) * 1.1 for n, w in zip(names, wps, strict=True)
    }
    s = postprocess(wh, plan, check_plan=False, deadlines=due)
    _say(
        f"\n3. Layers on warehouse-part1 (12 robots, {args.layer_runs} runs per rate, policy "
        "replan, delays exp. mean 2 s, each robot due 10 % after its planned arrival)"
    )
    _say(
        f"{'p':>5} {'delays':>7} {'slack':>7} {'stn':>7} {'replan':>7} {'makespan+':>10} "
        f"{'collisions':>10}"
    )
    for p in [float(x) for x in args.rates.split(",") if x]:
        mc = monte_carlo(
            wh,
            s,
            [RandomDelays(p, "exponential", 2.0)],
            runs=args.layer_runs,
            workers=args.workers,
            progress=False,
        )
        h = mc.handled
        total = max(1, sum(h.values()))
        _say(
            f"{p:>5.2f} {total:>7} {h.get('slack', 0) / total:>7.1%} "
            f"{h.get('stn', 0) / total:>7.1%} {h.get('replan', 0) / total:>7.1%} "
            f"{float(np.nanmean(mc.delays)):>9.2f}s {mc.collisions:>10}"
        )
    robot_rows(wh, plain, 3 if args.quick else 10)
    mc = monte_carlo(
        wh,
        plain,
        [RandomDelays(0.2, "constant", 1.0)],
        runs=args.layer_runs,
        workers=args.workers,
        progress=False,
        replan_below=0.9,
        replan_solver="cbm",
    )
    new = mc.replanned
    _say(
        f"\n5. Delay-aware re-plan on warehouse-part1 ({mc.runs} runs, delays p=0.2 of 1 s, "
        "threshold 0.9)"
    )
    _say(f"{'':>6} {'on time min':>11} {'below':>6} {'planned makespan':>16} {'rounds':>6}")
    _say(f"{'before':>6} {mc.on_time.min():>11.2f} {len(mc.below):>6} {plain.makespan:>15.2f}s")
    if new is not None:
        low = int(np.count_nonzero(new.result.on_time < 0.9))
        _say(
            f"{'after':>6} {new.result.on_time.min():>11.2f} {low:>6} "
            f"{new.schedule.makespan:>15.2f}s {new.rounds:>6}"
        )
    inst = load_scen(scen, graph, agents=args.replan_agents)
    replan_rows(inst, 2 if args.quick else args.replan_seeds, limit)
    return 0


def replan_rows(instance: Instance, seeds: int, time_limit: float) -> list[dict]:
    """Table 6: each re-plan's whole layer time beside its MAPF solve's own time."""
    import dataclasses

    from hierplan_opt.execution import Breakdown, RandomDelays, Stop, simulate
    from hierplan_opt.execution.chain import plan_and_post

    K = instance.num_agents
    _say(
        f"\n6. Re-plan layer against its MAPF solve ({instance.name}, {K} robots; per seed "
        "3 breakdowns, a stop, random delays p=0.1 exp. mean 2 s; one warm process)"
    )
    _say(
        f"{'radius':>6} {'seed':>4} {'t':>6} {'robots':>6} {'solver':>6} {'frontier':>9} "
        f"{'solve s':>8} {'post s':>7} {'hand-over':>9} {'layer s':>8} {'layer/solve':>11} "
        f"{'target':>6}"
    )
    rows = []
    for radius in (0.0, 0.3):
        kin = Kinematics(radius=radius)
        inst = dataclasses.replace(
            instance,
            agents=tuple(dataclasses.replace(a, kinematics=kin) for a in instance.agents),
        )
        planned = plan_and_post(inst, "ecbs", time_limit=time_limit)
        if planned.schedule is None:
            _say(f"{radius:>6} {planned.why}")
            continue
        sched = planned.schedule
        names = [a.name for a in inst.agents]
        for seed in range(seeds):
            rng = np.random.default_rng(seed)
            who = rng.choice(K, size=4, replace=False)
            dist = [
                RandomDelays(0.1, "exponential", 2.0, seed=seed),
                Stop(names[int(who[0])], 10.0, at_time=3.0),
                Breakdown(names[int(who[1])], at_time=5.0),
                Breakdown(names[int(who[2])], at_time=8.0),
                Breakdown(names[int(who[3])], at_time=15.0),
            ]
            ex = simulate(inst, sched, disturbances=dist, seed=seed)
            for r in ex.statistics["replan_runtime"]:
                ratio = r["layer"] / max(r["solve"], 1e-9)
                ok = r["layer"] <= 2 * r["solve"] and r["layer"] < 2.0
                _say(
                    f"{radius:>6g} {seed:>4} {r['time']:>6.1f} {r['robots']:>6} "
                    f"{r['solver']:>6} {r['frontier'] * 1e3:>7.1f}ms {r['solve']:>8.3f} "
                    f"{r['post']:>7.3f} {r['handover']:>9.3f} {r['layer']:>8.3f} "
                    f"{ratio:>10.2f}x {'ok' if ok else 'MISS':>6}"
                )
                rows.append({"radius": radius, "seed": seed, **r})
    return rows


def robot_rows(instance: Instance, schedule, seeds: int) -> None:
    """Table 4: robot mode through re-plans on the warehouse."""
    from hierplan_opt.execution import Breakdown, RandomDelays, Stop, simulate

    names = [a.name for a in instance.agents]
    _say(
        f"\n4. Robot mode through re-plans on warehouse-part1 ({seeds} seeds: random delays "
        "p=0.1, a stop, youbot8 breaks down; dt 0.05 s)"
    )
    _say(
        f"{'seed':>4} {'replans':>7} {'max|a|/a_max':>12} {'violations':>10} "
        f"{'collisions':>10} {'makespan':>8} {'agent':>7} {'run s':>6}"
    )
    for seed in range(seeds):
        rng = np.random.default_rng(seed)
        dist = [
            RandomDelays(0.1, "exponential", 2.0),
            Stop(names[int(rng.integers(len(names)))], 5.0, at_time=float(rng.uniform(0, 15))),
            Breakdown("youbot8", float(rng.uniform(3, 15))),
        ]
        agent = simulate(instance, schedule, disturbances=dist, seed=seed)
        t0 = time.perf_counter()
        ex = simulate(instance, schedule, disturbances=dist, seed=seed, mode="robot", dt=0.05)
        el = time.perf_counter() - t0
        st = ex.statistics
        _say(
            f"{seed:>4} {st['replans']:>7} {st['max_acceleration_ratio']:>12.4f} "
            f"{st['acceleration_violations']:>10} {st['collisions']:>10} "
            f"{st['makespan']:>8.2f} {agent.statistics['makespan']:>7.2f} {el:>6.2f}"
        )
