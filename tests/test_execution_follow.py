"""Execution following refined trajectories (``simulate(..., trajectories=...)``)."""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from hierplan_opt import Graph, Instance, Plan
from hierplan_opt.cli import main
from hierplan_opt.core.errors import HierplanError
from hierplan_opt.core.instance import Kinematics
from hierplan_opt.execution import RandomDelays, Stop, simulate
from hierplan_opt.io import save_instance, save_plan
from hierplan_opt.schedule import postprocess
from hierplan_opt.trajectory import read_trajectories, refine, write_trajectories

KIN = Kinematics(v_max=1.0, a_max=1.0, radius=0.3)


def convoy() -> tuple[Instance, Plan]:
    """agent1 follows agent0 one cell behind along a corridor."""
    inst = Instance.mapf(Graph.grid(6, 1), [(1, 0), (0, 0)], [(5, 0), (4, 0)], kinematics=KIN)
    return inst, Plan.from_paths([[1, 2, 3, 4, 5], [0, 1, 2, 3, 4]])


def crossing() -> tuple[Instance, Plan]:
    """Two robots cross at the centre of a plus; one waits for the other."""
    g = Graph.grid(3, 3, obstacles=[(0, 0), (2, 0), (0, 2), (2, 2)])
    inst = Instance.mapf(g, [(0, 1), (1, 0)], [(2, 1), (1, 2)], kinematics=KIN)
    return inst, Plan.from_paths([[3, 4, 5], [1, 1, 4, 7]])


@pytest.fixture(scope="module")
def convoy_refined():
    inst, plan = convoy()
    sched = postprocess(inst, plan)
    return inst, sched, refine(inst, sched, stretch="auto")


@pytest.mark.parametrize("case", [convoy, crossing])
def test_undisturbed_run_is_the_refined_motion(case) -> None:
    inst, plan = case()
    sched = postprocess(inst, plan)
    tr = refine(inst, sched, stretch="auto")
    ex = simulate(inst, sched, trajectories=tr, policy="slack")
    st = ex.statistics
    assert st["finished"] == inst.num_agents and st["collisions"] == 0 and not ex.log
    assert st["trajectories"] == "refined"
    assert st["guaranteed_distance"] == pytest.approx(tr.safety_distance)
    assert st["min_distance"] >= tr.required(0, 1) - 1e-9 and st["distance_kept"]
    # Every robot passes its way-points when its refined trajectory does ...
    events = np.concatenate([r.event_times for r in tr.robots])
    np.testing.assert_allclose(ex.event_times, events, atol=1e-9)
    np.testing.assert_allclose(ex.arrival, [r.arrival for r in tr.robots], atol=1e-9)
    # ... and is where that trajectory is at every executed sample.
    for r, tj in zip(tr.robots, ex.trajectories, strict=True):
        t = tj[:, 0]
        np.testing.assert_allclose(tj[:, 1:], r.state(t)["p"] / sched.scale, atol=1e-9)
    # Not the constant-velocity execution: the timing is the refined one.
    plain = simulate(inst, sched, policy="slack")
    assert not np.allclose(plain.event_times, ex.event_times)


def test_a_stopped_leader_makes_the_follower_hold(convoy_refined) -> None:
    inst, sched, tr = convoy_refined
    stop = Stop("agent0", 2.0, at_time=1.5)
    ex = simulate(inst, sched, trajectories=tr, policy="slack", disturbances=[stop])
    st = ex.statistics
    assert st["collisions"] == 0 and st["distance_kept"]
    assert st["min_distance"] >= tr.required(0, 1) - 1e-9
    free = np.array([r.arrival for r in tr.robots])
    assert ex.arrival[0] == pytest.approx(free[0] + 2.0)
    # The follower held (TPG rule), so it arrives late although nothing stopped it.
    assert ex.arrival[1] > free[1] + 1.0
    # During the stop the leader stands still on its refined path.
    lead = ex.trajectories[0]
    held = lead[(lead[:, 0] >= 1.5) & (lead[:, 0] <= 3.5), 1:]
    assert np.ptp(held, axis=0).max() < 1e-12
    for policy in ("stn", "replan", "adg"):
        other = simulate(inst, sched, trajectories=tr, policy=policy, disturbances=[stop])
        assert other.statistics["collisions"] == 0 and other.statistics["distance_kept"]
        assert other.arrival[1] > free[1] + 1.0
    # Ignoring the TPG while following the same trajectories collides.
    naive = simulate(inst, sched, trajectories=tr, policy="naive", disturbances=[stop])
    assert naive.statistics["collisions"] > 0 and not naive.statistics["distance_kept"]


