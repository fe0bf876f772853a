"""Schedules run in MuJoCo physics (issue 33): agreement with the schedule, gates,
measured clearance."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("mujoco")

from hierplan_opt.api import solve
from hierplan_opt.core.graph import Graph
from hierplan_opt.core.instance import Instance, Kinematics
from hierplan_opt.execution.disturbances import Slow, Stop
from hierplan_opt.physics.run import (
    AGREEMENT,
    GOAL_TOL,
    Gates,
    follow,
    scheduled_positions,
    waypoints_m,
)
from hierplan_opt.schedule.post import postprocess

YOUBOT = Kinematics("youbot", drive="omni", v_max=0.8, a_max=1.0, radius=0.35)
PIONEER = Kinematics(
    "pioneer", drive="differential", v_max=0.6, omega_max=1.5, a_max=0.3, radius=0.3
)
CREATE = Kinematics(
    "create2", drive="differential", v_max=0.5, omega_max=2.0, a_max=0.5, radius=0.17
)
QUAD = Kinematics("quad", drive="omni", v_max=1.0, a_max=2.0, radius=0.15)


def _swap2d(k: Kinematics) -> tuple[Instance, object]:
    g = Graph.grid(5, 4, obstacles=[(2, 1), (2, 2)])
    inst = Instance.mapf(
        g, [(0, 0), (4, 0), (0, 3), (4, 3)], [(4, 3), (0, 3), (4, 0), (0, 0)], kinematics=k
    )
    return inst, postprocess(inst, solve(inst, "cbs", time_limit=10).plan)


def _swap3d() -> tuple[Instance, object]:
    g = Graph.grid(3, 3, 3)
    inst = Instance.mapf(
        g, [(0, 0, 0), (2, 2, 2), (0, 2, 0)], [(2, 2, 2), (0, 0, 0), (2, 0, 2)], kinematics=QUAD
    )
    return inst, postprocess(inst, solve(inst, "cbs", time_limit=10).plan)


@pytest.mark.parametrize("k", [YOUBOT, PIONEER, CREATE, QUAD], ids=lambda k: k.robot_type)
def test_agreement_without_disturbances(k):
    inst, sched = _swap3d() if k is QUAD else _swap2d(k)
    run = follow(inst, sched)
    st = run.statistics
    assert st["finished"] == inst.num_agents and st["contacts"] == 0
    assert st["distance_kept"] and st["min_margin"] >= 0
    tol = AGREEMENT[k.robot_type]
    for reach, planned in zip(run.reach, run.planned, strict=True):
        assert not np.isnan(reach).any()
        assert np.abs(reach - planned).max() <= tol
        assert abs(reach[-1] - planned[-1]) <= GOAL_TOL
    assert abs(st["makespan"] - sched.makespan) <= GOAL_TOL


def test_gates_hold_a_robot_behind_a_stopped_one():
    # Two youBots in a corridor, the front one halts for 5 s: the one behind holds at
    # its gate (the TPG's Type-2 arc), no contact, and it arrives later than planned.
    g = Graph.grid(7, 1)
    inst = Instance.mapf(g, [(1, 0), (0, 0)], [(6, 0), (5, 0)], kinematics=YOUBOT)
    sched = postprocess(inst, solve(inst, "cbs", time_limit=10).plan)
    calm = follow(inst, sched)
    names = sched.agent_names
    run = follow(inst, sched, [Stop(names[0], duration=5.0, at_time=1.0)])
    st = run.statistics
    assert st["contacts"] == 0 and st["min_margin"] >= 0
    assert st["finished"] == 2
    assert run.reach[1][-1] > calm.reach[1][-1] + 1.0
    # Without gates the follower would run into the halted robot: the gates did it.
    assert any(Gates(sched).preds[1])


def test_spill_makes_robots_late_and_no_spill_does_not():
    g = Graph.grid(6, 3)
    # Robot 0 brakes to its goal on the spill (a robot cruising over it keeps its
    # speed: it needs no grip for that).
    inst = Instance.mapf(g, [(0, 1), (0, 0)], [(3, 1), (2, 2)], kinematics=YOUBOT)
    sched = postprocess(inst, solve(inst, "cbs", time_limit=10).plan)
    calm = follow(inst, sched)
    wet = follow(inst, sched, [Slow(0.3, cells=((2, 1), (3, 1)))])
    late_calm = calm.statistics["lateness_max"]
    late_wet = wet.statistics["lateness_max"]
    assert late_calm < 0.6
    assert late_wet > late_calm + 1.0
    assert wet.statistics["contacts"] == 0


def test_scheduled_positions_and_tracking():
    inst, sched = _swap2d(YOUBOT)
    t = np.array([0.0, sched.makespan + 1])
    pos = scheduled_positions(sched, t)
    for i in range(inst.num_agents):
        wp = waypoints_m(sched, i)
        assert np.allclose(pos[0, i], wp[0]) and np.allclose(pos[1, i], wp[-1])
    run = follow(inst, sched)
    st = run.statistics
    assert 0 < st["tracking_error_rms"] <= st["tracking_error_max"] < 0.5
    assert st["real_time_factor"] > 0
    assert set(st["tracking"]) == set(sched.agent_names)


def test_simulate_physics_mode_and_cli(tmp_path):
    # simulate(..., mode="physics") and `hierplan simulate --mode physics` run the
    # schedule in MuJoCo through the same report; a breakdown that blocks the other
    # robot is handed to the re-plan layer, whose new plan reaches the controllers.
    import yaml

    from hierplan_opt.cli import main
    from hierplan_opt.execution import simulate
    from hierplan_opt.execution.disturbances import Breakdown
    from hierplan_opt.io import save_plan

    g = Graph.grid(5, 3)
    inst = Instance.mapf(g, [(0, 1), (4, 1)], [(4, 1), (0, 1)], kinematics=YOUBOT)
    plan = solve(inst, "cbs", time_limit=10).plan
    sched = postprocess(inst, plan)
    names = sched.agent_names
    # The robot that waits at a gate for the other one: break the other one early, once
    # it has left the waiter's goal by more than the clearance (at 1.0 s it stands 0.62 m
    # from it, < 0.7 m: the goal is cut off and the waiter gets a substitute).
    waiter = next(j for j in range(2) if any(Gates(sched).preds[j]))
    other = names[1 - waiter]
    ex = simulate(inst, sched, disturbances=[Breakdown(other, 1.5)], mode="physics")
    st = ex.statistics
    assert ex.mode == "physics" and st["collisions"] == 0
    assert st["replans"] == 1 and st["handled"]["replan"] >= 1
    assert st["finished"] == 1 and st["unfinished"] == [other]
    assert not np.isnan(ex.arrival[waiter])
    kinds = [(e.kind, e.layer) for e in ex.log]
    assert ("breakdown", "replan") in kinds
    inst_path = tmp_path / "i.yaml"
    from hierplan_opt.io import save_instance

    save_instance(inst_path, inst)
    plan_path = tmp_path / "p.yaml"
    save_plan(plan_path, inst, plan)
    out = tmp_path / "r.yaml"
    rc = main(["simulate", str(inst_path), str(plan_path), "--mode", "physics", "--out", str(out)])
    assert rc == 0
    rep = yaml.safe_load(out.read_text())
    assert rep["statistics"]["collisions"] == 0 and rep["statistics"]["finished"] == 2
    # `hierplan run` (plan -> post -> execute) in physics mode.
    out3 = tmp_path / "run.yaml"
    assert main(["run", str(inst_path), "--mode", "physics", "--out", str(out3)]) == 0
    rep = yaml.safe_load(out3.read_text())
    assert rep["statistics"]["collisions"] == 0 and rep["statistics"]["finished"] == 2
    # Monte Carlo has no physics mode: refused in one line, nothing written.
    out2 = tmp_path / "mc.yaml"
    argv = ["simulate", str(inst_path), str(plan_path), "--mode", "physics", "--runs", "2"]
    assert main([*argv, "--out", str(out2)]) == 2
    assert not out2.exists()


def test_physics_run_animation(tmp_path):
    # The animation of a physics run (the viz module's, on the Execution).
    from hierplan_opt.execution import simulate
    from hierplan_opt.viz.animation import animate

    g = Graph.grid(4, 2)
    inst = Instance.mapf(g, [(0, 0), (3, 1)], [(3, 0), (0, 1)], kinematics=YOUBOT)
    sched = postprocess(inst, solve(inst, "cbs", time_limit=10).plan)
    ex = simulate(inst, sched, mode="physics")
    out = animate(ex, inst, tmp_path / "run.gif", max_frames=12)
    data = out.read_bytes()
    assert data[:6] in (b"GIF89a", b"GIF87a") and len(data) > 1000


def _physics_run(inst, sched, dist, seed):
    from hierplan_opt.execution import simulate

    ex = simulate(inst, sched, disturbances=dist, mode="physics", seed=seed)
    return ex, [(e.time, e.agent, e.kind, e.layer) for e in ex.log]


def test_closed_loop_identical_for_identical_seeds():
    from hierplan_opt.execution.disturbances import RandomDelays

    inst, sched = _swap2d(YOUBOT)
    dist = [RandomDelays(0.3, "exponential", 1.5)]
    a, ea = _physics_run(inst, sched, dist, 5)
    b, eb = _physics_run(inst, sched, dist, 5)
    c, _ec = _physics_run(inst, sched, dist, 6)
    assert ea == eb
    assert all(np.array_equal(x, y) for x, y in zip(a.trajectories, b.trajectories, strict=True))
    # Another seed: other delays, another motion.
    assert any(
        not np.array_equal(x, y) for x, y in zip(a.trajectories, c.trajectories, strict=True)
    )
    st = a.statistics
    assert st["contacts"] == 0 and st["collisions"] == 0 and st["measured_min_margin"] >= 0
    assert st["finished"] == len(a.agent_names) and st["distance_kept"]


def test_random_delays_with_their_own_seed_ignore_the_run_seed():
    from hierplan_opt.execution.disturbances import RandomDelays

    inst, sched = _swap2d(YOUBOT)
    dist = [RandomDelays(0.3, "exponential", 1.5, seed=11)]
    a, ea = _physics_run(inst, sched, dist, 5)
    b, eb = _physics_run(inst, sched, dist, 6)
    assert ea == eb
    assert all(np.array_equal(x, y) for x, y in zip(a.trajectories, b.trajectories, strict=True))


def test_paper_warehouse_with_disturbances_in_physics_keeps_clearance():
    # Issue 33 with ClosedLoop over the MuJoCo plant: the paper warehouse (part 1) and
    # its disturbances file. Before: the robots stopped within the plant's 5 cm were not
    # "at their goals" (1e-6 check), and a robot driven onto a gated node stood exactly
    # the clearance from the robot it waited for and touched it (2 contact pairs, 1 mm).
    from hierplan_opt.execution import load_disturbances, simulate
    from hierplan_opt.io import load_instance

    inst = load_instance("instances/paper/warehouse-part1.yaml")
    dist = load_disturbances("instances/paper/warehouse-disturbances.yaml")
    sched = postprocess(inst, solve(inst, "cbm", time_limit=30).plan)
    ex = simulate(inst, sched, disturbances=dist, mode="physics")
    st = ex.statistics
    assert ex.mode == "physics" and st["loop"] == "closed"
    assert st["contacts"] == 0 and st["contact_pairs"] == [] and st["collisions"] == 0
    assert st["measured_min_margin"] >= 0 and st["distance_kept"]
    assert st["broken"] == ["youbot8"] and st["stranded"] == []
    assert st["finished"] == len(ex.agent_names) - 1
    assert st["handled"]["none"] == 0 and st["handled"]["replan"] >= 1
    assert st["real_time_factor"] > 1 and st["tracking_error_max"] > 0


def test_spill_delays_are_named_and_absorbed_and_dry_run_has_none() -> None:
    """The water spill of the paper's warehouse makes the robots on it late: each such
    delay is an event named ``spill`` with the layer that handled it; the same run
    without the spill has no such event."""
    from pathlib import Path

    from hierplan_opt.execution import simulate
    from hierplan_opt.execution.disturbances import load_disturbances
    from hierplan_opt.io import load_instance

    paper = Path(__file__).resolve().parent.parent / "instances" / "paper"
    inst = load_instance(paper / "warehouse-part1.yaml")
    dist = load_disturbances(paper / "warehouse-disturbances.yaml")
    spills = [d for d in dist if isinstance(d, Slow)]
    plan = solve(inst, "cbm").plan
    assert plan is not None and spills
    sched = postprocess(inst, plan)
    wet = simulate(inst, sched, disturbances=spills, mode="physics")
    dry = simulate(inst, sched, disturbances=[], mode="physics")
    on = {n for n, c in wet.statistics["disturbed"].items() if "spill" in c}
    events = [e for e in wet.log if e.kind == "spill"]
    assert events and {e.agent for e in events} <= on
    assert all(e.layer in ("slack", "reorder", "stn", "replan") and e.delay > 0 for e in events)
    assert wet.statistics["disturbances"] == len(
        [e for e in wet.log if e.kind in ("spill", "late", "stop", "breakdown", "random")]
    )
    assert not [e for e in dry.log if e.kind == "spill"]
    assert not dry.statistics["disturbed"]
    assert wet.statistics["contacts"] == 0 and dry.statistics["contacts"] == 0
