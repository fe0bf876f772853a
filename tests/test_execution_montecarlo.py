"""Monte Carlo: on-time probabilities and the delay-aware re-plan they trigger."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import yaml

from hierplan_opt import Graph, Instance, solve
from hierplan_opt.cli import main
from hierplan_opt.core.validate import validate
from hierplan_opt.execution import RandomDelays
from hierplan_opt.execution.montecarlo import monte_carlo
from hierplan_opt.schedule import check_bounds, postprocess
from hierplan_opt.schedule.replay import replay


@pytest.fixture(scope="module")
def crossing():
    """Three robots through the centre of a 5x5 grid: tight windows, so random delays
    make late arrivals likely."""
    g = Graph.grid(5, 5)
    inst = Instance.mapf(g, [(0, 2), (2, 0), (4, 2)], [(4, 2), (2, 4), (0, 2)])
    plan = solve(inst, "cbs", time_limit=30).plan
    assert plan is not None
    return inst, postprocess(inst, plan)


def test_threshold_triggers_a_delay_aware_replan(crossing):
    inst, s = crossing
    delays = [RandomDelays(0.3, "constant", 1.0)]
    mc = monte_carlo(inst, s, delays, runs=40, workers=1, progress=False, replan_below=0.8)
    # The trigger fired: some location of the planned schedule is late too often.
    assert mc.replan_advised and mc.below
    assert all(mc.on_time_of(loc) < 0.8 for loc in mc.below)
    new = mc.replanned
    assert new is not None and new.rounds >= 1
    # The new plan validates, its schedule meets every bound and replays.
    assert validate(inst, new.plan) == []
    assert new.schedule.stn is not None
    assert check_bounds(new.schedule.stn, new.schedule.times) == []
    assert replay(new.schedule, inst).ok
    # Its locations are on time as asked (estimated on fresh seeds), at a later makespan.
    assert new.result.on_time.min() >= 0.8 > mc.on_time.min()
    assert new.schedule.makespan > s.makespan
    assert new.result.collisions == 0 and mc.collisions == 0
    summary = mc.summary()["replanned"]
    assert summary["on_time_min"] == pytest.approx(float(new.result.on_time.min()))
    assert summary["planned_makespan"] == pytest.approx(new.schedule.makespan)


def test_no_trigger_above_the_threshold(crossing):
    inst, s = crossing
    delays = [RandomDelays(0.3, "constant", 1.0)]
    mc = monte_carlo(inst, s, delays, runs=10, workers=1, progress=False, replan_below=0.0)
    assert not mc.replan_advised and mc.replanned is None and mc.below == ()
    # Without a solver the threshold only advises.
    mc = monte_carlo(
        inst, s, delays, runs=10, workers=1, progress=False, replan_below=1.0, replan_solver=None
    )
    assert mc.replan_advised and mc.replanned is None
    np.testing.assert_array_equal(mc.samples.shape, (10, len(mc.nodes)))


def test_cli_replan_below(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    root = Path(__file__).resolve().parent.parent
    warehouse = str(root / "instances" / "paper" / "warehouse-part1.yaml")
    dist = tmp_path / "d.yaml"
    dist.write_text(
        "disturbances:\n  - {kind: random, probability: 0.2, duration: {constant: 1.0}}\n"
    )
    out = tmp_path / "r.yaml"
    argv = ["run", warehouse, "--solver", "cbm", "--disturbances", str(dist), "--runs", "20"]
    code = main([*argv, "--workers", "1", "--replan-below", "0.9", "--out", str(out)])
    text = capsys.readouterr().out
    assert code == 0, text
    assert "delay-aware re-plan" in text
    data = yaml.safe_load(out.read_text())
    before, after = data["monte_carlo"]["on_time_min"], data["monte_carlo"]["replanned"]
    assert before < 0.9 <= after["on_time_min"]
    assert set(data["replanned_schedule"]) == set(data["schedule"])
    code = main(["run", warehouse, "--solver", "cbm", "--replan-below", "0.9", "--out", str(out)])
    assert code == 2 and "--runs" in capsys.readouterr().err


def test_monte_carlo_in_robot_mode(crossing):
    inst, s = crossing
    from hierplan_opt.core.instance import Kinematics

    k = Kinematics("bot", "omni", v_max=1.0, a_max=0.5, radius=0.3)
    inst = Instance(inst.graph, tuple(replace(a, kinematics=k) for a in inst.agents), (), None)
    s = postprocess(inst, solve(inst, "cbs", time_limit=30).plan)
    delays = [RandomDelays(0.3, "constant", 1.0)]
    agent = monte_carlo(inst, s, delays, runs=8, workers=1, progress=False)
    robot = monte_carlo(inst, s, delays, runs=8, workers=1, progress=False, mode="replay")
    assert robot.collisions == 0 and all(st["mode"] == "replay" for st in robot.runs_stats)
    assert all(st["acceleration_violations"] == 0 for st in robot.runs_stats)
    # Accelerating and taking corners at rest costs time: the robots are later.
    assert np.nanmean(robot.samples) > np.nanmean(agent.samples)
    # Closed loop (its own delays, fed back into the layers): safe and within a_max.
    loop = monte_carlo(inst, s, delays, runs=8, workers=1, progress=False, mode="robot")
    assert loop.collisions == 0 and all(st["loop"] == "closed" for st in loop.runs_stats)
    assert all(st["acceleration_violations"] == 0 for st in loop.runs_stats)
    assert robot.makespans.mean() > agent.makespans.mean()


def test_random_delays_with_their_own_seed_still_vary_between_runs(crossing):
    # A seeded random disturbance (as in a YAML file with `seed: 1`) must not make every
    # run of the batch draw the same delays: the batch's run seeds drive them.
    inst, s = crossing
    seeded = [RandomDelays(0.3, "exponential", 1.0, seed=1)]
    unseeded = [RandomDelays(0.3, "exponential", 1.0)]
    a = monte_carlo(inst, s, seeded, runs=20, workers=1, progress=False)
    b = monte_carlo(inst, s, unseeded, runs=20, workers=1, progress=False)
    assert len(set(a.makespans.tolist())) > 1
    assert np.array_equal(a.makespans, b.makespans)