def test_run_is_deterministic_for_a_seed(convoy_refined) -> None:
    inst, sched, tr = convoy_refined
    dist = [RandomDelays(0.5, "exponential", 1.0)]
    runs = [
        simulate(inst, sched, trajectories=tr, disturbances=dist, seed=s, policy="stn")
        for s in (3, 3, 4)
    ]
    a, b, c = runs
    np.testing.assert_array_equal(a.event_times, b.event_times)
    for x, y in zip(a.trajectories, b.trajectories, strict=True):
        np.testing.assert_array_equal(x, y)
    assert a.statistics["collisions"] == 0 and a.statistics["distance_kept"]
    assert not np.array_equal(a.event_times, c.event_times)


def test_mismatched_trajectories_are_refused(convoy_refined) -> None:
    inst, sched, tr = convoy_refined
    other, plan = crossing()
    with pytest.raises(HierplanError, match="way-point events"):
        simulate(other, postprocess(other, plan), trajectories=tr)
    with pytest.raises(HierplanError, match=r"do not match .* agent1 missing"):
        simulate(inst, sched, trajectories=replace(tr, robots=tr.robots[:1]))


def test_npz_round_trip_is_exact(convoy_refined, tmp_path: Path) -> None:
    inst, sched, tr = convoy_refined
    back = read_trajectories(write_trajectories(tr, tmp_path / "t.npz"))
    assert back.agent_names == tr.agent_names and back.required(0, 1) == tr.required(0, 1)
    for a, b in zip(tr.robots, back.robots, strict=True):
        np.testing.assert_array_equal(a.p, b.p)
        np.testing.assert_array_equal(a.event_times, b.event_times)
        assert a.limits == b.limits  # an unbounded limit (inf) is written as null
    assert any(math.isinf(v) for r in tr.robots for v in r.limits.values())
    ex = simulate(inst, sched, trajectories=back)
    assert ex.arrival.tolist() == simulate(inst, sched, trajectories=tr).arrival.tolist()


def one_line(err: str) -> str:
    lines = [ln for ln in err.splitlines() if not ln.startswith(("INFO", "DEBUG"))]
    assert len(lines) == 1 and "Traceback" not in err, err
    return lines[0]


