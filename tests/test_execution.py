"""Execution under disturbances: the layers (slack, STN re-solve, re-plan), the TPG
rule (no collisions), the baselines, determinism and the disturbance files."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import hierplan_opt as hp
from hierplan_opt import Graph, Instance, Plan
from hierplan_opt.core.errors import InputError, OptionError
from hierplan_opt.core.instance import Kinematics
from hierplan_opt.execution import (
    Breakdown,
    RandomDelays,
    Slow,
    Stop,
    load_disturbances,
    simulate,
)
from hierplan_opt.schedule import check_bounds, postprocess

ROOT = Path(__file__).resolve().parent.parent
WAREHOUSE = ROOT / "instances" / "paper" / "warehouse-part1.yaml"


@pytest.fixture(scope="module")
def warehouse():
    inst = hp.load_instance(WAREHOUSE)
    plan = hp.solve(inst, "cbm", time_limit=60).plan
    assert plan is not None
    return inst, postprocess(inst, plan, check_plan=False)


def _slack_point(schedule, min_slack: float):
    """(robot name, a time inside its move, next node) with at least ``min_slack``."""
    tpg = schedule.stn.tpg
    for j in range(tpg.num_agents):
        nodes = list(tpg.agent_nodes(j))
        for a, b in zip(nodes[:-1], nodes[1:], strict=True):
            if schedule.times[b] - schedule.times[a] > 0.2 and schedule.slack[b] > min_slack:
                t = float(schedule.times[a] + 0.1)
                return tpg.agent_names[j], t, b
    raise AssertionError("no node with that much slack")


def test_delay_within_slack_triggers_nothing(warehouse):
    inst, s = warehouse
    name, t, n = _slack_point(s, 3.0)
    ex = simulate(inst, s, disturbances=[Stop(name, 1.0, at_time=t)], policy="replan")
    assert [e.layer for e in ex.log] == ["slack"]
    st = ex.statistics
    assert st["stn_resolves"] == st["replans"] == 0
    assert st["makespan"] == pytest.approx(s.makespan)
    # No other robot's event moved: the order and times of the plan are kept.
    tpg = s.stn.tpg
    j = tpg.agent_names.index(name)
    other = tpg.node_agent != j
    assert np.allclose(ex.event_times[other], s.times[other])
    assert st["collisions"] == 0 and st["distance_kept"]


def test_larger_delay_triggers_stn_resolve_that_meets_every_bound(warehouse):
    inst, s = warehouse
    name, t, n = _slack_point(s, 1.0)
    d = float(s.slack[n]) + 4.0
    ex = simulate(inst, s, disturbances=[Stop(name, d, at_time=t)], policy="stn")
    assert [e.layer for e in ex.log] == ["stn"]
    assert ex.statistics["stn_resolves"] == 1
    phase = ex.phases[0]
    assert check_bounds(phase.stn, phase.targets) == []  # the re-solved schedule
    assert check_bounds(phase.stn, phase.times) == []  # what was executed
    assert phase.targets[n] >= s.times[n] + d - s.slack[n] - 1e-6
    assert ex.statistics["makespan"] > s.makespan
    assert ex.statistics["collisions"] == 0 and ex.statistics["distance_kept"]
    # The slack policy keeps the old targets and lets the TPG hold the others.
    ex2 = simulate(inst, s, disturbances=[Stop(name, d, at_time=t)], policy="slack")
    assert ex2.statistics["stn_resolves"] == 0
    assert ex2.statistics["collisions"] == 0


def _blocking_breakdown(inst, s):
    for name in s.agent_names:
        ex = simulate(inst, s, disturbances=[Breakdown(name, 6.0)], policy="stn")
        if ex.statistics["unfinished"] != [name] and len(ex.statistics["unfinished"]) > 1:
            return name, ex
    raise AssertionError("no breakdown blocks another robot")


def test_breakdown_on_a_path_triggers_a_valid_replan(warehouse):
    inst, s = warehouse
    name, stuck = _blocking_breakdown(inst, s)
    assert stuck.log[0].layer == "none"  # the stn policy cannot help
    ex = simulate(inst, s, disturbances=[Breakdown(name, 6.0)], policy="replan")
    st = ex.statistics
    assert st["replans"] == 1 and "replan" in [e.layer for e in ex.log]
    assert st["unfinished"] == [name] and st["finished"] == inst.num_agents - 1
    ((inst2, plan),) = ex.replans
    assert hp.validate(inst2, plan) == []
    assert st["collisions"] == 0 and st["distance_kept"]
    # The broken robot is an obstacle of the new plan.
    g = inst2.graph
    where = ex.trajectories[s.agent_names.index(name)][-1, 1:]
    near = np.linalg.norm(g.coords - where, axis=1) < 0.5
    assert not g.passable[near].any()


def test_deadline_escalates_to_replan(warehouse):
    inst, s = warehouse
    last = s.agent_names[int(np.argmax([w.arrival[-1] for w in s.waypoints]))]
    tight = postprocess(inst, _plan(inst), deadlines={last: s.makespan + 0.5})
    name, t, n = _slack_point(tight, 0.0)
    stop = Stop(last, 30.0, at_time=1.0)
    ex = simulate(inst, tight, disturbances=[stop], policy="stn")
    assert ex.log[0].layer == "none" and "inconsistent" in ex.log[0].detail
    ex = simulate(inst, tight, disturbances=[stop], policy="replan")
    assert ex.log[0].layer == "replan" and ex.statistics["replans"] == 1
    assert ex.statistics["collisions"] == 0 and ex.statistics["distance_kept"]


def _plan(inst):
    return hp.solve(inst, "cbm", time_limit=60).plan


@pytest.mark.parametrize("policy", ["slack", "stn", "replan", "reorder", "adg"])
def test_monte_carlo_batch_has_no_collisions(warehouse, policy):
    inst, s = warehouse
    for seed in range(6):
        dist = [
            RandomDelays(0.15, "exponential", 2.0),
            Stop(s.agent_names[seed], 5.0, at_time=3.0 + seed),
            Slow(0.4, cells=((8, 9), (9, 9), (10, 9))),
        ]
        if seed % 3 == 0:
            dist.append(Breakdown(s.agent_names[(seed + 4) % len(s.agent_names)], 8.0))
        ex = simulate(inst, s, disturbances=dist, policy=policy, seed=seed)
        st = ex.statistics
        assert st["collisions"] == 0, (policy, seed)
        assert st["distance_kept"], (policy, seed, st["min_distance"])
        assert st["min_distance"] >= st["guaranteed_distance"] - 1e-9


def _corridor():
    kin = Kinematics("disc", v_max=1.0, radius=0.3)
    inst = Instance.mapf(Graph.grid(6, 1), [(1, 0), (0, 0)], [(5, 0), (4, 0)], kinematics=kin)
    s = postprocess(inst, Plan.from_paths([[1, 2, 3, 4, 5], [0, 1, 2, 3, 4]]))
    return inst, s


def test_naive_collides_where_the_tpg_waits():
    inst, s = _corridor()
    stop = [Stop("agent0", 3.0, at_time=0.5)]
    naive = simulate(inst, s, disturbances=stop, policy="naive")
    assert naive.statistics["collisions"] == 1
    assert naive.statistics["min_distance"] < 0.6
    for policy in ("slack", "stn", "adg"):
        st = simulate(inst, s, disturbances=stop, policy=policy).statistics
        assert st["collisions"] == 0 and st["min_distance"] >= 0.6 - 1e-9


def test_identical_seeds_identical_results(warehouse):
    inst, s = warehouse
    dist = [RandomDelays(0.3, "uniform", 0.5, 3.0)]
    a = simulate(inst, s, disturbances=dist, seed=3)
    b = simulate(inst, s, disturbances=dist, seed=3)
    c = simulate(inst, s, disturbances=dist, seed=4)
    assert all(np.array_equal(x, y) for x, y in zip(a.trajectories, b.trajectories, strict=True))
    assert a.log == b.log
    assert a.statistics["makespan"] == b.statistics["makespan"]
    assert not all(
        x.shape == y.shape and np.array_equal(x, y)
        for x, y in zip(a.trajectories, c.trajectories, strict=True)
    )


def test_slow_region_and_waypoint_stop(warehouse):
    inst, s = warehouse
    base = simulate(inst, s)
    assert base.log == () and base.statistics["makespan"] == pytest.approx(s.makespan)
    # Executed trajectories of an undisturbed run pass the planned way-points on time.
    for wp, tr in zip(s.waypoints, base.trajectories, strict=True):
        assert tr[-1, 0] == pytest.approx(wp.arrival[-1])
    ex = simulate(inst, s, disturbances=[Slow(0.1, cells=tuple((x, 9) for x in range(21)))])
    assert ex.statistics["makespan"] > s.makespan
    ex = simulate(inst, s, disturbances=[Stop("pioneer1", 7.0, at_waypoint=2)])
    assert ex.log[0].kind == "stop" and ex.statistics["collisions"] == 0


def test_options_refused(warehouse):
    inst, s = warehouse
    with pytest.raises(OptionError, match="unknown policy"):
        simulate(inst, s, policy="magic")
    with pytest.raises(InputError, match="not in the schedule"):
        simulate(inst, s, disturbances=[Stop("nobody", 1.0, at_time=1.0)])
    with pytest.raises(InputError):
        Stop("a", 1.0)


EXAMPLE = """disturbances:
  - {kind: stop, agent: youbot3, at_time: 4.0, duration: 6.0}
  - {kind: stop, agent: youbot4, at_waypoint: 2, duration: 1.0}
  - {kind: breakdown, agent: youbot7, at_time: 10.0}
  - {kind: slow, cells: [[3, 4], [3, 5]], factor: 0.3, from: 0.0, to: 30.0}
  - {kind: slow, edges: [[[0, 0], [1, 0]]], factor: 0.5}
  - {kind: random, probability: 0.1, duration: {exponential: 2.0}, seed: 1}
  - {kind: random, probability: 0.1, duration: {uniform: [1, 2]}}