def test_cli_simulate_and_run_follow_refined_trajectories(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    inst, plan = convoy()
    ipath, ppath = tmp_path / "convoy.yaml", tmp_path / "plan.yaml"
    save_instance(ipath, inst)
    save_plan(ppath, inst, plan)
    spath, npz = tmp_path / "s.yaml", tmp_path / "t.npz"
    assert main(["-q", "post", str(ipath), str(ppath), "--out", str(spath)]) == 0
    assert main(["-q", "refine", str(ipath), str(spath), "--out", str(npz)]) == 0
    capsys.readouterr()
    out = tmp_path / "r.yaml"
    argv = ["simulate", str(ipath), str(spath), "--trajectories", str(npz), "--out", str(out)]
    assert main(argv) == 0
    text = capsys.readouterr().out
    assert "following refined trajectories" in text and "0 collisions" in text
    # Trajectories of another schedule: one line, exit 2, no report.
    other, oplan = crossing()
    opath = tmp_path / "plus.yaml"
    save_instance(opath, other)
    sched = postprocess(other, oplan)
    bad = write_trajectories(refine(other, sched, stretch="auto"), tmp_path / "plus.npz")
    out2 = tmp_path / "r2.yaml"
    argv = ["simulate", str(ipath), str(spath), "--trajectories", str(bad), "--out", str(out2)]
    assert main(argv) == 2
    line = one_line(capsys.readouterr().err)
    assert "plus.npz" in line and "way-point events" in line and not out2.exists()
    csv = tmp_path / "t.csv"
    csv.write_text("agent,t,x,y,vx,vy\n")
    assert main([*argv[:4], str(csv), "--out", str(out2)]) == 2
    assert ".npz" in one_line(capsys.readouterr().err)
    # The whole hierarchy with refinement.
    argv = ["run", str(ipath), "--solver", "cbs", "--refine", "--policy", "slack"]
    assert main(argv) == 0
    text = capsys.readouterr().out
    assert "refined (path mode)" in text and "0 collisions" in text


def test_robot_mode_and_monte_carlo_follow_refined_timing(convoy_refined) -> None:
    from hierplan_opt.execution.montecarlo import monte_carlo

    inst, sched, tr = convoy_refined
    dist = [Stop("agent0", 2.0, at_time=1.0)]
    agent = simulate(inst, sched, disturbances=dist, trajectories=tr)
    ex = simulate(inst, sched, disturbances=dist, trajectories=tr, mode="robot", dt=0.05)
    plain = simulate(inst, sched, disturbances=dist, mode="robot", dt=0.05)
    st = ex.statistics
    assert st["trajectories"] == "refined" and st["collisions"] == 0 and st["distance_kept"]
    assert st["acceleration_violations"] == 0 and st["max_acceleration_ratio"] <= 1 + 1e-6
    assert st["guaranteed_distance"] == pytest.approx(sched.safety_distance)
    # Paced by the refined event times: never before them, later than the
    # constant-velocity targets would pace it.
    assert np.all(ex.robot_times >= agent.event_times - 0.05 - 1e-9)
    assert not np.allclose(ex.robot_times, plain.robot_times)
    mc = monte_carlo(
        inst,
        sched,
        [RandomDelays(0.3, "constant", 1.0)],
        runs=4,
        workers=1,
        progress=False,
        trajectories=tr,
    )
    assert mc.collisions == 0 and all(s["trajectories"] == "refined" for s in mc.runs_stats)


def lane_and_bypass() -> Instance:
    """agent1 follows agent0 along row 0; agent2 drives along row 2 (a breakdown of
    agent0 blocks agent1: re-plan through row 1)."""
    k = Kinematics("bot", "omni", v_max=1.0, a_max=0.5, radius=0.2)
    g = Graph.grid(9, 3)
    return Instance.mapf(g, [(1, 0), (0, 0), (0, 2)], [(5, 0), (4, 0), (8, 2)], kinematics=k)


def test_a_replan_is_refined_again(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from hierplan_opt import solve
    from hierplan_opt.execution import Breakdown

    inst = lane_and_bypass()
    sched = postprocess(inst, solve(inst, "cbs").plan)
    tr = refine(inst, sched, stretch="auto")
    ex = simulate(inst, sched, disturbances=[Breakdown("agent0", 1.5)], trajectories=tr)
    st = ex.statistics
    assert st["replans"] == 1 and st["collisions"] == 0 and st["distance_kept"]
    assert any("refined again" in e.detail for e in ex.log)
    # agent0 stays where its refined trajectory had got to (the re-plan's obstacle).
    here = tr.robots[0].state(np.array([1.5]))["p"][0] / sched.scale
    np.testing.assert_allclose(ex.trajectories[0][-1, 1:], here, atol=1e-9)
    assert ex.trajectories[0][-1, 0] == pytest.approx(1.5)
    # The new schedule's events happen when its refined trajectories pass them ...
    (inst2, _plan2), phase = ex.replans[0], ex.phases[1]
    tr2 = refine(inst2, phase.schedule, stretch="auto")
    events = np.concatenate([r.event_times for r in tr2.robots])
    np.testing.assert_allclose(phase.times, events, atol=1e-9)
    # ... and the robots are where those trajectories are at every executed sample.
    for j, g in enumerate(phase.agents):
        tj = ex.trajectories[g]
        r = tr2.robots[j]
        inside = (tj[:, 0] >= r.event_times[0]) & (tj[:, 0] <= r.event_times[-1])
        assert inside.sum() > 10
        np.testing.assert_allclose(tj[inside, 1:], r.state(tj[inside, 0])["p"], atol=1e-6)
    # The whole hierarchy from the command line: plan, post, refine, simulate, re-plan,
    # refine again.
    ipath, dpath = tmp_path / "lane.yaml", tmp_path / "d.yaml"
    save_instance(ipath, inst)
    dpath.write_text("disturbances:\n  - {kind: breakdown, agent: agent0, at_time: 1.5}\n")
    argv = ["run", str(ipath), "--solver", "cbs", "--refine", "--disturbances", str(dpath)]
    assert main(argv) == 0
    text = capsys.readouterr().out
    assert "refined again" in text and "0 collisions" in text