"""


def test_disturbance_file(tmp_path):
    f = tmp_path / "d.yaml"
    f.write_text(EXAMPLE)
    ds = load_disturbances(f)
    assert [type(d).__name__ for d in ds] == [
        "Stop",
        "Stop",
        "Breakdown",
        "Slow",
        "Slow",
        "RandomDelays",
        "RandomDelays",
    ]
    assert ds[3] == Slow(0.3, ((3, 4), (3, 5)), (), 0.0, 30.0)
    assert ds[5] == RandomDelays(0.1, "exponential", 2.0, 0.0, 1)


BAD = [
    ("disturbances: [{kind: stop, agent: a, duration: 1}]", ":1:", "exactly one of"),
    ("disturbances:\n  - {kind: jump, agent: a}", ":2:", "unknown kind 'jump'"),
    ("disturbances:\n  - {kind: stop, agent: a, at_time: -1, duration: 1}", ":2:", "negative"),
    ("disturbances:\n  - {kind: slow, cells: [[1, 2]], factor: 2}", ":2:", "(0, 1]"),
    ("disturbances:\n  - {kind: slow, factor: 0.5}", ":2:", "cells or edges"),
    ("disturbances:\n  - {kind: random, probability: 1.5, duration: 1}", ":2:", "[0, 1]"),
    ("disturbances:\n  - {kind: random, probability: 0.5, duration: {gauss: 1}}", ":2:", "gauss"),
    ("disturbances:\n  - {kind: breakdown, agent: a, at_time: 1, x: 2}", ":2:", "unknown key"),
    ("disturbances:\n  - {kind: stop, agent: zz, at_time: 1, duration: 1}", ":2:", "no robot"),
    ("stops: []", "", "unknown key 'stops'"),
    ("disturbances: [", "", "YAML syntax error"),
]


@pytest.mark.parametrize(("text", "where", "what"), BAD)
def test_bad_disturbance_files_refused_with_one_line(tmp_path, text, where, what):
    f = tmp_path / "bad.yaml"
    f.write_text(text + "\n")
    with pytest.raises(InputError) as exc:
        load_disturbances(f, agents=("a", "b"))
    msg = str(exc.value)
    assert "\n" not in msg and msg.startswith(str(f) + where) and what in msg


def test_pictures(tmp_path, warehouse):
    import matplotlib

    from hierplan_opt.viz.animation import animate, plot_distance, plot_layers

    backend = matplotlib.get_backend()
    inst, s = warehouse
    ex = simulate(inst, s, disturbances=[Stop("youbot3", 6.0, at_time=4.0)])
    fig = plot_distance(ex, inst, tmp_path / "d.png")
    assert (tmp_path / "d.png").stat().st_size > 0 and fig.axes
    plot_layers([("one", ex.statistics["handled"])], tmp_path / "l.png")
    gif = animate(ex, inst, tmp_path / "run.gif", max_frames=6)
    from PIL import Image

    assert Image.open(gif).n_frames == 6
    assert matplotlib.get_backend() == backend  # the library never switches it
    with pytest.raises(InputError, match="gif or .mp4"):
        animate(ex, inst, tmp_path / "run.avi")


def test_bench_resolve_row_matches_a_full_pass():
    from hierplan_opt.bench.execution import resolve_row
    from hierplan_opt.io.movingai import load_map, load_scen

    g = load_map(str(ROOT / "instances/movingai/warehouse-10-20-10-2-1.map"))
    inst = load_scen(str(ROOT / "instances/movingai/warehouse-10-20-10-2-1-even-1.scen"), g, 20)
    plan = hp.solve(inst, "ecbs", w=1.5, time_limit=60).plan
    s = postprocess(inst, plan, check_plan=False)
    row = resolve_row(inst, plan, s, 1.5, 1)  # asserts incremental == full pass
    assert row["pushed"] >= 1 and row["replan_ok"]


@pytest.mark.slow
def test_bench_execution_quick(capsys):
    from hierplan_opt.bench.execution import main

    assert main(["--quick"]) == 0
    out = capsys.readouterr().out
    assert "STN re-solve" in out and "runs/s" in out and "replan" in out


@pytest.mark.parametrize("radius", [0.0, 0.3])
def test_reorder_lets_the_robot_behind_a_late_one_pass_first(radius):
    g = Graph.grid(5, 5)
    kin = Kinematics("disc", v_max=1.0, radius=radius)
    inst = Instance.mapf(g, [(0, 2), (2, 0)], [(4, 2), (2, 4)], kinematics=kin)
    a = [g.vertex((x, 2)) for x in range(5)]
    b = [g.vertex(c) for c in [(2, 0), (2, 0), (2, 1), (2, 2), (2, 3), (2, 4)]]
    s = postprocess(inst, Plan.from_paths([a, b]))  # agent0 crosses (2, 2) first
    stop = [Stop("agent0", 10.0, at_time=0.5)]
    held = simulate(inst, s, disturbances=stop, policy="stn")
    ex = simulate(inst, s, disturbances=stop, policy="reorder")
    assert held.arrival[1] > 14.0 - 1e-9  # agent1 waits at the crossing
    assert ex.arrival.tolist() == [14.0, pytest.approx(s.makespan)]  # it goes first
    assert ex.statistics["collisions"] == 0 and ex.statistics["distance_kept"]
    assert ex.statistics["reorders"] == 1 and ex.log[0].layer == "reorder"
    phase = ex.phases[0]
    assert phase.stn.topo.is_dag and check_bounds(phase.stn, phase.times) == []


def test_reorder_keeps_a_robot_that_comes_back_ordered():
    """Issue 30: agent1 passes (2, 1) twice in a row (to (2, 2) and back), agent0 once
    before it. Switching agent0 behind agent1's first passage treated agent1 as the last
    at the lock and left its second passage unordered with agent0: with both held up,
    the two point robots met on (2, 1). The claims of a lock must stay totally ordered."""
    g = Graph.grid(5, 3)
    kin = Kinematics("disc", v_max=1.0, radius=0.0)
    inst = Instance.mapf(g, [(0, 1), (2, 0)], [(4, 1), (2, 0)], kinematics=kin)
    a = [g.vertex((x, 1)) for x in range(5)]
    b = [g.vertex(c) for c in [(2, 0)] * 4 + [(2, 1)] + [(2, 2)] * 10 + [(2, 1), (2, 0)]]
    s = postprocess(inst, Plan.from_paths([a, b]))
    stops = [
        Stop("agent0", 10.0, at_time=0.5),
        Stop("agent0", 20.0, at_waypoint=2),  # it halts on (2, 1)
        Stop("agent1", 20.0, at_waypoint=2),
    ]
    ex = simulate(inst, s, disturbances=stops, policy="reorder")
    assert ex.statistics["collisions"] == 0
    ta, tb = ex.trajectories
    ts = np.union1d(ta[:, 0], tb[:, 0])
    pa = np.column_stack([np.interp(ts, ta[:, 0], ta[:, k]) for k in (1, 2)])
    pb = np.column_stack([np.interp(ts, tb[:, 0], tb[:, k]) for k in (1, 2)])
    d0, e = (pa - pb)[:-1], np.diff(pa - pb, axis=0)  # relative motion, piecewise linear
    ee = np.maximum(np.einsum("ij,ij->i", e, e), 1e-300)
    f = np.clip(-np.einsum("ij,ij->i", d0, e) / ee, 0.0, 1.0)
    assert np.linalg.norm(d0 + f[:, None] * e, axis=1).min() > 0.1  # never on one point


def _max_acceleration(tr: np.ndarray, scale: float, dt: float) -> float:
    """Largest |acceleration| (vector, m/s^2) of a trajectory sampled every ``dt``."""
    t, p = tr[:, 0], tr[:, 1:] * scale
    grid = np.arange(0.0, t[-1] + dt / 2, dt)
    P = np.column_stack([np.interp(grid, t, p[:, k]) for k in range(p.shape[1])])
    a = (P[2:] - 2 * P[1:-1] + P[:-2]) / dt**2
    return float(np.linalg.norm(a, axis=1).max(initial=0.0))


def _check_limits(inst, s, ex, dt):
    for a, tr in zip(inst.agents, ex.trajectories, strict=True):
        step = np.diff(tr[:, 0])
        speed = np.linalg.norm(np.diff(tr[:, 1:], axis=0), axis=1) * s.scale / step
        assert speed.max() <= a.kinematics.v_max * (1 + 1e-6)
        # Vector acceleration: corners are taken at rest, holds are braked for.
        assert _max_acceleration(tr, s.scale, dt) <= a.kinematics.a_max * (1 + 1e-6), a.name
    assert ex.statistics["acceleration_violations"] == 0
    assert ex.statistics["max_acceleration_ratio"] <= 1 + 1e-6


@pytest.mark.parametrize("policy", ["slack", "stn", "adg"])
def test_robot_mode_keeps_limits_and_distance(warehouse, policy):
    inst, s = warehouse
    dist = [RandomDelays(0.2, "exponential", 2.0), Stop("youbot3", 6.0, at_time=4.0)]
    agent = simulate(inst, s, disturbances=dist, policy=policy, seed=2)
    # Open loop on the agent run's times (the closed loop draws its own delays).
    ex = simulate(inst, s, disturbances=dist, policy=policy, seed=2, mode="replay", dt=0.05)
    st = ex.statistics
    assert st["collisions"] == 0 and st["distance_kept"] and st["finished"] == inst.num_agents
    assert st["makespan"] >= agent.statistics["makespan"] - 1e-6  # accelerating costs time
    _check_limits(inst, s, ex, 0.05)


def test_robot_mode_replans_within_a_max(warehouse):
    """A seeded batch with stops, breakdowns and re-plans: robots brake before they
    follow a new plan, never exceed a_max, and never collide."""
    inst, s = warehouse
    names = [a.name for a in inst.agents]
    replans = 0
    for seed in range(5):
        rng = np.random.default_rng(seed)
        dist = [
            RandomDelays(0.1, "exponential", 2.0),
            Stop(names[int(rng.integers(len(names)))], 5.0, at_time=float(rng.uniform(0, 15))),
            Breakdown("youbot8", float(rng.uniform(3, 15))),  # blocks youbot7
        ]
        agent = simulate(inst, s, disturbances=dist, policy="replan", seed=seed)
        ex = simulate(
            inst, s, disturbances=dist, policy="replan", seed=seed, mode="replay", dt=0.05
        )
        st = ex.statistics
        assert st["replans"] == agent.statistics["replans"] >= 1
        assert st["collisions"] == 0 and st["distance_kept"]
        assert st["finished"] == agent.statistics["finished"] == inst.num_agents - 1
        for inst2, plan in ex.replans:
            assert hp.validate(inst2, plan) == []
        _check_limits(inst, s, ex, 0.05)
        # The broken robot stands where the re-plan took it for an obstacle.
        k = names.index("youbot8")
        np.testing.assert_allclose(ex.trajectories[k][-1, 1:], agent.trajectories[k][-1, 1:])
        replans += st["replans"]
    assert replans >= 5


def test_robot_mode_records_what_a_max_cannot_do():
    """A robot that learns of a re-plan too late to brake for its new start is stopped
    there anyway, and the run says so (never hidden)."""
    from dataclasses import replace

    from hierplan_opt.execution.robot import robot_run
    from hierplan_opt.execution.simulate import Simulation

    k = Kinematics("bot", "omni", v_max=1.0, a_max=0.5, radius=0.2)
    g = Graph.grid(9, 3)
    inst = Instance.mapf(g, [(1, 0), (0, 0), (0, 2)], [(5, 0), (4, 0), (8, 2)], kinematics=k)
    s = postprocess(inst, hp.solve(inst, "cbs").plan)
    sim = Simulation(inst, s, [Breakdown("agent0", 1.5)], "replan", 0, "ecbs", 30.0)
    sim.run()
    assert len(sim.phases) == 2
    honest = robot_run(sim, inst, 0.05)
    assert honest.violations == () and honest.max_ratio <= 1 + 1e-6
    # Had agent2 heard of the re-plan only when it got to its new start at full speed:
    late = replace(sim.phases[1], start=6.0)
    sim.phases[1] = late
    out = robot_run(sim, inst, 0.05)
    assert out.violations and all(need > k.a_max for _, _, need in out.violations)
    assert {g for _, g, _ in out.violations} == {2} and out.max_ratio > 1
